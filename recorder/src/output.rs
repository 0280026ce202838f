//! Where the recording goes: a temporary file next to `--out`, renamed into place once the run
//! produced a recording, so that a failed start never truncates an existing recording.
//!
//! The temporary file is `.<name>.partial-<pid>` in the directory of `--out` (the same file
//! system, so the rename is atomic). The recorder renames it as soon as the first state of the run
//! arrives: from then on `--out` is the new recording, growing as the run goes (a `kill -9`
//! leaves a readable partial recording there). A run that ends before any state (bad peer, no
//! plant, Ctrl-C while waiting) removes the temporary file and leaves `--out` as it was. A
//! recorder killed (`kill -9`) before the first state cannot remove its twin; the next recorder
//! to the same `--out` removes the twins of processes that no longer run.

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
        self.remove_stale_twins();
        std::fs::File::create(&self.temp).map_err(|e| {
            anyhow::anyhow!(
                "invalid --out = {}: allowed a file path in an existing, writable directory (cannot create {}: {e})",
                self.out.display(),
                self.temp.display()
            )
        })?;
        Ok(&self.temp)
    }

    /// Removes `.<name>.partial-<pid>` files next to `--out` whose process no longer runs (no
    /// `/proc/<pid>`): twins left by a recorder killed before its run's first state. Twins of
    /// running processes (another recorder to the same file) are left alone.
    fn remove_stale_twins(&self) {
        let (Some(dir), Some(name)) = (self.temp.parent(), self.out.file_name()) else {
            return;
        };
        let prefix = format!(".{}.partial-", name.to_string_lossy());
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let file = entry.file_name();
            let Some(pid) = file
                .to_str()
                .and_then(|f| f.strip_prefix(&prefix))
                .and_then(|p| p.parse::<u32>().ok())
            else {
                continue;
            };
            let gone = !Path::new(&format!("/proc/{pid}")).exists();
            if gone && pid != std::process::id() && entry.path().is_file() {
                let _ = std::fs::remove_file(entry.path());
            }
        }
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
    fn twins_of_dead_recorders_are_removed_and_those_of_live_ones_kept() {
        let d = scratch("stale");
        let out = d.join("x.rrd");
        // a process that has ended: its pid names no running process (unless reused at once)
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead = child.id();
        child.wait().unwrap();
        let stale = d.join(format!(".x.rrd.partial-{dead}"));
        let live = d.join(".x.rrd.partial-1"); // init runs as long as the machine
        let other = d.join(format!(".y.rrd.partial-{dead}")); // another output's twin
        for f in [&stale, &live, &other] {
            std::fs::write(f, b"header only").unwrap();
        }
        {
            let o = Output::new(&out).unwrap();
            o.create().unwrap();
            assert!(!stale.exists(), "the dead recorder's twin is still there");
            assert!(live.exists() && other.exists());
        }
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
