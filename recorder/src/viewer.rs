//! Live view: the recording also streams to a running Rerun viewer over gRPC while the file is
//! written (`crawler-recorder record --connect [URL]`, `--spawn`).
//!
//! The viewer is best effort and never holds up the file: the recording stream hands each message
//! to [`ViewerSink`], which queues it (at most [`QUEUE`] messages and [`QUEUE_BYTES`] bytes) for a
//! thread that owns the
//! Rerun SDK's [`GrpcSink`]. While the viewer is not reachable the queue keeps the first messages
//! (the recording's header and layout) and later ones are dropped and counted; once it connects it
//! gets what was kept and everything from then on. If it goes away, the rest is dropped. The file
//! always gets every message. [`Viewer::finish`] flushes the viewer with a bound at the end and
//! says what it got.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{bounded, Receiver, Sender};
use rerun::external::re_chunk_store::external::re_chunk::external::re_byte_size::SizeBytes;
use rerun::external::re_uri::ProxyUri;
use rerun::log::LogMsg;
use rerun::sink::{GrpcSink, GrpcSinkConnectionState, LogSink, SinkFlushError};

/// The Rerun SDK's default viewer address, `rerun+http://127.0.0.1:9876/proxy`.
pub const DEFAULT_URL: &str = rerun::DEFAULT_CONNECT_URL;

/// Messages held for the viewer while it connects or catches up (a message is one chunk of the
/// batcher, typically a few KiB: a few seconds of a run).
pub const QUEUE: usize = 4096;

/// Bytes held for the viewer at most (the memory a missing or slow viewer costs).
pub const QUEUE_BYTES: u64 = 64 << 20;

/// Parses a viewer address; errors name `--connect`.
pub fn parse_url(url: &str) -> anyhow::Result<ProxyUri> {
    url.parse::<ProxyUri>().map_err(|e| {
        anyhow::anyhow!(
            "invalid --connect = {url}: allowed the gRPC address of a Rerun viewer, such as {DEFAULT_URL} ({e})"
        )
    })
}

/// State of the link to the viewer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Link {
    /// Not connected yet (the SDK retries every 100 ms).
    Connecting,
    /// Connected; messages are flowing.
    Connected,
    /// The viewer closed the connection (or the address is unusable); no more attempts.
    Gone,
}

impl Link {
    fn from_u8(v: u8) -> Self {
        match v {
            0 => Link::Connecting,
            1 => Link::Connected,
            _ => Link::Gone,
        }
    }
}

/// What the viewer got, at the end of the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Delivery {
    /// The link at the end.
    pub link: Link,
    /// The viewer confirmed everything sent to it (the final flush succeeded).
    pub flushed: bool,
    /// Messages the viewer never got (it was absent, behind or gone).
    pub dropped: u64,
}

struct Shared {
    link: AtomicU8,
    /// Bytes of the messages in the queue.
    queued: AtomicU64,
    dropped: AtomicU64,
    quit: AtomicBool,
    warned_drop: AtomicBool,
    url: String,
}

impl Shared {
    fn set(&self, link: Link) {
        self.link.store(link as u8, Ordering::Relaxed);
    }
    fn drop_one(&self) {
        self.dropped.fetch_add(1, Ordering::Relaxed);
    }
}

enum Cmd {
    /// A message and its size in bytes.
    Msg(LogMsg, u64),
    Flush(Sender<Result<(), String>>, Duration),
}

/// The sink given to the recording stream (next to the file sink).
pub struct ViewerSink {
    tx: Sender<Cmd>,
    shared: Arc<Shared>,
}

/// The recorder's handle on the viewer link.
pub struct Viewer {
    tx: Sender<Cmd>,
    shared: Arc<Shared>,
}

impl Viewer {
    /// Starts connecting to the viewer at `uri` (in the background: never blocks).
    pub fn connect(uri: ProxyUri) -> anyhow::Result<(Viewer, ViewerSink)> {
        let (tx, rx) = bounded(QUEUE);
        let shared = Arc::new(Shared {
            link: AtomicU8::new(Link::Connecting as u8),
            queued: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            quit: AtomicBool::new(false),
            warned_drop: AtomicBool::new(false),
            url: uri.to_string(),
        });
        let s = shared.clone();
        std::thread::Builder::new()
            .name("viewer_link".into())
            .spawn(move || forward(uri, rx, &s))
            .map_err(|e| anyhow::anyhow!("cannot start the viewer link: {e}"))?;
        Ok((
            Viewer {
                tx: tx.clone(),
                shared: shared.clone(),
            },
            ViewerSink { tx, shared },
        ))
    }

    /// The viewer's address.
    pub fn url(&self) -> &str {
        &self.shared.url
    }

