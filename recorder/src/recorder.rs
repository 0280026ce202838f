//! The writer: turns protocol messages into Rerun entities, in step order, with decimation.

use crawler_facts::Metric;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

use rerun::RecordingStream;

use crawler_protocol::{
    decode, Environment, Events, FinalReport, Metrics, ModelPrediction, Prediction, ProcessState,
    Role, Series, State, Status,
};

use crate::checks::{self, RunFacts};
use crate::paths;

/// Messages held back until the plant's model description arrives (they cannot be checked
/// before); beyond this many they are rejected.
const EARLY_MAX: usize = 1024;

/// What the zenoh callbacks hand to the writer (raw payloads: decoding happens on the writer).
#[derive(Debug, Clone)]
pub enum Incoming {
    /// `crawler/<run>/state`.
    State(Vec<u8>),
    /// `crawler/<run>/events`.
    Events(Vec<u8>),
    /// `crawler/<run>/metrics`.
    Metrics(Vec<u8>),
    /// `crawler/<run>/prediction`.
    Prediction(Vec<u8>),
    /// `crawler/<run>/status/*`.
    Status(Vec<u8>),
    /// The liveliness token of a plant appeared (its id).
    PlantUp(String),
    /// The liveliness token of a plant disappeared (its id): the plant process ended.
    PlantDown(String),
}

/// Longest a state may wait in the inbox before the recorder decimates the fields it records.
pub const LAG_LIMIT: Duration = Duration::from_millis(100);

/// Recorder settings.
#[derive(Debug, Clone, Copy)]
pub struct RecorderOptions {
    /// Record the fields of every `every`-th step (metrics, events and lanes are always recorded).
    pub every: u64,
    /// Most nodes given a stick/slip lane (evenly spaced).
    pub lanes: usize,
    /// Rows (recorded steps) per heatmap block.
    pub heatmap_rows: usize,
    /// Flush the file at least this often (bounds what `kill -9` loses).
    pub flush_every: Duration,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            every: 1,
            lanes: 64,
            heatmap_rows: 128,
            flush_every: Duration::from_millis(200),
        }
    }
}

/// Counters of the recording, for tests and the final report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// States received and decoded.
    pub states: u64,
    /// States whose fields were recorded.
    pub recorded_steps: u64,
    /// Duplicate states ignored (the plant resends a state when no answer comes).
    pub duplicates: u64,
    /// Episodes logged.
    pub episodes: u64,
    /// Metric blocks logged.
    pub metric_blocks: u64,
    /// Messages not recorded because they failed to decode or failed a check (never recorded).
    pub rejected: u64,
    /// Of `rejected`: messages that decoded but that the run cannot have produced
    /// ([`crate::checks`]).
    pub invalid: u64,
    /// Payloads refused at arrival, before decoding: larger than the run's largest legal
    /// message, or (authenticated runs) without a valid seal.
    pub refused: u64,
    /// Messages the callbacks dropped because the writer was behind.
    pub dropped: u64,
}

/// Converts messages into a recording.
pub struct Recorder {
    rec: RecordingStream,
    opts: RecorderOptions,
    /// Current decimation (>= opts.every; raised while the writer is behind).
    every: u64,
    pending: BTreeMap<u64, State>,
    next_step: Option<u64>,
    last_stuck: Vec<bool>,
    lane_nodes: Vec<usize>,
    heat: Vec<f32>,
    heat_rows: usize,
    heat_start_step: u64,
    predictions: Vec<ModelPrediction>,
    tail_series: Option<Series>,
    tail_offset: Option<f64>,
    tail_buffer: Vec<(u64, f64, f64)>,
    settled: bool,
    counts: Counts,
    last_flush: Instant,
    /// When the decimation last changed.
    last_pace_change: Instant,
    finished: bool,
    /// Body length L, m.
    length: f64,
    /// Where node `i` sits on the body, in cells: at `(i + node_offset) dx` from the tail (0 on a
    /// periodic body, 0.5 on a free one, whose nodes are the cell centres).
    node_offset: f64,
    plant_id: Option<String>,
    last_step_time: (u64, f64),
    run_last_step: Option<u64>,
    last_state_at: Option<Instant>,
    facts: Option<RunFacts>,
    early: Vec<Incoming>,
    controller_id: Option<String>,
    invalid_by_kind: BTreeMap<&'static str, u64>,
    /// The pipe, once the plant answered it.
    environment: Option<Environment>,
    /// When the liveliness token of the recorded plant disappeared.
    plant_gone_at: Option<Instant>,
    /// Step of the plant's last state (last: true), once it came: the run's last step.
    plant_last_state: Option<u64>,
    /// The plant's `finished` statuses for a step before the model's last that came before any
    /// last state (a task-mode run the plant ended early), by step; a few at most.
    held_finished: BTreeMap<u64, Status>,
    /// Episode rows not yet sent ([`EPISODE_ROWS`] at most).
    episodes: EpisodeRows,
}

/// Most `finished` statuses held while the plant's last state is awaited.
const HELD_FINISHED_MAX: usize = 8;

/// Episode rows sent to the recording as one chunk. In hard stick-slip tens of thousands of
/// episodes end per second: a logging call apiece made the recorder fall behind the run, and a
/// chunk per block of events left the file in thousands of small chunks.
const EPISODE_ROWS: usize = 4096;

