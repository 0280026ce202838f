//! The result store: one small JSON file per evaluated point, named by the point's id
//! (`<dir>/<first two hex digits>/<id>.json`), written atomically (temporary file, then rename: a killed process leaves either the whole
//! record or none).
//! A finished point is never lost and never half-written; plans that share points share files.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::record::Record;

/// A result store in a directory.
#[derive(Debug, Clone)]
pub struct Store {
    dir: PathBuf,
}

impl Store {
    /// The store in `dir` (created if missing).
    pub fn open(dir: &Path) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir).map_err(|e| {
            anyhow::anyhow!("cannot create the result store {}: {e}", dir.display())
        })?;
        Ok(Self {
            dir: dir.to_path_buf(),
        })
    }

    /// The store's directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn path(&self, id: &str) -> PathBuf {
        self.dir.join(&id[..2]).join(format!("{id}.json"))
    }

    /// True if the point `id` has a record.
    pub fn contains(&self, id: &str) -> bool {
        self.path(id).is_file()
    }

    /// The record of point `id`, if stored. A file that does not parse (written by something
    /// else) is an error naming it, not silently ignored.
    pub fn get(&self, id: &str) -> anyhow::Result<Option<Record>> {
        let path = self.path(id);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => anyhow::bail!("cannot read {}: {e}", path.display()),
        };
        let rec: Record = serde_json::from_str(&text).map_err(|e| {
            anyhow::anyhow!(
                "{} is not a sweep record ({e}); delete it to recompute the point",
                path.display()
            )
        })?;
        anyhow::ensure!(
            rec.id == id,
            "{} holds the record of another point ({}); delete it to recompute the point",
            path.display(),
            rec.id
        );
        Ok(Some(rec))
    }

    /// Stores `rec` atomically (an existing record of the same point is replaced).
    pub fn put(&self, rec: &Record) -> anyhow::Result<()> {
        let path = self.path(&rec.id);
        let dir = path.parent().expect("a file in a folder");
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
        let tmp = dir.join(format!(
            ".{}.{}.{:?}.tmp",
            rec.id,
            std::process::id(),
            std::thread::current().id()
        ));
        let json = serde_json::to_vec(rec).expect("a record serialises");
        let write = || -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&json)?;
            drop(f);
            std::fs::rename(&tmp, &path)
        };
        write().map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            anyhow::anyhow!("cannot store {}: {e}", path.display())
        })
    }
}
