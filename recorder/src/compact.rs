//! The recording's chunks merged at close: the equivalent of `rerun rrd optimize`.
//!
//! During the run the recorder sends a chunk per entity per block of states, and more often at
//! each flush (what `kill -9` loses is bounded by it, and a live viewer sees the run as it goes):
//! small chunks of the thin entities. At close, the file is read back once, in order, and each
//! entity's consecutive chunks of the same columns are merged up to [`CHUNK_BYTES`] and
//! [`CHUNK_ROWS`] (Rerun's object-store profile, against which `rerun rrd stats` counts its lower
//! bound), then written to a twin file (with the footer) that replaces the recording. Memory stays
//! bounded: one pending chunk per entity, and never more than [`PENDING_BYTES`] in all.

use std::collections::HashMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use re_log_encoding::{DecoderApp, FileSink, FileSinkOptions};
use rerun::external::re_log_types::StoreId;
use rerun::log::{Chunk, LogMsg};
use rerun::SizeBytes;

/// Largest merged chunk, bytes (in memory).
pub const CHUNK_BYTES: u64 = 2 << 20;
/// Most rows of a merged chunk.
pub const CHUNK_ROWS: usize = 65_536;
/// Most bytes held in pending chunks at once.
pub const PENDING_BYTES: u64 = 64 << 20;

/// What merging did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Merged {
    /// Chunks read.
    pub before: u64,
    /// Chunks written.
    pub after: u64,
}

/// Chunks of one entity with the same timelines and components: mergeable.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct Key {
    store: StoreId,
    signature: String,
}

fn key(store: &StoreId, c: &Chunk) -> Key {
    let mut components: Vec<String> = c.components().keys().map(|k| k.to_string()).collect();
    components.sort();
    let mut timelines: Vec<String> = c.timelines().keys().map(|t| t.to_string()).collect();
    timelines.sort();
    Key {
        store: store.clone(),
        signature: format!(
            "{}|{}|{}",
            c.entity_path(),
            timelines.join(","),
            components.join(",")
        ),
    }
}

/// The chunks waiting to be merged and the sink they go to.
struct Merger {
    sink: FileSink,
    pending: HashMap<Key, Chunk>,
    held: u64,
    written: u64,
}

impl Merger {
    fn write(&mut self, store: &StoreId, chunk: &Chunk) -> anyhow::Result<()> {
        self.sink
            .send(LogMsg::ArrowMsg(store.clone(), chunk.to_arrow_msg()?));
        self.written += 1;
        Ok(())
    }

    /// Takes a chunk of a recording: merged with the pending one of its key if both fit in one,
    /// else the pending one is written and this one waits.
    fn take(&mut self, store: &StoreId, chunk: Chunk) -> anyhow::Result<()> {
        let k = key(store, &chunk);
        let size = chunk.heap_size_bytes();
        if let Some(p) = self.pending.remove(&k) {
            let p_size = p.heap_size_bytes();
            self.held -= p_size;
            let fits = p.num_rows() + chunk.num_rows() <= CHUNK_ROWS
                && p_size + size <= CHUNK_BYTES
                && p.concatenable(&chunk);
            if fits {
                let merged = Chunk::concat_and_sort(&p, &chunk)?;
                self.held += merged.heap_size_bytes();
                self.pending.insert(k, merged);
                return self.bound();
            }
            self.write(store, &p)?;
        }
        self.held += size;
        self.pending.insert(k, chunk);
        self.bound()
    }

    /// Writes the largest pending chunks while more than [`PENDING_BYTES`] are held.
    fn bound(&mut self) -> anyhow::Result<()> {
        while self.held > PENDING_BYTES {
            let Some(k) = self
                .pending
                .iter()
                .max_by_key(|(_, c)| c.heap_size_bytes())
                .map(|(k, _)| k.clone())
            else {
                break;
            };
            let c = self.pending.remove(&k).expect("present");
            self.held -= c.heap_size_bytes();
            self.write(&k.store, &c)?;
        }
        Ok(())
    }

    /// Writes every pending chunk of `store`.
    fn flush(&mut self, store: &StoreId) -> anyhow::Result<()> {
        let keys: Vec<Key> = self
            .pending
            .keys()
            .filter(|k| &k.store == store)
            .cloned()
            .collect();
        for k in keys {
            let c = self.pending.remove(&k).expect("present");
            self.held -= c.heap_size_bytes();
            self.write(&k.store, &c)?;
        }
        Ok(())
    }
}

/// The twin file an optimization writes next to `path`.
fn twin(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.optimizing-{}", std::process::id()))
}

/// Merges the chunks of the recording at `path` (with the footer if `footer`) and replaces it;
/// `Ok(None)`, the recording left as it was, if `abort` says so before the end.
pub fn optimize(
    path: &Path,
    footer: bool,
    abort: &dyn Fn() -> bool,
) -> anyhow::Result<Option<Merged>> {
    let out = twin(path);
    let result = merge_into(path, &out, footer, abort);
    match result {
        Ok(Some(m)) => {
            std::fs::rename(&out, path).map_err(|e| {
                anyhow::anyhow!("cannot move {} onto {}: {e}", out.display(), path.display())
            })?;
            Ok(Some(m))
        }
        other => {
            let _ = std::fs::remove_file(&out);
            other
        }
    }
}

fn merge_into(
    path: &Path,
    out: &Path,
    footer: bool,
    abort: &dyn Fn() -> bool,
) -> anyhow::Result<Option<Merged>> {
    let file = std::fs::File::open(path)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    let messages = DecoderApp::decode_eager(BufReader::with_capacity(1 << 20, file))?;
    let sink = FileSink::with_options(
        out,
        FileSinkOptions {
            write_footer: footer,
        },
    )
    .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
    let mut m = Merger {
        sink,
        pending: HashMap::new(),
        held: 0,
        written: 0,
    };
    let mut read = 0u64;
    for msg in messages {
        if abort() {
            return Ok(None);
        }
        match msg? {
            LogMsg::ArrowMsg(store, arrow) => {
                read += 1;
                let chunk = Chunk::from_arrow_msg(&arrow)?;
                if store.is_recording() && !chunk.is_static() {
                    m.take(&store, chunk)?;
                } else {
                    m.write(&store, &chunk)?;
                }
            }
            other => {
                // the store's chunks so far precede what follows them (an activation command
                // follows its blueprint)
                m.flush(&other.store_id().clone())?;
                m.sink.send(other);
            }
        }
    }
    let stores: Vec<StoreId> = m.pending.keys().map(|k| k.store.clone()).collect();
    for s in stores {
        m.flush(&s)?;
    }
    let written = m.written;
    m.sink
        .flush_blocking(std::time::Duration::from_secs(60))
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
    // dropping the sink ends its writer, which writes the footer
    drop(m);
    Ok(Some(Merged {
        before: read,
        after: written,
    }))
}