/// Text rows of stick episodes waiting to be sent together, each with its step and time.
#[derive(Default)]
struct EpisodeRows {
    steps: Vec<i64>,
    times: Vec<f64>,
    texts: Vec<String>,
}

/// A recording written to `path`, with the default layout, and streamed to `viewer` if given.
///
/// With `footer` (the default of `crawler-recorder record`) the file ends with Rerun's footer, an
/// index of every chunk: `rerun rrd verify` wants it and large files load faster. The encoder
/// keeps that index in memory for the whole run (about 40 MB per 10^6 steps); without it memory
/// stays flat however long the run, and `rerun rrd optimize` can add the index afterwards. The
/// footer is written when the file sink closes: [`Recorder::finish`].
pub fn open(
    path: &Path,
    footer: bool,
    viewer: Option<crate::viewer::ViewerSink>,
) -> anyhow::Result<RecordingStream> {
    let cannot = |e: &dyn std::fmt::Display| {
        anyhow::anyhow!("cannot write recording {}: {e}", path.display())
    };
    let file = rerun::sink::FileSink::with_options(
        path,
        rerun::sink::FileSinkOptions {
            write_footer: footer,
        },
    )
    .map_err(|e| cannot(&e))?;
    let mut sinks: Vec<Box<dyn rerun::sink::LogSink>> = vec![Box::new(file)];
    if let Some(v) = viewer {
        sinks.push(Box::new(v));
    }
    let rec = rerun::RecordingStreamBuilder::new("crawler")
        .set_sinks(sinks)
        .map_err(|e| cannot(&e))?;
    crate::layout::send(&rec)?;
    Ok(rec)
}

/// A recording written to `path` only (see [`open`]).
pub fn open_file(path: &Path, footer: bool) -> anyhow::Result<RecordingStream> {
    open(path, footer, None)
}

impl Recorder {
    /// A recorder writing to `rec`.
    pub fn new(rec: RecordingStream, opts: RecorderOptions) -> anyhow::Result<Self> {
        let me = Self {
            rec,
            every: opts.every.max(1),
            opts,
            pending: BTreeMap::new(),
            next_step: None,
            last_stuck: Vec::new(),
            lane_nodes: Vec::new(),
            heat: Vec::new(),
            heat_rows: 0,
            heat_start_step: 0,
            predictions: Vec::new(),
            tail_series: None,
            tail_offset: None,
            tail_buffer: Vec::new(),
            settled: false,
            counts: Counts::default(),
            last_flush: Instant::now(),
            last_pace_change: Instant::now(),
            finished: false,
            length: 1.0,
            node_offset: 0.0,
            plant_id: None,
            last_step_time: (0, 0.0),
            run_last_step: None,
            last_state_at: None,
            facts: None,
            early: Vec::new(),
            controller_id: None,
            invalid_by_kind: BTreeMap::new(),
            environment: None,
            plant_gone_at: None,
            plant_last_state: None,
            held_finished: BTreeMap::new(),
            episodes: EpisodeRows::default(),
        };
        me.log_static()?;
        Ok(me)
    }

    /// Counters so far.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// True once the plant reported the end of the run and its last state was recorded.
    pub fn finished(&self) -> bool {
        // what is still buffered is written by finish(); after the last state, the plant's final
        // status (with its summary) is awaited for at most two seconds
        // a plant that ended (or died) without its last state or final status reaching us ends
        // the recording too, once what it sent before had two seconds to arrive
        self.finished
            || self
                .last_state_at
                .is_some_and(|t| t.elapsed() > Duration::from_secs(2))
            || self
                .plant_gone_at
                .is_some_and(|t| t.elapsed() > Duration::from_secs(2))
    }

    /// Takes the plant's model description: the body length, and the run's last step, marked at
    /// once so that the recording's timeline spans the whole run from its first bytes.
    /// With it the pipe the plant resolved, if it answered (drawn before the messages that came
    /// early are recorded).
    pub fn set_model(
        &mut self,
        info: &crawler_protocol::ModelInfo,
        environment: Option<Environment>,
    ) -> anyhow::Result<()> {
        if info.length.is_finite() && info.length > 0.0 {
            self.length = info.length;
        }
        // the protocol admits only "periodic" and "free"
        self.node_offset = if info.boundary == "free" { 0.5 } else { 0.0 };
        self.run_last_step = Some(info.last_step);
        self.facts = Some(RunFacts::of(info));
        let end = info.start_time + info.last_step as f64 * info.step;
        self.set_time(info.last_step, end);
        self.rec.log(
            paths::LOG_RECORDER,
            &rerun::TextLog::new(format!(
                "run {} ends at step {} (t = {end} s): {} cells, L = {} m, H = {} s, eps = {}, n_F = {}",
                info.run, info.last_step, info.cells, info.length, info.step, info.eps, info.n_f
            ))
            .with_level(rerun::TextLogLevel::INFO),
        )?;
        if let Some(env) = environment {
            self.set_environment(env)?;
        }
        // what arrived before can be checked now
        for msg in std::mem::take(&mut self.early) {
            self.handle(msg)?;
        }
        Ok(())
    }