    /// The link now.
    pub fn link(&self) -> Link {
        Link::from_u8(self.shared.link.load(Ordering::Relaxed))
    }

    /// Waits at most `timeout` for the viewer to confirm everything queued so far (call after the
    /// recording stream was flushed), then lets the link go.
    pub fn finish(&self, timeout: Duration) -> Delivery {
        let flushed = if self.link() == Link::Connected {
            let (done_tx, done_rx) = bounded(1);
            self.tx
                .send_timeout(Cmd::Flush(done_tx, timeout), timeout)
                .is_ok()
                && matches!(done_rx.recv_timeout(timeout), Ok(Ok(())))
        } else {
            false
        };
        self.shared.quit.store(true, Ordering::Relaxed);
        Delivery {
            link: self.link(),
            flushed,
            dropped: self.shared.dropped.load(Ordering::Relaxed),
        }
    }
}

impl LogSink for ViewerSink {
    fn send(&self, msg: LogMsg) {
        let size = msg.total_size_bytes();
        // counted before it is queued, so the link's thread never takes off more than was added
        let before = self.shared.queued.fetch_add(size, Ordering::Relaxed);
        let kept = before + size <= QUEUE_BYTES && self.tx.try_send(Cmd::Msg(msg, size)).is_ok();
        if !kept {
            self.shared.queued.fetch_sub(size, Ordering::Relaxed);
            self.shared.drop_one();
            if !self.shared.warned_drop.swap(true, Ordering::Relaxed)
                && Link::from_u8(self.shared.link.load(Ordering::Relaxed)) == Link::Connected
            {
                eprintln!(
                    "crawler-recorder: warning: the viewer at {} is behind; it misses some data (the file has everything)",
                    self.shared.url
                );
            }
        }
    }

    /// Never waits for the viewer: the recording's flushes are for the file. [`Viewer::finish`]
    /// flushes the viewer, with a bound.
    fn flush_blocking(&self, _timeout: Duration) -> Result<(), SinkFlushError> {
        Ok(())
    }
}

/// The link's thread: holds the queue until the viewer answers, then forwards.
fn forward(uri: ProxyUri, rx: Receiver<Cmd>, shared: &Shared) {
    let grpc = GrpcSink::new(uri);
    loop {
        match grpc.status() {
            GrpcSinkConnectionState::Connected => {
                shared.set(Link::Connected);
                break;
            }
            GrpcSinkConnectionState::Disconnected(_) => {
                shared.set(Link::Gone);
                break;
            }
            GrpcSinkConnectionState::Connecting { .. } => {
                if shared.quit.load(Ordering::Relaxed) {
                    // never connected: leave without the SDK's flush on drop (it waits 5 s)
                    std::mem::forget(grpc);
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
    let mut gone = matches!(grpc.status(), GrpcSinkConnectionState::Disconnected(_));
    for cmd in rx.iter() {
        match cmd {
            Cmd::Msg(msg, size) => {
                shared.queued.fetch_sub(size, Ordering::Relaxed);
                if gone {
                    shared.drop_one();
                    continue;
                }
                grpc.send(msg);
                if let GrpcSinkConnectionState::Disconnected(_) = grpc.status() {
                    gone = true;
                    shared.set(Link::Gone);
                    shared.drop_one();
                    eprintln!(
                        "crawler-recorder: warning: the viewer at {} went away; recording to the file only",
                        shared.url
                    );
                }
            }
            Cmd::Flush(done, timeout) => {
                let r = if gone {
                    Err("the viewer went away".to_string())
                } else {
                    grpc.flush_blocking(timeout).map_err(|e| e.to_string())
                };
                let _ = done.send(r);
            }
        }
    }
}

/// Starts a Rerun viewer listening on loopback at the port of `uri` (nothing is started if
/// something already listens there), `exe` or `rerun` from `PATH`. Returns the viewer's process
/// id when one was started. The viewer outlives the recorder (the user closes it).
pub fn spawn(uri: &ProxyUri, exe: Option<&std::path::Path>) -> anyhow::Result<Option<u32>> {
    anyhow::ensure!(
        uri.origin.is_localhost(),
        "invalid --connect = {uri} with --spawn: allowed a loopback address (the viewer is started on this machine)"
    );
    let opts = rerun::SpawnOptions {
        port: uri.origin.port,
        wait_for_bind: true,
        executable_path: exe.map(|p| p.display().to_string()),
        hide_welcome_screen: true,
        // loopback only, like every socket of the project
        extra_args: vec!["--bind".into(), "127.0.0.1".into()],
        ..Default::default()
    };
    let info = rerun::spawn(&opts).map_err(|e| anyhow::anyhow!("cannot start a viewer: {e}"))?;
    Ok(info.child_pid)
}
