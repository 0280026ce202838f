//! `crawler-recorder record`: subscribe to a run and write a Rerun recording.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::{Args, Parser, Subcommand};
use crossbeam_channel::{bounded, Sender};
use zenoh::Wait;

use crawler_cli::Exit;
use crawler_protocol::{decode, Environment, Message, ModelInfo, Role, RunKeys, RunLimits};
use crawler_recorder::output::Output;
use crawler_recorder::viewer::{self, Link, Viewer};
use crawler_recorder::{Incoming, Recorder, RecorderOptions};
use crawler_transport::budget::{ByteBudget, Charged};
use crawler_transport::gate::{Gate, Refused};
use crawler_transport::{Credential, Network, Seal};

/// Byte budget of the states in the inbox between the zenoh callbacks and the writer. The three
/// budgets below (44 MiB together) are what a writer that stalls under a flood (a slow disk's
/// flush, a starved core) lets the inbox grow to, so together with zenoh's buffers they must stay
/// well under the 64 MiB a process may grow by (`docs/security.md`). A message larger than its
/// budget (a state of more than 650 000 cells) still passes when nothing else is queued.
const STATE_BYTES: usize = 24 << 20;
/// Byte budget of everything else in it (events, metrics, predictions): its own, so a backlog of
/// states never crowds them out.
const OTHER_BYTES: usize = 16 << 20;
/// Statuses have an inbox and a budget of their own: a flood of episodes (tens of thousands per
/// second in hard stick-slip) must never drop the plant's final status.
const STATUS_BYTES: usize = 4 << 20;
/// Messages the status inbox holds (a process sends about one status a second).
const STATUS_SLOTS: usize = 1024;

#[derive(Parser)]
#[command(
    name = "crawler-recorder",
    version,
    about = "Records a soft-crawler co-simulation into a Rerun .rrd file"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Subscribe to a run (before or after it starts) and record it until it ends.
    Record(RecordArgs),
}

#[derive(Args)]
struct RecordArgs {
    #[command(flatten)]
    network: crawler_transport::NetworkArgs,
    /// Output file.
    #[arg(long, value_name = "FILE.rrd", default_value = "crawler.rrd")]
    out: PathBuf,
    /// Record the fields of every K-th step (metrics, events and lanes: always).
    #[arg(long, value_name = "K", default_value_t = 1)]
    every: u64,
    /// Most stick/slip lanes (evenly spaced nodes).
    #[arg(long, default_value_t = 64)]
    lanes: usize,
    /// Recorded steps per heatmap block.
    #[arg(long, default_value_t = 128)]
    heatmap_rows: usize,
    /// Capacity of the inbox between the zenoh callbacks and the writer, messages (the byte
    /// budgets bound its memory: 24 MiB of states, 16 MiB of the rest, 4 MiB of statuses).
    #[arg(long, default_value_t = 65536)]
    inbox: usize,
    /// Leave out the index of chunks (Rerun's footer) at the end of the file: memory stays flat
    /// however long the run (the index costs about 40 MB per 10^6 steps), but `rerun rrd verify`
    /// needs `--check-footers=false` (or add the index later with `rerun rrd optimize`).
    #[arg(long)]
    no_footer: bool,
    /// Also stream the recording live to a running Rerun viewer at URL (its gRPC address) while
    /// writing the file. Start one with `rerun` (or `.venv/bin/rerun`), or pass --spawn. A viewer
    /// that is absent, slow or closed never stops the recording: it misses data, the file does not.
    #[arg(long, value_name = "URL", num_args = 0..=1, default_missing_value = crawler_recorder::viewer::DEFAULT_URL)]
    connect: Option<String>,
    /// Start a Rerun viewer (listening on loopback at the --connect port, default 9876) unless one
    /// already runs there, and stream to it; implies --connect.
    #[arg(long)]
    spawn: bool,
    /// The `rerun` executable --spawn starts (default: `rerun` from PATH).
    #[arg(long, value_name = "PATH", requires = "spawn")]
    viewer_exe: Option<PathBuf>,
    /// Give up if no message arrives for this many seconds (default: wait as long as it takes).
    #[arg(long)]
    idle_timeout: Option<f64>,
    /// Validate every input (flags, --out, --connect, network options) and exit without
    /// creating a file or subscribing to anything.
    #[arg(long)]
    check: bool,
}

