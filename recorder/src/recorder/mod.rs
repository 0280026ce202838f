//! The writer: turns protocol messages into Rerun entities, in step order, columnar.
//!
//! States are recorded in step order (a few held back to reorder late arrivals); what each state
//! adds to each entity is kept in [`columns::Columns`] and sent as one chunk per entity every
//! block of states ([`RecorderOptions::block_states`], or sooner at a flush). Every state's
//! scalars are recorded, and every `--every`-th state's fields; nothing is thinned for speed (the
//! inbox applies back-pressure instead, [`crate::session`]); a state that never reached the
//! writer is counted, noted in `log/recorder` and in the `recorder/*` series.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

use rerun::RecordingStream;

use crawler_protocol::{
    decode, Environment, Events, Metrics, ModelInfo, Prediction, Series, State, Status,
};

use crate::checks::{self, RunFacts};
use crate::paths;

pub mod columns;
mod heat;
mod messages;
mod picture;
mod state;

pub use columns::{Live, Sinks};

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

/// Recorder settings.
#[derive(Debug, Clone, Copy)]
pub struct RecorderOptions {
    /// Record the fields of every `every`-th step (scalars, metrics, events and lanes: every one).
    pub every: u64,
    /// Most nodes given a stick/slip lane (evenly spaced).
    pub lanes: usize,
    /// Rows (recorded states) per heatmap block.
    pub heatmap_rows: usize,
    /// Most states per block; `None`: as many as make the largest entity's chunk about
    /// [`BLOCK_BYTES`].
    pub block_states: Option<usize>,
    /// Send what the block holds at least this often (bounds what `kill -9` loses).
    pub flush_every: Duration,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            every: 1,
            lanes: 64,
            heatmap_rows: 256,
            block_states: None,
            flush_every: Duration::from_millis(200),
        }
    }
}

/// Bytes the largest entity (the body's boxes, about 18 bytes a cell) gets per block: Rerun's
/// chunks of a megabyte or two are what its store and file index handle best, and four such blocks merge
/// into one at close ([`crate::compact`]).
pub const BLOCK_BYTES: usize = 512 << 10;

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
    /// Metric blocks logged (forcing-period and clock blocks).
    pub metric_blocks: u64,
    /// Of `metric_blocks`: clock blocks.
    pub clock_blocks: u64,
    /// Chunks of states sent (blocks).
    pub blocks: u64,
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
    /// States missing from the step sequence the writer recorded (dropped before it, or lost).
    pub missing_states: u64,
}

/// What the plant said about its run and the pipe, once known.
#[derive(Debug, Clone)]
struct Model {
    facts: RunFacts,
    /// Body length L, m.
    length: f64,
    /// Cross-section A_c, m^2.
    area: f64,
    /// Communication step H, s.
    step: f64,
    /// Where node `i` sits on the body, in cells: at `(i + node_offset) dx` from the tail (0 on a
    /// periodic body, 0.5 on a free one, whose nodes are the cell centres).
    node_offset: f64,
    periodic: bool,
}

/// Running sums of the task's progress, from the first state recorded.
#[derive(Debug, Clone, Copy, Default)]
struct Task {
    /// Mean displacement at the first state, m.
    start: Option<f64>,
    /// Actuator work since then, J.
    energy: f64,
}

/// Converts messages into a recording.
pub struct Recorder {
    sinks: Sinks,
    opts: RecorderOptions,
    columns: columns::Columns,
    /// States in the current block.
    block_len: usize,
    /// Most states per block (from the body's size once the model is known).
    block_max: usize,
    pending: BTreeMap<u64, State>,
    next_step: Option<u64>,
    last_stuck: Vec<bool>,
    lane_nodes: Vec<usize>,
    heat: heat::Heat,
    predictions: Vec<crawler_protocol::ModelPrediction>,
    tail: TailPrediction,
    task: Task,
    /// Step and time of the first state recorded.
    first_at: Option<(u64, f64)>,
    /// Step of the metric block the predictions were last recorded at.
    predicted_at: Option<u64>,
    counts: Counts,
    last_flush: Instant,
    finished: bool,
    model: Option<Model>,
    plant_id: Option<String>,
    last_step_time: (u64, f64),
    last_state_at: Option<Instant>,
    early: Vec<Incoming>,
    controller_id: Option<String>,
    /// The controller of the last state recorded ("" before one joined).
    acting: Option<String>,
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
    /// Episode rows not yet sent.
    episodes: messages::EpisodeRows,
}

