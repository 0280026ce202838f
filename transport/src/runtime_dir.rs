//! The private runtime directory of a run: where its credential, the plant's zenoh user file
//! and its default unix socket live.
//!
//! `$XDG_RUNTIME_DIR/crawler/<run>` when the login session has a runtime directory, else
//! `<temp>/crawler-<uid>/<run>` (`<temp>` is `$TMPDIR` or `/tmp`). Every directory created here
//! is created with mode 0700, and every directory used is checked first: a real directory (not a
//! symbolic link), owned by this user, no permission for group or others. A directory failing
//! the check is an error naming it and what is wrong (another user may have created it first, to
//! read or plant files); nothing is ever loosened or taken over.

use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};

/// The effective user id of this process.
pub fn euid() -> u32 {
    // SAFETY: geteuid has no preconditions and cannot fail.
    unsafe { libc::geteuid() }
}

/// The base directory of every run of this user (not created).
pub fn base() -> PathBuf {
    match std::env::var_os("XDG_RUNTIME_DIR").map(PathBuf::from) {
        Some(xdg) if xdg.is_absolute() => xdg.join("crawler"),
        _ => std::env::temp_dir().join(format!("crawler-{}", euid())),
    }
}

/// The private directory of run `run_id` (not created; the run id is validated by the caller).
pub fn run_dir(run_id: &str) -> PathBuf {
    base().join(run_id)
}

/// Checks that `dir` is a directory (not a link) owned by this user with no permission for
/// group or others.
pub fn check_private_dir(dir: &Path) -> anyhow::Result<()> {
    let meta = std::fs::symlink_metadata(dir)
        .with_context(|| format!("cannot inspect the private directory {}", dir.display()))?;
    if meta.file_type().is_symlink() {
        bail!(
            "{} is a symbolic link; a private run directory must be a real directory (remove it)",
            dir.display()
        );
    }
    if !meta.is_dir() {
        bail!("{} exists and is not a directory", dir.display());
    }
    if meta.uid() != euid() {
        bail!(
            "{} belongs to user id {}, not to this user ({}): refusing to use it (another user \
             may have created it; remove it or set XDG_RUNTIME_DIR)",
            dir.display(),
            meta.uid(),
            euid()
        );
    }
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        bail!(
            "{} has mode {mode:03o}: a private run directory must not be accessible to group or \
             others (chmod 700 it, or remove it)",
            dir.display()
        );
    }
    Ok(())
}

/// Creates `dir` with mode 0700 if it does not exist, then checks it.
fn ensure_private_dir(dir: &Path) -> anyhow::Result<()> {
    match std::fs::DirBuilder::new().mode(0o700).create(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => {
            return Err(e).with_context(|| format!("cannot create the directory {}", dir.display()))
        }
    }
    check_private_dir(dir)
}

/// Creates (if needed) and checks the private directory of run `run_id`, and every private
/// directory above it that belongs to this project. `$XDG_RUNTIME_DIR` itself must pass the same
/// check (the XDG specification requires it).
pub fn ensure_run_dir(run_id: &str) -> anyhow::Result<PathBuf> {
    let base = base();
    if let Some(parent) = base.parent() {
        if std::env::var_os("XDG_RUNTIME_DIR").is_some() && parent.is_absolute() {
            check_private_dir(parent).context("XDG_RUNTIME_DIR is not private")?;
        }
    }
    ensure_private_dir(&base)?;
    let dir = base.join(run_id);
    ensure_private_dir(&dir)?;
    Ok(dir)
}

/// A run id held by the plant of a running run: an advisory lock on `<run dir>/plant.lock`. The
/// operating system releases it when the holder exits, however it exits, so a run stopped by
/// `kill -9` can be resumed under its id at once.
#[derive(Debug)]
pub struct RunClaim {
    _file: std::fs::File,
    path: PathBuf,
}

/// Claims run `run_id` for this process, or says that another plant runs it: two plants (or a
/// launcher's credential) must never share a run's private directory.
pub fn claim(run_id: &str) -> anyhow::Result<RunClaim> {
    use std::os::unix::fs::OpenOptionsExt;
    let dir = ensure_run_dir(run_id)?;
    let path = dir.join("plant.lock");
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .mode(0o600)
        .open(&path)
        .with_context(|| format!("cannot open the run's lock {}", path.display()))?;
    match file.try_lock() {
        Ok(()) => Ok(RunClaim { _file: file, path }),
        Err(std::fs::TryLockError::WouldBlock) => bail!(
            "invalid --run-id = {run_id}: already in use on this machine (a plant of that run is \
             running and holds {}); allowed an id no running run has: choose another --run-id, \
             or stop that run first",
            path.display()
        ),
        Err(std::fs::TryLockError::Error(e)) => {
            Err(e).with_context(|| format!("cannot lock {}", path.display()))
        }
    }
}

impl Drop for RunClaim {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_private_directory_is_created_0700_and_others_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path().join("run");
        ensure_private_dir(&d).unwrap();
        let mode = std::fs::metadata(&d).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o700);
        // already there and private: fine
        ensure_private_dir(&d).unwrap();
        // readable by others: refused, naming the mode
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o755)).unwrap();
        let e = check_private_dir(&d).unwrap_err().to_string();
        assert!(e.contains("mode 755"), "{e}");
        // a symbolic link to a private directory: refused
        let real = tmp.path().join("real");
        ensure_private_dir(&real).unwrap();
        let link = tmp.path().join("link");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        let e = check_private_dir(&link).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
        // a file: refused
        let f = tmp.path().join("file");
        std::fs::write(&f, b"").unwrap();
        assert!(check_private_dir(&f)
            .unwrap_err()
            .to_string()
            .contains("not a directory"));
    }

    #[test]
    fn a_run_id_is_held_by_one_plant_at_a_time() {
        let id = format!("claim-test-{}", std::process::id());
        let first = claim(&id).unwrap();
        let e = claim(&id).unwrap_err().to_string();
        assert!(
            e.contains("--run-id") && e.contains("already in use"),
            "{e}"
        );
        drop(first);
        // released with its holder: the id can be claimed again (a resumed run)
        let again = claim(&id).unwrap();
        drop(again);
        let _ = std::fs::remove_dir(run_dir(&id));
    }
}
