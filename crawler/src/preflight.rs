//! Everything `crawler run` checks before it starts a process: a bad input must not cost the
//! user anything, least of all an existing recording.

use std::path::Path;
use std::process::Command;

use crate::children::Invocation;

/// The recording path is usable: not a directory, its directory exists, and an existing file
/// there is a file the recorder may replace (the recorder writes a temporary file and renames it
/// into place only when the run produced a recording).
pub fn check_out(out: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(
        !out.as_os_str().is_empty(),
        "invalid --out = \"\": allowed a file path"
    );
    anyhow::ensure!(
        !out.is_dir(),
        "invalid --out = {}: a directory; allowed a file path",
        out.display()
    );
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    anyhow::ensure!(
        dir.is_dir(),
        "invalid --out = {}: the directory {} does not exist",
        out.display(),
        dir.display()
    );
    if let Ok(meta) = std::fs::metadata(dir) {
        anyhow::ensure!(
            !meta.permissions().readonly(),
            "invalid --out = {}: the directory {} is read-only",
            out.display(),
            dir.display()
        );
    }
    Ok(())
}

/// `--every` records the fields of every K-th step: K >= 1.
pub fn check_every(every: u64) -> anyhow::Result<()> {
    anyhow::ensure!(
        every >= 1,
        "invalid --every = {every}: allowed an integer >= 1"
    );
    Ok(())
}

/// Runs `check` (a program with `--check`: it validates all of its inputs and exits); the error
/// is the program's own message.
pub fn check_child(name: &str, check: &Invocation) -> anyhow::Result<()> {
    let exe = &check.exe;
    let out = Command::new(exe)
        .args(&check.args)
        .stdin(std::process::Stdio::null())
        .output()
        .map_err(|e| anyhow::anyhow!("cannot start {}: {e}", exe.display()))?;
    if out.status.success() {
        // what it has to say about the run, it says again when the run starts
        return Ok(());
    }
    for line in String::from_utf8_lossy(&out.stderr).lines() {
        eprintln!("[{name}] {line}");
    }
    anyhow::bail!("the {name} refused its inputs (above); nothing was started")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_directory_or_a_missing_directory_is_not_a_recording() {
        let dir = tempfile::tempdir().unwrap();
        let e = check_out(dir.path()).unwrap_err().to_string();
        assert!(e.contains("--out") && e.contains("a directory"), "{e}");
        let e = check_out(&dir.path().join("no/such/dir/x.rrd"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not exist"), "{e}");
        check_out(&dir.path().join("x.rrd")).unwrap();
        check_out(Path::new("x.rrd")).unwrap();
        assert!(check_every(0).unwrap_err().to_string().contains("--every"));
    }
}
