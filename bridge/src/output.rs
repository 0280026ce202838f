//! Where the recording goes: a temporary file next to `--out`, renamed into place once the run
//! produced a recording, so that a failed start never truncates an existing recording.
//!
//! The temporary file is `.<name>.partial-<pid>` in the directory of `--out` (the same file
//! system, so the rename is atomic). The recorder renames it as soon as the first state of the run
//! arrives: from then on `--out` is the new recording, growing as the run goes (a `kill -9`
//! leaves a readable partial recording there). A run that ends before any state (bad peer, no
//! plant, Ctrl-C while waiting) removes the temporary file and leaves `--out` as it was.

use std::path::{Path, PathBuf};

/// The output file of a recording and its temporary twin.
#[derive(Debug)]
pub struct Output {
    out: PathBuf,
    temp: PathBuf,
    promoted: bool,
}

impl Output {
    /// Checks `--out` (a file name in an existing directory, not a directory) and picks the
    /// temporary file next to it. Nothing is created yet.
    pub fn new(out: &Path) -> anyhow::Result<Self> {
        let bad = |why: &str| {
            anyhow::anyhow!(
                "invalid --out = {}: allowed a file path in an existing, writable directory ({why})",
                out.display()
            )
        };
        if out.is_dir() {
            return Err(bad("it is a directory"));
        }
        let name = match out.file_name() {
            Some(n) if !out.as_os_str().to_string_lossy().ends_with('/') => n,
            _ => return Err(bad("it names no file")),
        };
        if out.exists() && !out.is_file() {
            return Err(bad("it exists and is not a regular file"));
        }
        let dir = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !dir.is_dir() {
            return Err(bad(&format!("no directory {}", dir.display())));
        }
        let temp = dir.join(format!(
            ".{}.partial-{}",
            name.to_string_lossy(),
            std::process::id()
        ));
        Ok(Self {
            out: out.to_path_buf(),
            temp,
            promoted: false,
        })
    }

    /// Creates the temporary file (empty), proving the directory writable; the recording's
    /// file sink then opens it. Errors name `--out`.
    pub fn create(&self) -> anyhow::Result<&Path> {
        std::fs::File::create(&self.temp).map_err(|e| {
            anyhow::anyhow!(
                "invalid --out = {}: allowed a file path in an existing, writable directory (cannot create {}: {e})",
                self.out.display(),
                self.temp.display()
            )
        })?;
        Ok(&self.temp)
    }

    /// The file the recording is written to until it is promoted.
    pub fn temp(&self) -> &Path {
        &self.temp
    }

    /// The final path, `--out`.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// True once the recording replaced `--out`.
    pub fn promoted(&self) -> bool {
        self.promoted
    }

    /// Renames the temporary file onto `--out` (atomic; the open file keeps being written).
    pub fn promote(&mut self) -> anyhow::Result<()> {
        if !self.promoted {
            std::fs::rename(&self.temp, &self.out).map_err(|e| {
                anyhow::anyhow!(
                    "cannot move the recording {} to --out = {}: {e}",
                    self.temp.display(),
                    self.out.display()
                )
            })?;
            self.promoted = true;
        }
        Ok(())
    }
}

impl Drop for Output {
    /// A recording that was never promoted is removed: `--out` stays as it was.
    fn drop(&mut self) {
        if !self.promoted {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("bridge-output-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn an_unpromoted_recording_leaves_the_existing_file_untouched() {
        let d = scratch("keep");
        let out = d.join("keep.rrd");
        std::fs::write(&out, b"old recording").unwrap();
        {
            let o = Output::new(&out).unwrap();
            let temp = o.create().unwrap().to_path_buf();
            std::fs::write(&temp, b"new, never promoted").unwrap();
            assert!(temp.starts_with(&d) && temp != out);
        }
        assert_eq!(std::fs::read(&out).unwrap(), b"old recording");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "temp file left");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_promoted_recording_replaces_the_file() {
        let d = scratch("promote");
        let out = d.join("x.rrd");
        std::fs::write(&out, b"old").unwrap();
        {
            let mut o = Output::new(&out).unwrap();
            std::fs::write(o.create().unwrap(), b"new").unwrap();
            o.promote().unwrap();
            assert!(o.promoted());
        }
        assert_eq!(std::fs::read(&out).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn bad_outputs_name_the_flag_and_the_value() {
        let d = scratch("bad");
        let cases = [
            (d.clone(), "it is a directory"),
            (d.join("no/such/x.rrd"), "no directory"),
            (
                PathBuf::from(format!("{}/", d.join("f").display())),
                "names no file",
            ),
        ];
        for (p, why) in cases {
            let e = Output::new(&p).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("invalid --out = {}: allowed", p.display()))
                    && e.contains(why),
                "{e}"
            );
        }
        std::fs::remove_dir_all(&d).unwrap();
    }
}