/// The paper's tail solution, aligned with the plant's once it has settled.
#[derive(Debug, Default)]
struct TailPrediction {
    series: Option<Series>,
    offset: Option<f64>,
    buffer: Vec<(u64, f64, f64)>,
    settled: bool,
}

/// Most `finished` statuses held while the plant's last state is awaited.
const HELD_FINISHED_MAX: usize = 8;

/// The recording's streams: the file at `path` (with the default layout) and, if given, a live
/// viewer (its own stream of the same recording).
///
/// With `footer` (the default of `crawler-recorder record`) the file ends with Rerun's footer, an
/// index of every chunk: `rerun rrd verify` wants it and large files load faster. The encoder
/// keeps that index in memory for the whole run (about 40 MB per 10^6 steps); without it memory
/// stays flat however long the run. The footer is written when the file sink closes:
/// [`Recorder::finish`].
pub fn open(
    path: &Path,
    footer: bool,
    viewer: Option<crate::viewer::ViewerSink>,
) -> anyhow::Result<Sinks> {
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
    let id = crate::layout::uuid_string(&crate::layout::uuid());
    let stream = |sink: Box<dyn rerun::sink::LogSink>| {
        rerun::RecordingStreamBuilder::new("crawler")
            .recording_id(id.clone())
            .set_sinks(vec![sink])
            .map_err(|e| cannot(&e))
    };
    let file = stream(Box::new(file))?;
    let view = viewer.map(|v| stream(Box::new(v))).transpose()?;
    let sinks = Sinks { file, view };
    for rec in sinks.each() {
        crate::layout::send(rec)?;
    }
    Ok(sinks)
}

/// A recording written to `path` only (see [`open`]).
pub fn open_file(path: &Path, footer: bool) -> anyhow::Result<Sinks> {
    open(path, footer, None)
}

/// Streams of a recording kept in memory (tests): the file's stream writes to `storage`.
pub fn in_memory(app: &'static str) -> anyhow::Result<(Sinks, rerun::sink::MemorySinkStorage)> {
    let (file, storage) = rerun::RecordingStreamBuilder::new(app).memory()?;
    Ok((Sinks { file, view: None }, storage))
}

impl Recorder {
    /// A recorder writing to `sinks`.
    pub fn new(sinks: Sinks, opts: RecorderOptions) -> anyhow::Result<Self> {
        let me = Self {
            sinks,
            opts: RecorderOptions {
                every: opts.every.max(1),
                ..opts
            },
            columns: columns::Columns::default(),
            block_len: 0,
            block_max: opts.block_states.unwrap_or(64).max(1),
            pending: BTreeMap::new(),
            next_step: None,
            last_stuck: Vec::new(),
            lane_nodes: Vec::new(),
            heat: heat::Heat::new(opts.heatmap_rows),
            predictions: Vec::new(),
            tail: TailPrediction::default(),
            task: Task::default(),
            first_at: None,
            predicted_at: None,
            counts: Counts::default(),
            last_flush: Instant::now(),
            finished: false,
            model: None,
            plant_id: None,
            last_step_time: (0, 0.0),
            last_state_at: None,
            early: Vec::new(),
            controller_id: None,
            acting: None,
            invalid_by_kind: BTreeMap::new(),
            environment: None,
            plant_gone_at: None,
            plant_last_state: None,
            held_finished: BTreeMap::new(),
            episodes: messages::EpisodeRows::default(),
        };
        me.log_static()?;
        Ok(me)
    }

    /// Counters so far.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The file's stream (tests flush it).
    pub fn file(&self) -> &RecordingStream {
        &self.sinks.file
    }