/// One malloc arena for the whole process. glibc gives threads their own arenas; the Rerun SDK's
/// batcher and file writer allocate chunk buffers on one thread and free them on another, which
/// fragments the arenas, and the resident memory crept up by about 55 % over a 10^6-step run.
/// With one arena it stays flat (`bench/long_run.py`). Must run before any thread starts.
fn one_malloc_arena() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator tuning; called before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

fn main() -> ExitCode {
    one_malloc_arena();
    crawler_cli::cpu::ensure_cpu_features();
    let Command::Record(a) = Cli::parse().command;
    match record(a) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("crawler-recorder: error: {e:#}");
            Exit::Failure.into()
        }
    }
}

/// Where the callbacks put what passed the gates.
/// A message of the inbox with the moment it arrived (the recorder's lag is measured from it).
type Arrival = (Instant, Charged<Incoming>);

#[derive(Clone)]
struct Sink {
    tx: Sender<Arrival>,
    status_tx: Sender<Arrival>,
    statuses: ByteBudget,
    states: ByteBudget,
    others: ByteBudget,
    dropped: Arc<AtomicU64>,
}

fn subscribe(
    session: &zenoh::Session,
    key: String,
    gate: Gate,
    sink: Sink,
    wrap: fn(Vec<u8>) -> Incoming,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
    session
        .declare_subscriber(key)
        .callback(move |sample| {
            // Oversized and unsealed payloads are counted by the gate. Never block the
            // publisher: if the writer is behind (inbox full in messages or bytes), drop and count.
            let Ok(bytes) = gate.admit(&sample) else {
                return;
            };
            let len = bytes.len();
            let msg = wrap(bytes);
            let (budget, tx) = match msg {
                Incoming::State(_) => (&sink.states, &sink.tx),
                Incoming::Status(_) => (&sink.statuses, &sink.status_tx),
                _ => (&sink.others, &sink.tx),
            };
            let queued = budget
                .charge(msg, len)
                .is_some_and(|m| tx.try_send((Instant::now(), m)).is_ok());
            if !queued {
                sink.dropped.fetch_add(1, Ordering::Relaxed);
            }
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh: {e}"))
}

/// The recorder's session and its subscriptions.
struct Connection {
    session: zenoh::Session,
    _subs: Vec<zenoh::pubsub::Subscriber<()>>,
    _plants: zenoh::pubsub::Subscriber<()>,
    _token: zenoh::liveliness::LivelinessToken,
    /// The gate of the state key (its limit is tightened once the run's size is known).
    state_gate: Gate,
    seal: Option<Seal>,
    limit: usize,
}

impl Connection {
    /// Connects to the plant (waiting for it until `give_up`), reassembling at most `limit`
    /// bytes, subscribed to every key of the run.
    fn open(
        network: &Network,
        credential: &mut Option<Credential>,
        limit: usize,
        (sink, refused): (&Sink, &Arc<Refused>),
        (plant_tx, id): (Sender<Incoming>, &str),
        give_up: &mut dyn FnMut() -> bool,
    ) -> anyhow::Result<Option<Self>> {
        let keys = RunKeys::new(&network.run_id)?;
        let Some((session, used)) = crawler_transport::connect_client(
            Role::Bridge,
            network,
            credential.clone(),
            limit,
            give_up,
        )?
        else {
            return Ok(None);
        };
        *credential = used;
        let seal = credential.as_ref().map(|c| Seal::new(&c.message_key()));
        let gate = |limit: usize| Gate::new(limit, seal.clone(), refused.clone());
        let state_gate = gate(limit);
        let subs = vec![
            subscribe(
                &session,
                keys.state(),
                state_gate.clone(),
                sink.clone(),
                Incoming::State,
            )?,
            subscribe(
                &session,
                keys.events(),
                gate(limit),
                sink.clone(),
                Incoming::Events,
            )?,
            subscribe(
                &session,
                keys.metrics(),
                gate(RunLimits::metrics()),
                sink.clone(),
                Incoming::Metrics,
            )?,
            subscribe(
                &session,
                keys.prediction(),
                gate(RunLimits::text_message()),
                sink.clone(),
                Incoming::Prediction,
            )?,
            subscribe(
                &session,
                keys.status_all(),
                gate(RunLimits::text_message()),
                sink.clone(),
                Incoming::Status,
            )?,
        ];
        // Plant liveliness goes through its own unbounded channel: it must never be dropped.
        let plant_keys = keys.clone();
        let plants = session
            .liveliness()
            .declare_subscriber(keys.alive_all(Role::Plant))
            .history(true)
            .callback(move |sample| {
                if let Some(pid) =
                    plant_keys.id_of_alive_key(Role::Plant, sample.key_expr().as_str())
                {
                    let _ = plant_tx.send(match sample.kind() {
                        zenoh::sample::SampleKind::Put => Incoming::PlantUp(pid.to_string()),
                        zenoh::sample::SampleKind::Delete => Incoming::PlantDown(pid.to_string()),
                    });
                }
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh: {e}"))?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Bridge, id))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh: {e}"))?;
        Ok(Some(Self {
            session,
            _subs: subs,
            _plants: plants,
            _token: token,
            state_gate,
            seal,
            limit,
        }))
    }

    /// The plant's model description, if it answers (sealed) within 200 ms.
    fn query_model(&self, keys: &RunKeys, refused: &Arc<Refused>) -> Option<ModelInfo> {
        self.query(keys.model(), refused, |info: &ModelInfo| {
            info.run == keys.run()
        })
    }

    fn query_environment(&self, keys: &RunKeys, refused: &Arc<Refused>) -> Option<Environment> {
        self.query(keys.environment(), refused, |e: &Environment| {
            e.run == keys.run()
        })
    }

    /// The plant's answer on the queryable `key`, decoded, validated and of this run (`ours`).
    fn query<M: Message>(
        &self,
        key: String,
        refused: &Arc<Refused>,
        ours: impl Fn(&M) -> bool,
    ) -> Option<M> {
        let replies = self
            .session
            .get(key)
            .timeout(Duration::from_millis(200))
            .wait()
            .ok()?;
        let gate = Gate::new(
            RunLimits::before_model(),
            self.seal.clone(),
            refused.clone(),
        );
        let mut found = None;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                if let Ok(bytes) = gate.admit(sample) {
                    if let Ok(m) = decode::<M>(&bytes) {
                        if ours(&m) {
                            found = Some(m);
                        }
                    }
                }
            }
        }
        found
    }

    fn close(self) {
        let Self { session, _subs, .. } = self;
        drop(_subs);
        let _ = session.close().wait();
    }
}