    /// Draws the pipe the plant resolved: eps(X) and n_F(X) as static step lines from a body
    /// length behind the tail's start to a body length past the last change (at least two body
    /// lengths ahead), and from now on the body's nodes on eps(X) at every recorded step.
    fn set_environment(&mut self, env: Environment) -> anyhow::Result<()> {
        let length = self.length;
        let first = env.piece_start.first().copied().unwrap_or(env.start);
        let last = env.piece_start.last().copied().unwrap_or(env.start);
        let (lo, hi) = (
            first.min(env.start) - length,
            (last + length).max(env.start + 3.0 * length),
        );
        // a 2D view's y axis points down: values are drawn at y = -value, so up is larger
        let steps = |uniform: f64, values: &[f64]| -> Vec<[f32; 2]> {
            let mut line = vec![[lo as f32, -uniform as f32]];
            let mut level = uniform;
            for (&x, &v) in env.piece_start.iter().zip(values) {
                line.push([x as f32, -level as f32]);
                line.push([x as f32, -v as f32]);
                level = v;
            }
            line.push([hi as f32, -level as f32]);
            line
        };
        self.rec.log_static(
            paths::PIPE_EPS,
            &rerun::LineStrips2D::new([steps(env.eps, &env.piece_eps)])
                .with_colors([rerun::Color::from_rgb(230, 160, 40)])
                .with_labels(["eps(X)"]),
        )?;
        self.rec.log_static(
            paths::PIPE_N_F,
            &rerun::LineStrips2D::new([steps(env.n_f, &env.piece_n_f)])
                .with_colors([rerun::Color::from_rgb(40, 150, 60)])
                .with_labels(["n_F(X)"]),
        )?;
        let exact = if env.merged == 1 {
            "exactly".to_string()
        } else {
            format!("merged, {} of its pieces per piece drawn", env.merged)
        };
        let (e, n) = (&env.piece_eps, &env.piece_n_f);
        let range = |u: f64, v: &[f64]| v.iter().fold((u, u), |(a, b), &x| (a.min(x), b.max(x)));
        let ((e0, e1), (n0, n1)) = (range(env.eps, e), range(env.n_f, n));
        self.note(
            format!(
                "pipe as the plant resolved it ({exact}): {} pieces, eps in [{e0}, {e1}], n_F in [{n0}, {n1}], tail starts at X = {} m",
                env.piece_start.len(),
                env.start
            ),
            rerun::TextLogLevel::INFO,
        );
        self.environment = Some(env);
        Ok(())
    }

    /// Counts a decoded message that fails a check, and notes it in the recording (the first
    /// five of each kind, then every 1000th).
    fn invalid(&mut self, kind: &'static str, reason: &str) {
        self.counts.rejected += 1;
        self.counts.invalid += 1;
        let n = self.invalid_by_kind.entry(kind).or_insert(0);
        *n += 1;
        let n = *n;
        if n <= 5 || n.is_multiple_of(1000) {
            let text = format!("rejected {kind} #{n} (not recorded): {reason}");
            eprintln!("crawler-recorder: {text}");
            self.note(text, rerun::TextLogLevel::WARN);
        }
    }

    /// Holds a message until the model description arrives (or rejects it if too many wait).
    fn hold(&mut self, msg: Incoming) {
        if self.early.len() < EARLY_MAX {
            self.early.push(msg);
        } else {
            self.invalid(
                "message",
                "arrived before the plant's model description, with too many others",
            );
        }
    }

    /// Records that `refused` payloads in all were refused at arrival so far (oversized or
    /// unsealed), noting each increase in the recording (at most about once a second, as the
    /// writer's loop calls it).
    pub fn refused_at_arrival(&mut self, oversize: u64, unsealed: u64) {
        let total = oversize + unsealed;
        if total > self.counts.refused {
            self.note(
                format!(
                    "{total} payloads refused at arrival so far (not recorded): {oversize} larger than the run's largest legal message, {unsealed} without a valid seal of this run"
                ),
                rerun::TextLogLevel::WARN,
            );
            self.counts.refused = total;
        }
    }

    /// Current decimation.
    pub fn decimation(&self) -> u64 {
        self.every
    }

    fn log_static(&self) -> anyhow::Result<()> {
        let rec = &self.rec;
        for root in [paths::BODY, paths::PIPE] {
            rec.log_static(
                root,
                &rerun::AnnotationContext::new([
                    (0, "slip", rerun::Rgba32::from_rgb(60, 120, 230)),
                    (1, "stick", rerun::Rgba32::from_rgb(220, 50, 40)),
                ]),
            )?;
        }
        let colors = [
            ("plant", [235, 235, 235]), // the dark theme's foreground: the truth, drawn widest
            ("paper", [230, 120, 20]),
            ("improved", [30, 160, 80]),
        ];
        for m in paths::METRICS {
            for (source, c) in colors {
                rec.log_static(
                    paths::metric_series(m, source),
                    &rerun::SeriesLines::new()
                        .with_names([format!("{m} ({source})")])
                        .with_colors([rerun::Rgba32::from_rgb(c[0], c[1], c[2])])
                        .with_widths([if source == "plant" { 2.5 } else { 1.5 }]),
                )?;
            }
        }
        rec.log_static(
            format!("{}/plant", paths::TAIL),
            &rerun::SeriesLines::new()
                .with_names(["u(0, t) plant"])
                .with_colors([rerun::Rgba32::from_rgb(235, 235, 235)])
                .with_widths([2.0]),
        )?;
        rec.log_static(
            format!("{}/paper", paths::TAIL),
            &rerun::SeriesLines::new()
                .with_names(["u(0, t) paper mu0 + eps mu1"])
                .with_colors([rerun::Rgba32::from_rgb(230, 120, 20)]),
        )?;
        Ok(())
    }

