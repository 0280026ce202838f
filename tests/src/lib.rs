//! Helpers for the end-to-end tests: the real binaries, isolated runs, recordings read back.
//!
//! Every test run gets its own run id and its own unix socket in a fresh temporary directory, so
//! tests can run in parallel without seeing each other; every spawned process is killed when its
//! [`Proc`] is dropped, and every wait is bounded. The processes of a run get that directory as
//! their `XDG_RUNTIME_DIR`, so the run's private directory (credential, zenoh user file) lives
//! there too and goes away with it.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// The directory holding the workspace's binaries (next to the test executable's `deps/`).
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("deps dir");
    deps.parent().expect("profile dir").to_path_buf()
}

/// Path of one of the project's binaries.
///
/// `cargo test --workspace` builds every binary (each binary's package has an integration test,
/// which makes cargo build it). When a test is run on its own (`cargo test -p crawler-e2e`) and
/// a binary is missing, the workspace's binaries are built once per test process, before any
/// test of that process spawns one, so no test's timeouts run while cargo compiles.
pub fn bin(name: &str) -> PathBuf {
    static BUILT: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    let path = bin_dir().join(name);
    if !path.is_file() {
        let built = BUILT.get_or_init(|| {
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let mut cmd = Command::new(cargo);
            cmd.args(["build", "--workspace", "--bins"]);
            if bin_dir().ends_with("release") {
                cmd.arg("--release");
            }
            match cmd.status() {
                Ok(s) if s.success() => Ok(()),
                Ok(s) => Err(format!("building the binaries failed ({s})")),
                Err(e) => Err(format!("cannot run cargo: {e}")),
            }
        });
        if let Err(e) = built {
            panic!("{e}");
        }
    }
    assert!(path.is_file(), "{} not found", path.display());
    path
}

/// The repository's root.
pub fn repo_root() -> PathBuf {
    // cargo test sets the variable for the run too: the checkout being tested, even when the test
    // binary was compiled in another checkout that shares the target dir (cargo hashes path
    // packages relative to the workspace, so it may reuse that binary)
    std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

/// The Python of the project's venv with the pinned packages, which `scripts/setup.sh` (or
/// `scripts/setup-python.sh`) installs before the tests; a test never installs packages itself.
/// Panics, naming the set-up step, when the venv is missing or older than a requirements file.
pub fn python() -> PathBuf {
    let root = repo_root();
    let p = root.join(".venv/bin/python");
    let modified = |f: &str| {
        std::fs::metadata(root.join(f))
            .and_then(|m| m.modified())
            .ok()
    };
    let installed = modified(".venv/.installed");
    let stale = ["requirements.txt", "requirements-peers.txt"]
        .into_iter()
        .filter(|f| matches!((modified(f), installed), (Some(r), Some(i)) if r > i))
        .collect::<Vec<_>>();
    assert!(
        p.is_file() && installed.is_some(),
        "the tests need the project's Python venv ({} is missing): run scripts/setup.sh once",
        if p.is_file() {
            ".venv/.installed"
        } else {
            ".venv/bin/python"
        }
    );
    assert!(
        stale.is_empty(),
        "the venv is older than {}: run scripts/setup.sh to install the pinned packages",
        stale.join(" and ")
    );
    p
}

/// The venv's Python with the project's package `softcrawler` installed from the current sources
/// (`scripts/setup-python.sh --package`, i.e. `pip install ./python`: maturin builds the
/// extension with cargo in the workspace's target dir), once per test process. The Python
/// examples import it. Call it before starting a plant that waits for a Python controller: the
/// first build of the extension takes minutes.
pub fn softcrawler() -> PathBuf {
    static DONE: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    let py = python();
    let done = DONE.get_or_init(|| {
        let started = Instant::now();
        let mut cmd = Command::new("bash");
        cmd.arg(repo_root().join("scripts/setup-python.sh"))
            .arg("--package")
            .current_dir(repo_root());
        // the test's own cargo variables are not the nested build's
        for (k, _) in std::env::vars_os() {
            let k = k.to_string_lossy().into_owned();
            if k.starts_with("CARGO_") && k != "CARGO_HOME" && k != "CARGO_TARGET_DIR" {
                cmd.env_remove(k);
            }
        }
        let out = cmd
            .output()
            .map_err(|e| format!("cannot run scripts/setup-python.sh --package: {e}"))?;
        eprintln!(
            "softcrawler installed in {:.1} s",
            started.elapsed().as_secs_f64()
        );
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "pip install ./python failed:\n{}\n{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ))
        }
    });
    if let Err(e) = done {
        panic!("{e}");
    }
    py
}

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// An isolated run: its own id, its own socket, its own temporary directory.
pub struct Run {
    /// Run id.
    pub id: String,
    /// Rendezvous endpoint.
    pub endpoint: String,
    /// Scratch directory (checkpoints, recordings, logs).
    pub dir: tempfile::TempDir,
}