/// How long the viewer may take to answer before the recorder says it is not there.
const VIEWER_GRACE: Duration = Duration::from_secs(3);

/// How long the end of the run waits for the viewer to confirm what it was sent.
const VIEWER_FLUSH: Duration = Duration::from_secs(10);

/// How a recording ended.
struct Closed {
    /// The run produced a recording, now at `--out`.
    recorded: bool,
    /// What the viewer got (empty without a viewer).
    viewer: String,
}

/// Ends the recording: writes what is pending, closes the file (with its footer), moves it to
/// `--out` if the run produced one (else removes it, leaving `--out` as it was), and flushes the
/// viewer (bounded).
fn close(
    recorder: &mut Recorder,
    output: &mut Output,
    viewer: Option<&Viewer>,
) -> anyhow::Result<Closed> {
    recorder.finish()?;
    let recorded = recorder.counts().states > 0;
    if recorded {
        output.promote()?;
    }
    let viewer = match viewer {
        None => String::new(),
        Some(v) => {
            let d = v.finish(VIEWER_FLUSH);
            let said = match (d.link, d.flushed, d.dropped) {
                (Link::Connected, true, 0) => "the viewer got everything".to_string(),
                (Link::Connected, true, n) => {
                    format!("the viewer missed {n} messages (it was behind)")
                }
                (Link::Connected, false, _) => {
                    "the viewer did not confirm the end of the data in time".to_string()
                }
                (Link::Connecting, _, _) => "no viewer answered".to_string(),
                (Link::Gone, _, n) => format!("the viewer went away and missed {n} messages"),
            };
            format!("; {said} at {}", v.url())
        }
    };
    Ok(Closed { recorded, viewer })
}