    fn set_time(&self, step: u64, time: f64) {
        self.rec.set_time_sequence("step", step as i64);
        self.rec.set_duration_secs("sim_time", time);
    }

    fn note(&self, text: String, level: &str) {
        let _ = self.rec.log(
            paths::LOG_RECORDER,
            &rerun::TextLog::new(text).with_level(level),
        );
    }

    /// Handles one message. Never fails on bad input: undecodable messages and messages the run
    /// cannot have produced are counted and noted, never recorded. Events, metrics and
    /// predictions that arrive before the plant's model description wait for it.
    pub fn handle(&mut self, msg: Incoming) -> anyhow::Result<()> {
        let facts = self.facts;
        match msg {
            Incoming::State(b) => match decode::<State>(&b) {
                Ok(s) => {
                    if let Some(f) = &facts {
                        if let Err(reason) = checks::state(&s, f) {
                            self.invalid("state", &reason);
                            return Ok(());
                        }
                    }
                    if !s.controller.is_empty() {
                        self.controller_id
                            .get_or_insert_with(|| s.controller.clone());
                    }
                    let last = (s.last && self.plant_last_state.is_none()).then_some(s.step);
                    self.counts.states += 1;
                    if self.pending.contains_key(&s.step)
                        || self.next_step.is_some_and(|n| s.step < n)
                    {
                        self.counts.duplicates += 1;
                    } else {
                        self.pending.insert(s.step, s);
                    }
                    self.drain(false)?;
                    if let Some(step) = last {
                        // the run's last step: a finished status held for it is the plant's
                        self.plant_last_state = Some(step);
                        if let Some(st) = self.held_finished.remove(&step) {
                            self.log_status(&st)?;
                        }
                    }
                }
                Err(_) => self.counts.rejected += 1,
            },
            Incoming::Events(ref b) => match (decode::<Events>(b), &facts) {
                (Ok(_), None) => self.hold(msg),
                (Ok(e), Some(f)) => match checks::events(&e, f) {
                    Ok(()) => self.log_events(&e)?,
                    Err(reason) => self.invalid("events", &reason),
                },
                (Err(_), _) => self.counts.rejected += 1,
            },
            Incoming::Metrics(ref b) => match (decode::<Metrics>(b), &facts) {
                (Ok(_), None) => self.hold(msg),
                (Ok(m), Some(f)) => match checks::metrics(&m, f) {
                    Ok(()) => self.log_metrics(&m)?,
                    Err(reason) => self.invalid("metrics", &reason),
                },
                (Err(_), _) => self.counts.rejected += 1,
            },
            Incoming::Prediction(ref b) => match (decode::<Prediction>(b), &facts) {
                (Ok(_), None) => self.hold(msg),
                (Ok(p), Some(f)) => {
                    match checks::prediction(&p, f, self.controller_id.as_deref()) {
                        Ok(()) => self.set_prediction(p),
                        Err(reason) => self.invalid("prediction", &reason),
                    }
                }
                (Err(_), _) => self.counts.rejected += 1,
            },
            Incoming::Status(b) => match decode::<Status>(&b) {
                Ok(s) => self.log_status(&s)?,
                Err(_) => self.counts.rejected += 1,
            },
            Incoming::PlantUp(id) => {
                if self.plant_id.is_none() {
                    self.plant_id = Some(id);
                }
            }
            Incoming::PlantDown(id) => {
                if self.plant_id.as_deref() == Some(id.as_str()) && self.plant_gone_at.is_none() {
                    self.plant_gone_at = Some(Instant::now());
                }
            }
        }
        Ok(())
    }

    /// Adjusts decimation to how far the writer is behind (`backlog` messages waiting in the
    /// inbox; `lag`, how long the message just recorded waited there) and records `dropped`
    /// messages lost by the callbacks so far.
    ///
    /// What `kill -9` loses is the lag plus the flush interval, so the lag is kept under
    /// [`LAG_LIMIT`]: the fields are decimated (never the metrics, events or lanes) until the
    /// writer keeps up. Decimation changes at most once per [`LAG_LIMIT`], so it follows the
    /// load instead of jumping to its maximum on one slow burst.
    pub fn pace(&mut self, backlog: usize, lag: Duration, dropped: u64) {
        if dropped > self.counts.dropped {
            self.note(
                format!(
                    "{} messages dropped so far because the recorder fell behind",
                    dropped
                ),
                rerun::TextLogLevel::WARN,
            );
            self.counts.dropped = dropped;
        }
        let before = self.every;
        if self.last_pace_change.elapsed() < LAG_LIMIT {
            return;
        }
        let behind = backlog > 256 || lag > LAG_LIMIT;
        let caught_up = backlog < 16 && lag < LAG_LIMIT / 4;
        if behind && self.every < 1024 {
            self.every *= 2;
        } else if caught_up && self.every > self.opts.every.max(1) {
            self.every = (self.every / 2).max(self.opts.every.max(1));
        }
        if self.every != before {
            self.last_pace_change = Instant::now();
            let level = if self.every > before {
                rerun::TextLogLevel::WARN
            } else {
                rerun::TextLogLevel::INFO
            };
            self.note(
                format!(
                    "recorder {} behind: recording the fields of every {}th step (requested every {}), backlog {} messages",
                    if self.every > before { "fell" } else { "caught up, no longer" },
                    self.every,
                    self.opts.every,
                    backlog
                ),
                level,
            );
            let _ = self.rec.log(
                "recorder/decimation",
                &rerun::Scalars::single(self.every as f64),
            );
        }
    }