    /// True once the plant reported the end of the run and its last state was recorded, or the
    /// plant ended (or died) and what it sent before had two seconds to arrive.
    pub fn finished(&self) -> bool {
        self.finished
            || self
                .last_state_at
                .is_some_and(|t| t.elapsed() > Duration::from_secs(2))
            || self
                .plant_gone_at
                .is_some_and(|t| t.elapsed() > Duration::from_secs(2))
    }

    /// Takes the plant's model description (the body, the step, the run's last step, marked at
    /// once so that the recording's timeline spans the whole run from its first bytes) and the
    /// pipe the plant resolved, if it answered; then records what arrived before.
    pub fn set_model(
        &mut self,
        info: &ModelInfo,
        environment: Option<Environment>,
    ) -> anyhow::Result<()> {
        let positive = |x: f64, or: f64| if x.is_finite() && x > 0.0 { x } else { or };
        let length = positive(info.length, 1.0);
        // the protocol admits only "periodic" and "free"
        let periodic = info.boundary != "free";
        self.model = Some(Model {
            facts: RunFacts::of(info),
            length,
            area: positive(info.area, f64::NAN),
            step: positive(info.step, f64::NAN),
            node_offset: if periodic { 0.0 } else { 0.5 },
            periodic,
        });
        let cells = (info.cells as usize).max(1);
        // the body's boxes take about 18 bytes a cell and row: blocks of about BLOCK_BYTES
        self.block_max = self
            .opts
            .block_states
            .unwrap_or(BLOCK_BYTES / (18 * cells))
            .clamp(1, 4096);
        let end = info.start_time + info.last_step as f64 * info.step;
        self.sinks.log_at(
            (info.last_step, end),
            paths::LOG_RECORDER,
            &rerun::TextLog::new(format!(
                "run {} ends at step {} (t = {end} s): {} cells, L = {} m, H = {} s, eps = {}, n_F = {}; \
                 the fields of {} recorded, in blocks of {} states",
                info.run,
                info.last_step,
                info.cells,
                info.length,
                info.step,
                info.eps,
                info.n_f,
                every(self.opts.every),
                self.block_max
            ))
            .with_level(rerun::TextLogLevel::INFO),
        )?;
        self.draw_world(environment.as_ref())?;
        if let Some(env) = environment {
            self.set_environment(env)?;
        }
        // what arrived before can be checked now
        for msg in std::mem::take(&mut self.early) {
            self.handle(msg)?;
        }
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

    /// Records that `oversize + unsealed` payloads in all were refused at arrival so far, noting
    /// each increase in the recording.
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

    /// Records that the callbacks dropped `dropped` messages in all so far (the writer was behind
    /// longer than the back-pressure allows), noting each increase.
    pub fn dropped(&mut self, dropped: u64) {
        if dropped > self.counts.dropped {
            self.note(
                format!(
                    "{dropped} messages dropped so far: the recorder was behind longer than the plant may be held up"
                ),
                rerun::TextLogLevel::WARN,
            );
            self.counts.dropped = dropped;
        }
    }

    fn note(&self, text: String, level: &str) {
        let _ = self.sinks.log_at(
            self.last_step_time,
            paths::LOG_RECORDER,
            &rerun::TextLog::new(text).with_level(level),
        );
    }

    /// Handles one message. Never fails on bad input: undecodable messages and messages the run
    /// cannot have produced are counted and noted, never recorded. Events, metrics and
    /// predictions that arrive before the plant's model description wait for it.
    pub fn handle(&mut self, msg: Incoming) -> anyhow::Result<()> {
        let facts = self.model.as_ref().map(|m| m.facts);
        match msg {
            Incoming::State(b) => match decode::<State>(&b) {
                Ok(s) => self.take_state(s, facts.as_ref())?,
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
                    Ok(()) => self.log_metrics(&m),
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

    /// A decoded state: checked, queued in step order, and recorded with those before it.
    fn take_state(&mut self, s: State, facts: Option<&RunFacts>) -> anyhow::Result<()> {
        if let Some(f) = facts {
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
        if self.pending.contains_key(&s.step) || self.next_step.is_some_and(|n| s.step < n) {
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
        Ok(())
    }

    /// Sends everything held if the flush interval passed since the last time.
    pub fn maybe_flush(&mut self) -> anyhow::Result<()> {
        if self.last_flush.elapsed() >= self.opts.flush_every {
            self.flush()?;
            for rec in self.sinks.each() {
                let _ = rec.flush_async();
            }
        }
        Ok(())
    }

    /// Sends the block's thick columns (the fields and the body: one chunk per entity).
    fn send_block(&mut self) -> anyhow::Result<()> {
        self.columns.send_thick(&self.sinks)?;
        self.counts.blocks += 1;
        self.block_len = 0;
        Ok(())
    }

    /// Sends every column held (one chunk per entity), the recorder's counters with them, and
    /// the episodes.
    fn flush(&mut self) -> anyhow::Result<()> {
        let at = self.last_step_time;
        let c = self.counts;
        if c.states > 0 {
            for (name, value) in [
                ("states", c.states),
                ("with_fields", c.recorded_steps),
                ("dropped", c.dropped),
                ("missing", c.missing_states),
            ] {
                self.columns
                    .scalar(&format!("{}/{name}", paths::RECORDER), at, value as f64);
            }
        }
        self.send_block()?;
        self.columns.send_thin(&self.sinks)?;
        self.send_episodes()?;
        self.last_flush = Instant::now();
        Ok(())
    }

    /// Records every pending state (end of run or shutdown), sends what is held, and closes the
    /// file (its writer thread ends and writes the footer); a viewer stays connected.
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
        self.note(self.closing_note(), rerun::TextLogLevel::INFO);
        self.flush_heat()?;
        self.flush()?;
        for rec in self.sinks.each() {
            rec.flush_blocking()
                .map_err(|e| anyhow::anyhow!("cannot flush the recording: {e}"))?;
        }
        self.sinks.file.finalize_deferred_sinks();
        Ok(())
    }

    /// What the recording holds, in a sentence (also the recorder's closing line).
    pub fn closing_note(&self) -> String {
        let c = &self.counts;
        let recorded = c.states - c.duplicates;
        let lost = if c.missing_states + c.dropped > 0 {
            format!(
                "; {} states never reached the writer ({} messages dropped while it was behind)",
                c.missing_states, c.dropped
            )
        } else {
            String::new()
        };
        let fields = match (c.missing_states + c.dropped, self.opts.every) {
            (0, 1) => ": every state's fields recorded".to_string(),
            (0, _) => format!(": the fields of {} recorded", every(self.opts.every)),
            _ => String::new(),
        };
        format!(
            "{recorded} states ({} with fields){fields}{lost}",
            c.recorded_steps
        )
    }

    /// Emits pending states in step order; holds a few back to reorder late arrivals.
    fn drain(&mut self, all: bool) -> anyhow::Result<()> {
        while let Some((&step, _)) = self.pending.iter().next() {
            let contiguous = self.next_step.is_none_or(|n| step == n);
            if !(all || contiguous || self.pending.len() > 32) {
                break;
            }
            let s = self.pending.remove(&step).expect("present");
            if let Some(n) = self.next_step {
                self.counts.missing_states += step.saturating_sub(n);
            }
            self.next_step = Some(step + 1);
            self.log_state(&s)?;
            self.block_len += 1;
            if self.block_len >= self.block_max {
                self.send_block()?;
            }
        }
        Ok(())
    }
}

/// "every state", "every 2nd state", "every 4th state".
fn every(n: u64) -> String {
    let suffix = match (n % 10, n % 100) {
        (1, r) if r != 11 => "st",
        (2, r) if r != 12 => "nd",
        (3, r) if r != 13 => "rd",
        _ => "th",
    };
    if n == 1 {
        "every state".to_string()
    } else {
        format!("every {n}{suffix} state")
    }
}

#[cfg(test)]
mod tests;
