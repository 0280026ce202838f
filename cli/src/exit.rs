//! The one table of process exit codes, shared by every program of the project (documented in
//! the README, "The programs").

use std::process::ExitCode;

/// How a program ended, as its exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// 0: the command or the run finished.
    Finished,
    /// 1: failure (an error, an invalid input, a discarded step, a supervised process failed).
    Failure,
    /// 2: the command line was refused (clap's code for bad flags), or the CPU lacks the
    /// instructions the build targets.
    Usage,
    /// 3: the peer left the run: the plant's controller (or the controller's plant) went away.
    PeerLost,
    /// 4: timeout: no peer joined, or no answer came in time.
    Timeout,
    /// 130: interrupted by SIGINT or SIGTERM (128 + SIGINT, as shells report Ctrl-C).
    Interrupted,
}

impl Exit {
    /// Every exit code, in increasing order.
    pub const ALL: [Exit; 6] = [
        Exit::Finished,
        Exit::Failure,
        Exit::Usage,
        Exit::PeerLost,
        Exit::Timeout,
        Exit::Interrupted,
    ];

    /// The numeric code.
    pub const fn code(self) -> u8 {
        match self {
            Exit::Finished => 0,
            Exit::Failure => 1,
            Exit::Usage => 2,
            Exit::PeerLost => 3,
            Exit::Timeout => 4,
            Exit::Interrupted => 130,
        }
    }

    /// What the code means, in the README's words.
    pub const fn meaning(self) -> &'static str {
        match self {
            Exit::Finished => "finished",
            Exit::Failure => "failure",
            Exit::Usage => "bad command line or unsupported CPU",
            Exit::PeerLost => "controller lost",
            Exit::Timeout => "timeout",
            Exit::Interrupted => "interrupted",
        }
    }

    /// True if a child process that ended with `status` (its code, `None` if a signal killed
    /// it) ended with this code.
    pub fn is(self, status: Option<i32>) -> bool {
        status == Some(i32::from(self.code()))
    }
}

impl From<Exit> for ExitCode {
    fn from(e: Exit) -> Self {
        ExitCode::from(e.code())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_distinct_and_the_shells_interrupt_code_is_130() {
        for (i, a) in Exit::ALL.iter().enumerate() {
            for b in &Exit::ALL[i + 1..] {
                assert!(a.code() < b.code(), "{a:?} and {b:?} out of order or equal");
            }
        }
        // 128 + SIGINT (2): what a shell reports for a program stopped by Ctrl-C.
        assert_eq!(Exit::Interrupted.code(), 128 + 2);
        assert!(Exit::Finished.is(Some(0)) && !Exit::Finished.is(None));
        assert!(!Exit::Timeout.is(Some(3)));
    }

    #[test]
    fn the_readme_documents_every_code() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md");
        let readme = std::fs::read_to_string(path).expect("README.md at the repository root");
        let text = readme.split_whitespace().collect::<Vec<_>>().join(" ");
        let line = text
            .split("Exit codes")
            .nth(1)
            .and_then(|rest| rest.split(". ").next())
            .expect("README says \"Exit codes ...: ...\"");
        for e in Exit::ALL {
            let entry = format!("{} {}", e.code(), e.meaning());
            assert!(
                line.contains(&entry),
                "README's exit codes lack {entry:?}: {line}"
            );
        }
    }
}