fn record(a: RecordArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        a.every >= 1,
        "invalid --every = {}: allowed an integer >= 1",
        a.every
    );
    anyhow::ensure!(
        a.lanes >= 1 && a.lanes <= 4096,
        "invalid --lanes = {}: allowed 1 to 4096",
        a.lanes
    );
    anyhow::ensure!(
        a.heatmap_rows >= 1 && a.heatmap_rows <= 65536,
        "invalid --heatmap-rows = {}: allowed 1 to 65536",
        a.heatmap_rows
    );
    anyhow::ensure!(
        a.inbox >= 16 && a.inbox <= 1 << 20,
        "invalid --inbox = {}: allowed 16 to 1048576",
        a.inbox
    );
    if let Some(t) = a.idle_timeout {
        anyhow::ensure!(
            t.is_finite() && t > 0.0 && t < 1e9,
            "invalid --idle-timeout = {}: allowed a number of seconds, 0 < idle-timeout < 1e9",
            crawler_cli::number(t)
        );
    }
    let network = a.network.network()?;
    let keys = RunKeys::new(&network.run_id)?;
    let mut output = Output::new(&a.out)?;
    let url = match (&a.connect, a.spawn) {
        (Some(u), _) => Some(viewer::parse_url(u)?),
        (None, true) => Some(viewer::parse_url(viewer::DEFAULT_URL)?),
        (None, false) => None,
    };
    if a.spawn {
        if let Some(u) = &url {
            anyhow::ensure!(
                u.origin.is_localhost(),
                "invalid --connect = {u} with --spawn: allowed a loopback address (the viewer is started on this machine)"
            );
        }
    }
    if a.check {
        eprintln!("crawler-recorder: inputs valid ({})", network.describe());
        return Ok(Exit::Finished.into());
    }
    // from here on Ctrl-C ends the recording properly (and removes an unused temporary file)
    let (stop_tx, stop_rx) = bounded::<()>(4);
    ctrlc::set_handler(move || {
        let _ = stop_tx.try_send(());
    })?;
    let temp = output.create()?.to_path_buf();
    let (viewer, viewer_sink) = match url {
        Some(u) => {
            // never fail the run because of the viewer: say so and record the file
            let spawned = !a.spawn
                || match viewer::spawn(&u, a.viewer_exe.as_deref()) {
                    Ok(Some(pid)) => {
                        eprintln!("crawler-recorder: started a Rerun viewer (pid {pid}) at {u}");
                        true
                    }
                    Ok(None) => {
                        eprintln!("crawler-recorder: a viewer already listens at {u}; using it");
                        true
                    }
                    Err(e) => {
                        eprintln!("crawler-recorder: warning: {e:#}; recording to the file only");
                        false
                    }
                };
            if spawned {
                let (v, sink) = Viewer::connect(u)?;
                (Some(v), Some(sink))
            } else {
                (None, None)
            }
        }
        None => (None, None),
    };
    let rec = crawler_recorder::recorder::open(&temp, !a.no_footer, viewer_sink)?;
    let opts = RecorderOptions {
        every: a.every,
        lanes: a.lanes,
        heatmap_rows: a.heatmap_rows,
        ..Default::default()
    };
    let mut recorder = Recorder::new(rec, opts)?;

    let interrupted = || !stop_rx.is_empty();
    let credential = network.wait_for_credential(
        "crawler-recorder",
        Duration::from_secs_f64(a.idle_timeout.unwrap_or(86_400.0)),
        &interrupted,
    )?;
    if credential.is_none() {
        eprintln!("crawler-recorder: warning: unauthenticated (--no-auth): the recording cannot tell the run's messages from anyone else's");
    }
    let (tx, rx) = bounded::<Arrival>(a.inbox);
    let (status_tx, status_rx) = bounded::<Arrival>(STATUS_SLOTS);
    let dropped = Arc::new(AtomicU64::new(0));
    let sink = Sink {
        tx,
        status_tx,
        statuses: ByteBudget::new(STATUS_BYTES),
        states: ByteBudget::new(STATE_BYTES),
        others: ByteBudget::new(OTHER_BYTES),
        dropped: dropped.clone(),
    };
    let refused = Arc::new(Refused::default());
    let (plant_tx, plant_rx) = crossbeam_channel::unbounded::<Incoming>();
    let id = crawler_transport::process_id();
    eprintln!(
        "crawler-recorder: recording {} into {}{} (waiting for the plant)",
        network.describe(),
        a.out.display(),
        viewer
            .as_ref()
            .map(|v| format!(" and live to the viewer at {}", v.url()))
            .unwrap_or_default()
    );
    let mut credential = credential;
    let started = Instant::now();
    let idle_timeout = a.idle_timeout;
    let mut give_up =
        || !stop_rx.is_empty() || idle_timeout.is_some_and(|t| started.elapsed().as_secs_f64() > t);
    let Some(mut conn) = Connection::open(
        &network,
        &mut credential,
        RunLimits::before_model(),
        (&sink, &refused),
        (plant_tx.clone(), &id),
        &mut give_up,
    )?
    else {
        if let Some(v) = viewer.as_ref().filter(|v| v.link() == Link::Connecting) {
            eprintln!(
                "crawler-recorder: warning: no Rerun viewer answers at {} (start one with `rerun --bind 127.0.0.1`, or pass --spawn)",
                v.url()
            );
        }
        let c = close(&mut recorder, &mut output, viewer.as_ref())?;
        eprintln!(
            "crawler-recorder: {}; nothing recorded (no state arrived), {} left as it was{}",
            if stop_rx.is_empty() {
                "no plant"
            } else {
                "interrupted"
            },
            a.out.display(),
            c.viewer
        );
        return Ok(if stop_rx.is_empty() {
            Exit::Timeout
        } else {
            Exit::Interrupted
        }
        .into());
    };

    let mut model_known = false;
    let mut next_query = Instant::now();
    let mut last_message = Instant::now();
    let mut viewer_warned = false;
    let mut lag = Duration::ZERO;
    let interrupted = loop {
        crossbeam_channel::select! {
            recv(stop_rx) -> _ => break true,
            recv(plant_rx) -> msg => {
                if let Ok(msg) = msg {
                    recorder.handle(msg)?;
                }
            },
            recv(rx) -> msg => {
                if let Ok((arrived, msg)) = msg {
                    let (msg, _charge) = msg.split();
                    recorder.handle(msg)?;
                    last_message = Instant::now();
                    lag = arrived.elapsed();
                }
            },
            recv(status_rx) -> msg => {
                if let Ok((_, msg)) = msg {
                    recorder.handle(msg.split().0)?;
                    last_message = Instant::now();
                }
            },
            default(Duration::from_millis(100)) => {},
        }
        if !output.promoted() && recorder.counts().states > 0 {
            // the run produced a recording: it replaces --out from now on
            output.promote()?;
        }
        if let Some(v) = &viewer {
            if !viewer_warned && v.link() == Link::Connecting && started.elapsed() > VIEWER_GRACE {
                viewer_warned = true;
                eprintln!(
                    "crawler-recorder: warning: no Rerun viewer answers at {} (start one with `rerun --bind 127.0.0.1`, or pass --spawn); recording to the file, the viewer gets the data if it comes up",
                    v.url()
                );
            }
        }
        recorder.pace(rx.len(), lag, dropped.load(Ordering::Relaxed));
        recorder.maybe_flush();
        if recorder.finished() && rx.is_empty() && status_rx.is_empty() {
            break false;
        }
        recorder.refused_at_arrival(refused.oversize(), refused.unsealed());
        if !model_known && Instant::now() >= next_query {
            next_query = Instant::now() + Duration::from_millis(200);
            if let Some(info) = conn.query_model(&keys, &refused) {
                let limits = RunLimits::new(info.cells as usize);
                if limits.largest() > conn.limit {
                    // a very large grid: reconnect able to reassemble its largest messages
                    conn.close();
                    let mut give_up = || !stop_rx.is_empty();
                    match Connection::open(
                        &network,
                        &mut credential,
                        limits.largest(),
                        (&sink, &refused),
                        (plant_tx.clone(), &id),
                        &mut give_up,
                    )? {
                        Some(c) => conn = c,
                        None => {
                            close(&mut recorder, &mut output, viewer.as_ref())?;
                            eprintln!("crawler-recorder: interrupted; recording closed properly");
                            return Ok(Exit::Interrupted.into());
                        }
                    }
                    continue;
                }
                conn.state_gate.set_limit(limits.state());
                // the pipe as the plant resolved it (a plant that does not answer: no map
                // drawn), taken with the model so that every state from now on is drawn on it
                let environment = conn.query_environment(&keys, &refused);
                recorder.set_model(&info, environment)?;
                model_known = true;
                // Our subscriptions reached the plant before this reply did (same link,
                // in order): from here on nothing the plant publishes is missed.
                eprintln!(
                    "crawler-recorder: plant found ({} cells, last step {}); recording every state from now on",
                    info.cells, info.last_step
                );
            }
        }
        if let Some(t) = a.idle_timeout {
            if last_message.elapsed().as_secs_f64() > t {
                let c = close(&mut recorder, &mut output, viewer.as_ref())?;
                eprintln!(
                    "crawler-recorder: no message for {t} s; {}{}",
                    if c.recorded {
                        format!("recording closed {}", a.out.display())
                    } else {
                        format!("nothing recorded, {} left as it was", a.out.display())
                    },
                    c.viewer
                );
                return Ok(Exit::Timeout.into());
            }
        }
    };
    // Drain what already arrived, then finish the file properly.
    while let Ok((_, msg)) = rx.try_recv().or_else(|_| status_rx.try_recv()) {
        recorder.handle(msg.split().0)?;
    }
    recorder.refused_at_arrival(refused.oversize(), refused.unsealed());
    let closed = close(&mut recorder, &mut output, viewer.as_ref())?;
    let c = recorder.counts();
    if closed.recorded {
        eprintln!(
            "crawler-recorder: {} {}: {} states ({} with fields), {} metric blocks, {} episodes, {} rejected ({} invalid), {} refused at arrival, {} dropped{}",
            if interrupted { "interrupted; recording closed properly" } else { "run finished; recording closed" },
            a.out.display(),
            c.states,
            c.recorded_steps,
            c.metric_blocks,
            c.episodes,
            c.rejected,
            c.invalid,
            c.refused,
            c.dropped,
            closed.viewer
        );
    } else {
        eprintln!(
            "crawler-recorder: {}; nothing recorded (no state arrived), {} left as it was{}",
            if interrupted {
                "interrupted"
            } else {
                "run ended"
            },
            a.out.display(),
            closed.viewer
        );
    }
    conn.close();
    // Ctrl-C (SIGINT, SIGTERM) ends with 130 like every program of the project, after the
    // recording was closed properly
    Ok(if interrupted {
        Exit::Interrupted
    } else {
        Exit::Finished
    }
    .into())
}