    /// Flushes if the last flush is older than the flush interval.
    pub fn maybe_flush(&mut self) {
        if self.last_flush.elapsed() >= self.opts.flush_every {
            if let Err(e) = self.send_episodes() {
                eprintln!("crawler-recorder: warning: episodes not recorded: {e:#}");
            }
            let _ = self.rec.flush_with_timeout(Duration::from_secs(2));
            self.last_flush = Instant::now();
        }
    }

    /// Records every pending state (end of run or shutdown), flushes and closes the file.
    pub fn finish(&mut self) -> anyhow::Result<()> {
        self.drain(true)?;
        if self.plant_gone_at.is_some() && !self.finished {
            self.note(
                "the plant ended without its final status reaching the recorder".to_string(),
                rerun::TextLogLevel::WARN,
            );
        }
        // finished statuses no last state of the plant confirmed: not the plant's end
        for (step, _) in std::mem::take(&mut self.held_finished) {
            let why = match self.plant_last_state {
                Some(l) => {
                    format!("status finished at step {step}: the plant's last state was step {l}")
                }
                None => format!(
                    "status finished at step {step}: no last state of the plant came for it"
                ),
            };
            self.invalid("status", &why);
        }
        if !self.invalid_by_kind.is_empty() {
            let kinds: Vec<String> = self
                .invalid_by_kind
                .iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            self.note(
                format!(
                    "{} messages rejected in all, not recorded: the run cannot have produced them ({})",
                    self.counts.invalid,
                    kinds.join(", ")
                ),
                rerun::TextLogLevel::WARN,
            );
        }
        if self.heat_rows > 0 {
            self.log_heat_block()?;
        }
        self.send_episodes()?;
        self.rec
            .flush_blocking()
            .map_err(|e| anyhow::anyhow!("cannot flush the recording: {e}"))?;
        // close the file (its writer thread ends and writes the footer); a viewer stays connected
        self.rec.finalize_deferred_sinks();
        Ok(())
    }

    /// Emits pending states in step order; holds a few back to reorder late arrivals.
    fn drain(&mut self, all: bool) -> anyhow::Result<()> {
        while let Some((&step, _)) = self.pending.iter().next() {
            let contiguous = self.next_step.is_none_or(|n| step == n);
            if !(all || contiguous || self.pending.len() > 32) {
                break;
            }
            let s = self.pending.remove(&step).expect("present");
            self.next_step = Some(step + 1);
            self.log_state(&s)?;
        }
        Ok(())
    }

    fn log_state(&mut self, s: &State) -> anyhow::Result<()> {
        let n = s.u.len();
        self.set_time(s.step, s.time);
        self.last_step_time = (s.step, s.time);
        if self.lane_nodes.is_empty() || self.last_stuck.len() != n {
            let lanes = self.opts.lanes.clamp(1, n);
            self.lane_nodes = (0..lanes).map(|j| j * n / lanes).collect();
            self.last_stuck = vec![false; n];
            for &i in &self.lane_nodes {
                self.rec.log(
                    paths::lane(i),
                    &rerun::StateChange::single(if s.stuck[i] { "stick" } else { "slip" }),
                )?;
            }
        } else {
            for &i in &self.lane_nodes {
                if s.stuck[i] != self.last_stuck[i] {
                    self.rec.log(
                        paths::lane(i),
                        &rerun::StateChange::single(if s.stuck[i] { "stick" } else { "slip" }),
                    )?;
                }
            }
        }
        self.last_stuck.clone_from(&s.stuck);
        // tail displacement and per-step scalars: every state
        self.rec.log(
            format!("{}/plant", paths::TAIL),
            &rerun::Scalars::single(s.u[0]),
        )?;
        self.log_tail_prediction(s.step, s.time, s.u[0])?;
        self.rec.log(
            format!("{}/mean_speed", paths::STEP),
            &rerun::Scalars::single(s.mean_speed),
        )?;
        // what the plant applied over the step that ended here: a wave's numbers at every state
        if let Some(w) = s.applied.as_ref().and_then(|a| a.wave) {
            for (name, value) in paths::APPLIED_WAVE
                .iter()
                .zip([w.f0, w.k, w.omega, w.phase])
            {
                self.rec
                    .log(paths::applied(name), &rerun::Scalars::single(value))?;
            }
        }
        let recorded = s.step.is_multiple_of(self.every) || s.last;
        self.log_pipe(s, recorded)?;
        if !recorded {
            return Ok(());
        }
        // a field with the other fields (decimated alike), in float64: the values applied
        if let Some(f) = s.applied.as_ref().and_then(|a| a.field.as_ref()) {
            self.rec
                .log(paths::APPLIED_FIELD, &rerun::BarChart::new(f.clone()))?;
        }
        self.counts.recorded_steps += 1;
        let mean = s.u.iter().sum::<f64>() / n as f64;
        let du: Vec<f32> = s.u.iter().map(|u| (u - mean) as f32).collect();
        let v: Vec<f32> = s.vel.iter().map(|&v| v as f32).collect();
        self.rec
            .log(paths::FIELD_U, &rerun::BarChart::new(du.clone()))?;
        self.rec.log(paths::FIELD_V, &rerun::BarChart::new(v))?;
        // body in space: points at x + u, and the deformation magnified below; classed stick / slip
        let length = self.length;
        let dx = length / n as f64;
        let row = 0.08 * length;
        let classes: Vec<u16> = s.stuck.iter().map(|&st| u16::from(st)).collect();
        let radius = [(0.45 * dx).max(0.004 * length) as f32];
        let points: Vec<[f32; 2]> =
            s.u.iter()
                .enumerate()
                .map(|(i, u)| [((i as f64 + self.node_offset) * dx + u) as f32, 0.0])
                .collect();
        let magnified: Vec<[f32; 2]> = s
            .u
            .iter()
            .enumerate()
            .map(|(i, u)| {
                [
                    ((i as f64 + self.node_offset) * dx + mean + paths::EXAGGERATION * (u - mean))
                        as f32,
                    -row as f32,
                ]
            })
            .collect();
        self.rec.log(
            paths::BODY_POINTS,
            &rerun::Points2D::new(points)
                .with_class_ids(classes.clone())
                .with_radii(radius),
        )?;
        self.rec.log(
            paths::BODY_EXAGGERATED,
            &rerun::Points2D::new(magnified)
                .with_class_ids(classes)
                .with_radii(radius),
        )?;
        // heatmap block
        if self.heat_rows == 0 {
            self.heat_start_step = s.step;
            self.heat.clear();
        }
        self.heat.extend_from_slice(&du);
        self.heat_rows += 1;
        if self.heat_rows >= self.opts.heatmap_rows {
            self.log_heat_block()?;
        }
        if s.last {
            self.last_state_at.get_or_insert_with(Instant::now);
        }
        Ok(())
    }