impl Run {
    /// A fresh run tagged `tag`.
    pub fn new(tag: &str) -> Self {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let id = format!("{tag}-{}-{n}", std::process::id());
        let dir = tempfile::Builder::new()
            .prefix("crw")
            .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o700))
            .tempdir_in("/tmp")
            .expect("temp dir");
        let endpoint = format!("unixsock-stream/{}/z.sock", dir.path().display());
        Self { id, endpoint, dir }
    }

    /// Another run with the same id, in its own directory at its own endpoint (a run started
    /// again after the first ended, as a user would with the same `--run-id`).
    pub fn same_id(&self) -> Self {
        let again = Self::new("again");
        Self {
            id: self.id.clone(),
            ..again
        }
    }

    /// A path in the run's directory.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// The run's private directory, as its processes compute it (their `XDG_RUNTIME_DIR` is the
    /// run's directory).
    pub fn private_dir(&self) -> PathBuf {
        self.dir.path().join("crawler").join(&self.id)
    }

    /// Where the plant of this run writes the run's credential.
    pub fn credential(&self) -> PathBuf {
        self.private_dir().join("credential")
    }

    /// A zenoh session on this run's endpoint (not a process of the run: a peer that dials it
    /// in the background) that presents `access` and reassembles messages up to the run's limits
    /// of `cells` cells.
    pub fn session(&self, access: &crawler_transport::Access, cells: usize) -> zenoh::Session {
        use zenoh::Wait;
        let net = crawler_transport::Network::loopback(&self.id, &self.endpoint).unwrap();
        let limit = crawler_protocol::RunLimits::new(cells).largest();
        let json = crawler_transport::probe_config_json(&net, access, limit);
        let session = zenoh::open(zenoh::Config::from_json5(&json).unwrap())
            .wait()
            .unwrap();
        // give an admitted session a moment to link and exchange declarations
        std::thread::sleep(Duration::from_millis(300));
        session
    }

    /// The run's credential, once the plant wrote it (bounded wait).
    pub fn load_credential(&self) -> crawler_transport::Credential {
        let path = self.wait_for_credential(Duration::from_secs(30));
        crawler_transport::Credential::load(&path, &self.id).unwrap()
    }

    /// A session that knows the run's zenoh password but not its message key: what a shared
    /// router, or anyone who only passed transport authentication, is.
    pub fn transport_only_session(&self, cells: usize) -> zenoh::Session {
        let pw = self.load_credential().transport_password();
        self.session(&crawler_transport::Access::Password(pw), cells)
    }

    /// A participant of this run on a session that presents `access` (a process of role `role`
    /// with a fresh id), sealing with `seal` (`None`: it holds no message key), in the run
    /// instance that the plant's answer to a `get` named, and the plant's id (bounded wait): what
    /// an attacker who holds the credential, or only the password, can be. (It reads the
    /// answer's envelope without checking its seal: whoever can read the run can learn both.)
    pub fn participant(
        &self,
        access: &crawler_transport::Access,
        seal: Option<crawler_transport::Seal>,
        role: crawler_protocol::Role,
        cells: usize,
    ) -> (crawler_transport::Participant, crawler_protocol::ProcessId) {
        use zenoh::Wait;
        let session = self.session(access, cells);
        let keys = crawler_protocol::RunKeys::new(&self.id).unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        let header = loop {
            let replies = session
                .get(keys.model())
                .payload(vec![0u8; 16])
                .timeout(Duration::from_millis(500))
                .wait()
                .unwrap();
            let found = replies.iter().find_map(|r| {
                let att = r.result().ok()?.attachment()?.to_bytes().into_owned();
                crawler_protocol::Header::decode(&att).ok()
            });
            if let Some(h) = found {
                break h;
            }
            assert!(Instant::now() < deadline, "the plant did not answer");
            std::thread::sleep(Duration::from_millis(100));
        };
        let p = crawler_transport::Participant::new(
            session,
            role,
            crawler_transport::process_id(),
            seal,
            crawler_transport::gate::RunInstance::known(header.run),
        );
        (p, header.sender)
    }

    /// Waits until the plant wrote the run's credential (bounded), and returns its path.
    pub fn wait_for_credential(&self, timeout: Duration) -> PathBuf {
        let path = self.credential();
        let deadline = Instant::now() + timeout;
        while !path.is_file() {
            assert!(
                Instant::now() < deadline,
                "no credential {} within {timeout:?}",
                path.display()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        path
    }

    fn net(&self) -> Vec<String> {
        vec![
            "--run-id".into(),
            self.id.clone(),
            "--endpoint".into(),
            self.endpoint.clone(),
        ]
    }

    /// `crawler-plant run` with `args` (network flags added).
    pub fn plant(&self, args: &[&str]) -> Proc {
        let mut a: Vec<String> = vec!["run".into()];
        a.extend(self.net());
        a.extend([
            "--checkpoint".into(),
            self.path("plant.ckpt").display().to_string(),
        ]);
        a.extend(args.iter().map(|s| s.to_string()));
        Proc::spawn("plant", &bin("crawler-plant"), &a, self.dir.path())
    }

    /// `crawler-controller run` with `args` (network flags added).
    pub fn controller(&self, args: &[&str]) -> Proc {
        let mut a: Vec<String> = vec!["run".into()];
        a.extend(self.net());
        a.extend(args.iter().map(|s| s.to_string()));
        Proc::spawn(
            "controller",
            &bin("crawler-controller"),
            &a,
            self.dir.path(),
        )
    }

    /// `crawler-recorder record --out FILE` with `args` (network flags added).
    pub fn bridge(&self, out: &Path, args: &[&str]) -> Proc {
        let mut a: Vec<String> = vec!["record".into()];
        a.extend(self.net());
        a.extend(["--out".into(), out.display().to_string()]);
        a.extend(args.iter().map(|s| s.to_string()));
        Proc::spawn("bridge", &bin("crawler-recorder"), &a, self.dir.path())
    }

    /// The Python example controller with `args`.
    pub fn python_controller(&self, args: &[&str]) -> Proc {
        self.python_example("python_controller.py", args)
    }

    /// The Python example `examples/<script>` with `args` (network flags added), run by the
    /// venv's Python with `softcrawler` installed ([`softcrawler`]).
    pub fn python_example(&self, script: &str, args: &[&str]) -> Proc {
        let mut a: Vec<String> = vec![repo_root()
            .join("examples")
            .join(script)
            .display()
            .to_string()];
        a.extend(self.net());
        a.extend(args.iter().map(|s| s.to_string()));
        Proc::spawn("python", &softcrawler(), &a, self.dir.path())
    }
}

/// A spawned process; killed on drop. Its stdout and stderr go to files.
pub struct Proc {
    /// Name for messages.
    pub name: String,
    /// The child.
    pub child: Child,
    out: PathBuf,
    err: PathBuf,
}

/// How a process ended.
#[derive(Debug)]
pub struct Ended {
    /// Exit status.
    pub status: ExitStatus,
    /// Everything it printed on stdout.
    pub stdout: String,
    /// Everything it printed on stderr.
    pub stderr: String,
    /// When it was seen to end.
    pub at: Instant,
}

impl Proc {
    /// Spawns `exe args` in `dir`.
    pub fn spawn(name: &str, exe: &Path, args: &[String], dir: &Path) -> Self {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let out = dir.join(format!("{name}-{n}.out"));
        let err = dir.join(format!("{name}-{n}.err"));
        let child = Command::new(exe)
            .args(args)
            .current_dir(dir)
            // not `cargo run`: the launcher must not rebuild the binaries under test
            .env_remove("CARGO")
            .env("XDG_RUNTIME_DIR", dir)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&out).expect("stdout file"))
            .stderr(std::fs::File::create(&err).expect("stderr file"))
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", exe.display()));
        Self {
            name: name.to_string(),
            child,
            out,
            err,
        }
    }

    /// Process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// What it printed on stderr so far.
    pub fn stderr_so_far(&self) -> String {
        std::fs::read_to_string(&self.err).unwrap_or_default()
    }

    /// Waits at most `timeout`; panics (after killing it) if it does not end.
    pub fn wait(mut self, timeout: Duration) -> Ended {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                let read = |p: &Path| {
                    let mut s = String::new();
                    let _ = std::fs::File::open(p).and_then(|mut f| f.read_to_string(&mut s));
                    s
                };
                return Ended {
                    status,
                    stdout: read(&self.out),
                    stderr: read(&self.err),
                    at: Instant::now(),
                };
            }
            if Instant::now() >= deadline {
                let err = self.stderr_so_far();
                let _ = self.child.kill();
                panic!(
                    "{} did not end within {:?}; stderr:\n{err}",
                    self.name, timeout
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Sends `signal` (e.g. "-9", "-INT", "-TERM").
    pub fn signal(&self, signal: &str) {
        let status = Command::new("kill")
            .args([signal, &self.pid().to_string()])
            .status()
            .expect("kill");
        assert!(status.success());
    }

    /// Waits until its stderr contains `needle` (bounded).
    pub fn wait_for_stderr(&self, needle: &str, timeout: Duration) {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if self.stderr_so_far().contains(needle) {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!(
            "{} never printed {needle:?}; stderr:\n{}",
            self.name,
            self.stderr_so_far()
        );
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Resident memory of process `pid` from `/proc/<pid>/status`: (now, peak), KiB; `None` once
/// the process has ended.
pub fn rss_kib(pid: u32) -> Option<(u64, u64)> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field = |name: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse::<u64>().ok())
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

/// Parses the JSON printed on stdout.
pub fn json(stdout: &str) -> serde_json::Value {
    serde_json::from_str(stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {stdout}"))
}

/// `crawler-plant simulate --json` with `args`.
pub fn simulate(args: &[&str]) -> serde_json::Value {
    let out = Command::new(bin("crawler-plant"))
        .arg("simulate")
        .arg("--json")
        .args(args)
        .output()
        .expect("simulate");
    assert!(
        out.status.success(),
        "simulate failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    json(&String::from_utf8_lossy(&out.stdout))
}

/// What a recording holds, per entity path.
#[derive(Debug, Default)]
pub struct Recording {
    /// Entity path → its data.
    pub entities: BTreeMap<String, Entity>,
}

/// One entity of a recording.
#[derive(Debug, Default, Clone)]
pub struct Entity {
    /// Rows logged on the `step` timeline (static rows excluded).
    pub rows: usize,
    /// The `step` of each row.
    pub steps: Vec<i64>,
    /// Scalar values (Scalars archetype), in row order.
    pub scalars: Vec<f64>,
    /// Line strips (LineStrips2D archetype) of every row, static ones included: each row's
    /// strips, each strip its points.
    pub strips: Vec<Vec<Vec<[f32; 2]>>>,
    /// Bar charts (BarChart archetype): the `step` of each row and its values, in step order.
    pub bars: Vec<(i64, Vec<f64>)>,
    /// Points (Points2D archetype): the `step` of each row and its positions, in step order.
    pub points: Vec<(i64, Vec<[f32; 2]>)>,
    /// Texts (TextLog archetype), static ones included, in the order read.
    pub texts: Vec<String>,
    /// Items of the list columns named `*:node` (the stick episodes' nodes), over all rows.
    pub nodes: usize,
}

impl Recording {
    /// The entity at `path` (panics with the list of paths if absent).
    pub fn entity(&self, path: &str) -> &Entity {
        self.entities.get(path).unwrap_or_else(|| {
            panic!(
                "no entity {path} in the recording; it has: {:?}",
                self.entities.keys().collect::<Vec<_>>()
            )
        })
    }
}

/// Reads an `.rrd` file with the rerun crate's own reader (its chunk store).
pub fn read_recording(path: &Path) -> anyhow::Result<Recording> {
    use rerun::dataframe::external::re_chunk_store::{ChunkStore, ChunkStoreConfig};
    let file = std::fs::File::open(path)?;
    let stores = ChunkStore::from_rrd_reader(
        &ChunkStoreConfig::ALL_DISABLED,
        &mut std::io::BufReader::new(file),
    )?;
    let scalars = rerun::Scalars::descriptor_scalars().component;
    let strips = rerun::LineStrips2D::descriptor_strips().component;
    let bar_values = rerun::BarChart::descriptor_values().component;
    let positions = rerun::Points2D::descriptor_positions().component;
    let texts = rerun::TextLog::descriptor_text().component;
    let mut rec = Recording::default();
    for (id, store) in &stores {
        if id.kind() != rerun::StoreKind::Recording {
            continue;
        }
        for chunk in store.iter_physical_chunks() {
            let path = chunk.entity_path().to_string();
            let path = path.trim_start_matches('/').to_string();
            let e = rec.entities.entry(path).or_default();
            for row in chunk.iter_component::<rerun::components::Text>(texts) {
                e.texts.extend(row.iter().map(|t| t.as_str().to_string()));
            }
            for (id, column) in chunk.components().iter() {
                if id.as_str().ends_with(":node") {
                    e.nodes += column.list_array.values().len();
                }
            }
            for row in chunk.iter_component::<rerun::components::LineStrip2D>(strips) {
                e.strips.push(
                    row.iter()
                        .map(|strip| strip.0.iter().map(|p| [p.x(), p.y()]).collect())
                        .collect(),
                );
            }
            let Some(steps) = chunk.timelines().get(&rerun::TimelineName::from("step")) else {
                continue;
            };
            let order: Vec<usize> = {
                let mut idx: Vec<usize> = (0..chunk.num_rows()).collect();
                idx.sort_by_key(|&i| steps.times_raw()[i]);
                idx
            };
            let values: Vec<Vec<f64>> = chunk
                .iter_slices::<f64>(scalars)
                .map(|s| s.to_vec())
                .collect();
            let bars: Vec<Vec<f64>> = chunk
                .iter_component::<rerun::components::TensorData>(bar_values)
                .map(|row| {
                    use rerun::datatypes::TensorBuffer;
                    match row.as_slice().first().map(|t| &t.0.buffer) {
                        Some(TensorBuffer::F64(b)) => b.to_vec(),
                        Some(TensorBuffer::F32(b)) => b.iter().map(|&x| f64::from(x)).collect(),
                        _ => Vec::new(),
                    }
                })
                .collect();
            for (i, bar) in bars.into_iter().enumerate() {
                e.bars.push((steps.times_raw()[i], bar));
            }
            let rows = chunk.iter_component::<rerun::components::Position2D>(positions);
            for (i, row) in rows.enumerate() {
                let row: Vec<[f32; 2]> = row.iter().map(|p| [p.x(), p.y()]).collect();
                if !row.is_empty() {
                    e.points.push((steps.times_raw()[i], row));
                }
            }
            for i in order {
                e.rows += 1;
                e.steps.push(steps.times_raw()[i]);
                if let Some(v) = values.get(i).and_then(|v| v.first()) {
                    e.scalars.push(*v);
                }
            }
        }
    }
    for e in rec.entities.values_mut() {
        let mut pairs: Vec<(i64, Option<f64>)> = e
            .steps
            .iter()
            .enumerate()
            .map(|(i, &s)| (s, e.scalars.get(i).copied()))
            .collect();
        pairs.sort_by_key(|p| p.0);
        e.steps = pairs.iter().map(|p| p.0).collect();
        e.scalars = pairs.iter().filter_map(|p| p.1).collect();
        e.bars.sort_by_key(|b| b.0);
        e.points.sort_by_key(|p| p.0);
    }
    Ok(rec)
}
