//! Results on standard output.
//!
//! `println!` panics when the reader has gone away (`crawler-controller optimize --json | head`
//! closes the pipe after ten lines). The programs write their results with [`line`] instead, which
//! returns the error, and treat a broken pipe as the end of the output, not as a failure
//! ([`is_broken_pipe`]): they stop quietly with exit code 0, as ripgrep does.

use std::io::{self, Write};

/// Writes `text` and a newline to standard output and flushes it.
pub fn line(text: impl std::fmt::Display) -> io::Result<()> {
    let mut out = io::stdout().lock();
    writeln!(out, "{text}")?;
    out.flush()
}

/// Writes `text` as it is to standard output and flushes it.
pub fn text(text: impl std::fmt::Display) -> io::Result<()> {
    let mut out = io::stdout().lock();
    write!(out, "{text}")?;
    out.flush()
}

/// True if `err`, or any error in its chain of causes, is a broken pipe: the reader of the
/// output has gone away.
pub fn is_broken_pipe(err: &(dyn std::error::Error + 'static)) -> bool {
    let mut cause = Some(err);
    while let Some(e) = cause {
        if e.downcast_ref::<io::Error>()
            .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe)
        {
            return true;
        }
        cause = e.source();
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    struct Wrapped(io::Error);

    impl std::fmt::Display for Wrapped {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "cannot write the report")
        }
    }

    impl std::error::Error for Wrapped {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.0)
        }
    }

    #[test]
    fn a_broken_pipe_is_found_in_the_chain_and_nothing_else_is_one() {
        let pipe = io::Error::from(io::ErrorKind::BrokenPipe);
        assert!(is_broken_pipe(&pipe));
        assert!(is_broken_pipe(&Wrapped(pipe)));
        let full = io::Error::from(io::ErrorKind::StorageFull);
        assert!(!is_broken_pipe(&full));
        assert!(!is_broken_pipe(&Wrapped(full)));
    }
}