    fn log_heat_block(&mut self) -> anyhow::Result<()> {
        let cols = self.heat.len() / self.heat_rows.max(1);
        let data = rerun::TensorData::new(
            vec![self.heat_rows as u64, cols as u64],
            rerun::datatypes::TensorBuffer::F32(std::mem::take(&mut self.heat).into()),
        );
        self.rec.log(
            paths::HEATMAP,
            &rerun::Tensor::new(data).with_dim_names(["time (recorded steps)", "node"]),
        )?;
        self.heat_rows = 0;
        Ok(())
    }

    /// The friction under the body: eps at the centre of mass every state, the nodes on eps(X)
    /// at recorded steps. Nothing without an environment or in a uniform pipe.
    fn log_pipe(&mut self, s: &State, recorded: bool) -> anyhow::Result<()> {
        // a uniform pipe is drawn once (its static lines); nothing per state
        let Some(env) = self.environment.as_ref().filter(|e| !e.is_uniform()) else {
            return Ok(());
        };
        let n = s.u.len();
        let dx = self.length / n as f64;
        let world = |i: usize| env.start + (i as f64 + self.node_offset) * dx + s.u[i];
        // the cells tile the body [start, start + L) at rest (on a periodic body node 0's cell is
        // half at the tail, half at the head): the centre of mass is at start + L / 2 + mean u
        let centre = env.start + 0.5 * self.length + s.u.iter().sum::<f64>() / n as f64;
        let centre_eps = env.at(centre).0;
        if !recorded {
            return self
                .rec
                .log(paths::PIPE_CENTRE_EPS, &rerun::Scalars::single(centre_eps))
                .map_err(Into::into);
        }
        let points: Vec<[f32; 2]> = (0..n)
            .map(|i| {
                let x = world(i);
                [x as f32, -env.at(x).0 as f32]
            })
            .collect();
        let classes: Vec<u16> = s.stuck.iter().map(|&st| u16::from(st)).collect();
        // the pipe is many body lengths long: points of a fixed size on screen
        let radius = [rerun::Radius::new_ui_points(2.5)];
        self.rec
            .log(paths::PIPE_CENTRE_EPS, &rerun::Scalars::single(centre_eps))?;
        self.rec.log(
            paths::PIPE_BODY,
            &rerun::Points2D::new(points)
                .with_class_ids(classes)
                .with_radii(radius),
        )?;
        Ok(())
    }

    fn log_tail_prediction(&mut self, step: u64, time: f64, u0: f64) -> anyhow::Result<()> {
        let Some(series) = &self.tail_series else {
            return Ok(());
        };
        let value = series.at(time);
        match self.tail_offset {
            Some(offset) => self.rec.log(
                format!("{}/paper", paths::TAIL),
                &rerun::Scalars::single(offset + value),
            )?,
            None => {
                // Align the drift's origin once the plant has settled: the offset is the mean
                // difference over the first steady forcing period.
                if self.settled {
                    self.tail_buffer.push((step, time, u0 - value));
                    let period = std::f64::consts::TAU / series.omega;
                    let first = self.tail_buffer[0].1;
                    if time - first >= period {
                        let offset = self.tail_buffer.iter().map(|x| x.2).sum::<f64>()
                            / self.tail_buffer.len() as f64;
                        self.tail_offset = Some(offset);
                        let series = series.clone();
                        for &(st, t, _) in &std::mem::take(&mut self.tail_buffer) {
                            self.rec.set_time_sequence("step", st as i64);
                            self.rec.set_duration_secs("sim_time", t);
                            self.rec.log(
                                format!("{}/paper", paths::TAIL),
                                &rerun::Scalars::single(offset + series.at(t)),
                            )?;
                        }
                        self.set_time(step, time);
                    }
                }
            }
        }
        Ok(())
    }

    fn set_prediction(&mut self, p: Prediction) {
        self.tail_series = p
            .models
            .iter()
            .find(|m| m.model == "paper")
            .and_then(|m| m.tail.clone());
        self.tail_offset = None;
        self.tail_buffer.clear();
        self.settled = false;
        let text = p
            .models
            .iter()
            .map(|m| {
                format!(
                    "{}: V = {}, P = {}, M = {}, sigma = {} ({})",
                    m.model,
                    opt(m.values.get(Metric::Velocity)),
                    opt(m.values.get(Metric::Power)),
                    opt(m.values.get(Metric::Mileage)),
                    opt(m.values.get(Metric::MaxStress)),
                    m.validity
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        self.note(
            format!(
                "controller {} ({}) applies f0 = {:.4} N, k = {:.4} rad/m, omega = {:.4} rad/s from step {}: {text}",
                p.controller, p.policy, p.wave.f0, p.wave.k, p.wave.omega, p.step
            ),
            rerun::TextLogLevel::INFO,
        );
        self.predictions = p.models;
    }

    fn log_metrics(&mut self, m: &Metrics) -> anyhow::Result<()> {
        self.counts.metric_blocks += 1;
        if m.steady {
            self.settled = true;
        }
        self.rec.set_time_sequence("step", m.step as i64);
        self.rec.set_duration_secs("sim_time", m.end);
        for name in paths::METRICS {
            if let Some(value) = m.values.get(name) {
                self.rec.log(
                    paths::metric_series(name, "plant"),
                    &rerun::Scalars::single(value),
                )?;
            }
        }
        for p in &self.predictions {
            for name in paths::METRICS {
                if let Some(v) = p.values.get(name) {
                    self.rec.log(
                        paths::metric_series(name, &p.model),
                        &rerun::Scalars::single(v),
                    )?;
                }
            }
        }
        Ok(())
    }

    /// One text row per episode at its block's step and time, sent in chunks of
    /// [`EPISODE_ROWS`] (and whatever is pending at every flush and at the end).
    fn log_events(&mut self, e: &Events) -> anyhow::Result<()> {
        self.rec.set_time_sequence("step", e.step as i64);
        self.rec.set_duration_secs("sim_time", e.time);
        for ep in &e.episodes {
            self.counts.episodes += 1;
            self.episodes.steps.push(e.step as i64);
            self.episodes.times.push(e.time);
            self.episodes.texts.push(format!(
                "node {} stuck {:.4} s ({:.4}-{:.4} s), left {}",
                ep.node,
                ep.duration,
                ep.start,
                ep.end,
                if ep.direction > 0 {
                    "forward"
                } else {
                    "backward"
                }
            ));
            if self.episodes.texts.len() >= EPISODE_ROWS {
                self.send_episodes()?;
            }
        }
        Ok(())
    }

    /// Sends the pending episode rows as one chunk.
    fn send_episodes(&mut self) -> anyhow::Result<()> {
        let rows = std::mem::take(&mut self.episodes);
        let n = rows.texts.len();
        if n == 0 {
            return Ok(());
        }
        let columns = rerun::TextLog::update_fields()
            .with_many_text(rows.texts)
            .with_many_level(std::iter::repeat_n(rerun::TextLogLevel::DEBUG, n))
            .columns_of_unit_batches()?;
        self.rec.send_columns(
            paths::LOG_EPISODES,
            [
                rerun::TimeColumn::new_sequence("step", rows.steps),
                rerun::TimeColumn::new_duration_secs("sim_time", rows.times),
            ],
            columns,
        )?;
        Ok(())
    }

    fn log_status(&mut self, s: &Status) -> anyhow::Result<()> {
        // Only the plant whose liveliness token we saw speaks for the plant, and only what fits
        // the run.
        let from_plant = s.role == Role::Plant && self.plant_id.as_deref() == Some(s.id.as_str());
        if s.role == Role::Plant && !from_plant {
            self.invalid(
                "status",
                &format!("a plant status from {:?}, not from the run's plant", s.id),
            );
            return Ok(());
        }
        if from_plant {
            if let Some(f) = self.facts {
                if let Err(reason) = checks::terminal(s, &f, self.plant_last_state) {
                    let early = s.state == ProcessState::Finished
                        && self.plant_last_state.is_none()
                        && s.step < f.last_step;
                    if early && self.held_finished.len() < HELD_FINISHED_MAX {
                        // a task-mode run may end early: its last state may be on its way
                        self.held_finished
                            .entry(s.step)
                            .or_insert_with(|| s.clone());
                    } else {
                        self.invalid("status", &reason);
                    }
                    return Ok(());
                }
            }
        }
        let level = match s.state {
            ProcessState::Failed => rerun::TextLogLevel::ERROR,
            ProcessState::Stopped => rerun::TextLogLevel::WARN,
            _ => rerun::TextLogLevel::INFO,
        };
        self.rec.log(
            paths::LOG_STATUS,
            &rerun::TextLog::new(format!(
                "{} {}: {} (step {}): {}",
                s.role, s.id, s.state, s.step, s.message
            ))
            .with_level(level),
        )?;
        if from_plant && s.state == ProcessState::Finished {
            if let Some(report) = &s.report {
                self.log_report(report)?;
            }
        }
        if from_plant && s.state.is_terminal() {
            self.finished = true;
        }
        Ok(())
    }

    /// The plant's final report: its metrics as scalars under `summary/`, and the whole report
    /// as a JSON document at `summary`.
    fn log_report(&mut self, r: &FinalReport) -> anyhow::Result<()> {
        let (step, time) = self.last_step_time;
        self.set_time(step, time);
        let values = r.values.iter().map(|(m, x)| (m.name(), x)).chain(
            paths::SUMMARY_EXTRA
                .iter()
                .map(|&k| (k, Some(r.dissipation))),
        );
        for (key, value) in values {
            if let Some(x) = value {
                self.rec.log(
                    format!("{}/{key}", paths::SUMMARY_ROOT),
                    &rerun::Scalars::single(x),
                )?;
            }
        }
        self.rec.log(
            paths::SUMMARY_ROOT,
            &rerun::TextDocument::new(serde_json::to_string_pretty(r)?),
        )?;
        Ok(())
    }
}

fn opt(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.4e}"))
}

#[cfg(test)]
mod pacing {
    use super::*;

    fn recorder(every: u64) -> Recorder {
        let (rec, _storage) = rerun::RecordingStreamBuilder::new("pacing")
            .memory()
            .expect("memory recording");
        Recorder::new(
            rec,
            RecorderOptions {
                every,
                ..Default::default()
            },
        )
        .expect("recorder")
    }

    /// Waits past the pacing interval, so the next call may change the decimation.
    fn tick() {
        std::thread::sleep(LAG_LIMIT + Duration::from_millis(5));
    }

    #[test]
    fn a_lagging_writer_decimates_once_per_interval_and_returns_to_the_request() {
        let mut r = recorder(2);
        tick();
        // a short inbox but states that waited too long: behind
        r.pace(3, LAG_LIMIT * 2, 0);
        assert_eq!(r.every, 4);
        // at most one change per interval, however long the lag
        r.pace(3, LAG_LIMIT * 10, 0);
        assert_eq!(r.every, 4);
        tick();
        r.pace(1000, Duration::ZERO, 0);
        assert_eq!(r.every, 8, "a long backlog is behind too");
        // a lag between a quarter and the whole limit changes nothing
        tick();
        r.pace(0, LAG_LIMIT / 2, 0);
        assert_eq!(r.every, 8);
        // caught up: halves back, never below the requested decimation
        for expected in [4, 2, 2] {
            tick();
            r.pace(0, Duration::ZERO, 0);
            assert_eq!(r.every, expected);
        }
    }
}

#[cfg(test)]
mod episodes {
    use super::*;
    use crawler_protocol::EpisodeMsg;

    /// Steps of the rows of `log/episodes` in the recording, chunk by chunk.
    fn episode_chunks(storage: &rerun::sink::MemorySinkStorage) -> Vec<Vec<i64>> {
        storage
            .take()
            .into_iter()
            .filter_map(|m| match m {
                rerun::log::LogMsg::ArrowMsg(_, a) => rerun::log::Chunk::from_arrow_msg(&a).ok(),
                _ => None,
            })
            .filter(|c| c.entity_path().to_string() == format!("/{}", paths::LOG_EPISODES))
            .map(|c| {
                let steps = c.timelines().get(&"step".into()).expect("step timeline");
                assert_eq!(steps.times_raw().len(), c.num_rows());
                steps.times_raw().to_vec()
            })
            .collect()
    }

    #[test]
    fn every_episode_is_one_row_at_its_step_sent_in_few_chunks() {
        let (rec, storage) = rerun::RecordingStreamBuilder::new("episodes")
            .memory()
            .expect("memory recording");
        let mut r = Recorder::new(rec, RecorderOptions::default()).expect("recorder");
        // 5000 episodes in blocks of 50: one full chunk on the way, the rest at the end
        let ep = EpisodeMsg {
            node: 3,
            start: 0.1,
            end: 0.2,
            duration: 0.1,
            direction: 1,
        };
        for step in 1..=100u64 {
            let e = Events {
                v: crawler_protocol::PROTOCOL_VERSION,
                step,
                time: step as f64 * 1e-3,
                episodes: vec![ep; 50],
            };
            r.log_events(&e).unwrap();
        }
        r.finish().unwrap();
        let chunks = episode_chunks(&storage);
        let lengths: Vec<usize> = chunks.iter().map(Vec::len).collect();
        assert_eq!(lengths, vec![EPISODE_ROWS, 5000 - EPISODE_ROWS]);
        let steps: Vec<i64> = chunks.concat();
        let expected: Vec<i64> = (1..=100).flat_map(|s| std::iter::repeat_n(s, 50)).collect();
        assert_eq!(steps, expected);
        assert_eq!(r.counts().episodes, 5000);
    }
}
