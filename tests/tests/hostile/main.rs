//! Attacks on a run, as another process of the same machine would try them (loopback only):
//! - a session without the credential: it cannot even connect, on any key ([`identity`]);
//! - a session that passed zenoh's authentication but lacks the message key (what a shared router
//!   is): its forged terminal statuses, its actuation carrying the joined controller's id, its
//!   events, its liveliness tokens and its rival answers to the plant's queries neither steer,
//!   join nor end the run ([`identity`]); its replays of the run's own sealed messages, from inside
//!   the run and from an earlier run with a kept credential, are refused and counted, never
//!   answered or recorded ([`replays`]);
//! - a process holding the credential that sends every kind of malformed or inconsistent
//!   message: each is rejected and counted, never applied ([`payloads`]);
//! - floods before and after the join: every process stays within its memory budget
//!   ([`floods`]).
//!
//! Every attack leaves the run's result (its state digest) unchanged and every process within
//! its memory budget.

mod floods;
mod identity;
mod payloads;
mod replays;

use crawler_facts::{Metric, MetricValues};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use zenoh::qos::CongestionControl;
use zenoh::Wait;

use crawler_e2e::{rss_kib, simulate, Proc};
use crawler_protocol::{
    EpisodeMsg, EpisodeStats, Events, FinalReport, ProcessState, ReportWindow, Role, Status,
    PROTOCOL_VERSION,
};
use crawler_transport::participant::{Congestion, Outlet};
use crawler_transport::Participant;

/// The memory budget of every process: growth of its resident memory above its idle size.
const BUDGET_MIB: f64 = 64.0;

/// The recorder of the attacked runs records the fields of every 64th state (and every state's
/// scalars). Its working set grows with what it records, attack or not: rerun's buffers take it
/// about 55 MiB above its idle size when it records the fields of every 4th state of a 512-cell
/// run (measured without any attack); recording fewer fields keeps what an attack would add
/// visible against [`BUDGET_MIB`].
const RECORDER: &[&str] = &["--every", "64"];

/// The wave policy of these runs, and the same run in process.
const WAVE: &[&str] = &["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"];

fn simulated(t_end: &str) -> serde_json::Value {
    simulate(&[
        "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", t_end,
    ])
}

/// The state digest of `policy` run in process on the plant of `--eps 1 --cells CELLS --t-end
/// T_END` (the scenario the co-simulated runs of these tests are given).
fn in_process_digest(policy: &str, cells: i64, t_end: f64) -> String {
    use crawler_physics::scenario::{Overrides, Scenario};
    let scenario = Scenario::load(
        None,
        &Overrides {
            eps: Some(1.0),
            cells: Some(cells),
            t_end: Some(t_end),
            ..Overrides::default()
        },
    )
    .unwrap();
    crawler_policies::in_process::run_named(&scenario, policy, &crawler_policies::Params::none())
        .unwrap()
        .report
        .state_digest
}

/// Puts `bytes` on `key` from `session`, without an envelope; dropped by the sender if its queue
/// is full.
fn put(session: &zenoh::Session, key: &str, bytes: Vec<u8>) {
    send(session, key, bytes, CongestionControl::Drop)
}

/// Like [`put`], but waits for room in the sender's queue: delivered unless the link breaks.
fn block(session: &zenoh::Session, key: &str, bytes: Vec<u8>) {
    send(session, key, bytes, CongestionControl::Block)
}

fn send(session: &zenoh::Session, key: &str, bytes: Vec<u8>, cc: CongestionControl) {
    session
        .put(key, bytes)
        .congestion_control(cc)
        .wait()
        .unwrap();
}

/// A participant's publishers, one per key (each keeps its sequence numbers), created as needed.
struct Outlets<'a> {
    participant: &'a Participant,
    outlets: HashMap<String, Outlet>,
}

impl<'a> Outlets<'a> {
    fn of(participant: &'a Participant) -> Self {
        Self {
            participant,
            outlets: HashMap::new(),
        }
    }

    /// Publishes `bytes` on `key`, enveloped and sealed as the participant's own message,
    /// waiting for room in the sender's queue.
    fn put(&mut self, key: &str, bytes: Vec<u8>) {
        let p = self.participant;
        let outlet = self
            .outlets
            .entry(key.to_string())
            .or_insert_with(|| p.outlet(key, Congestion::Block, false).unwrap());
        outlet.put(bytes).unwrap();
    }
}

/// A sample as it arrived: its key, payload and attachment (envelope and seal), to be sent again
/// unchanged.
#[derive(Clone)]
struct Captured {
    key: String,
    payload: Vec<u8>,
    attachment: Option<Vec<u8>>,
}

impl Captured {
    fn of(sample: &zenoh::sample::Sample) -> Self {
        Self {
            key: sample.key_expr().as_str().to_string(),
            payload: sample.payload().to_bytes().into_owned(),
            attachment: sample.attachment().map(|a| a.to_bytes().into_owned()),
        }
    }

    /// Sends it again, byte for byte, from `session` (blocking: delivered unless the link breaks).
    fn replay(&self, session: &zenoh::Session) {
        let b = session
            .put(&self.key, self.payload.clone())
            .congestion_control(CongestionControl::Block);
        match &self.attachment {
            Some(a) => b.attachment(a.clone()).wait().unwrap(),
            None => b.wait().unwrap(),
        }
    }
}

/// A plant status claiming `state` at `step` from `id`; a `finished` one with a forged (valid)
/// report.
fn status(id: &str, state: &str, step: u64) -> Status {
    let state = ProcessState::parse(state).unwrap();
    Status {
        v: PROTOCOL_VERSION,
        role: Role::Plant,
        id: id.into(),
        state,
        message: "forged".into(),
        step,
        rejected: Default::default(),
        report: (state == ProcessState::Finished).then(forged_report),
    }
}

/// A final report no run of these tests produced: its digest is `f0f0f0f0`.
fn forged_report() -> FinalReport {
    FinalReport {
        scenario: "forged".into(),
        values: MetricValues::of(&[
            (Metric::Velocity, 9.0),
            (Metric::Power, 1.0),
            (Metric::Mileage, 9.0),
            (Metric::MaxStress, 1.0),
            (Metric::MaxStrain, 0.0),
            (Metric::StuckFraction, 0.0),
            (Metric::MeanFrictionSelection, 0.0),
        ]),
        dissipation: 1.0,
        identity_velocity: 9.0,
        momentum_residual: None,
        events: EpisodeStats {
            count: 0,
            per_node_per_period: 0.0,
            mean_duration: 0.0,
            min_duration: 0.0,
        },
        window: ReportWindow {
            start: 0.0,
            end: 1.0,
            periods: 1.0,
            steady: true,
            whole_run: false,
        },
        cells: 512,
        dt: 1e-5,
        step: 1e-3,
        courant: 1.0,
        dx: 1.0 / 512.0,
        cells_per_wavelength: None,
        steps: 1,
        macro_steps: 1,
        t_end: 1.0,
        state_digest: "f0f0f0f0".into(),
        task: None,
    }
}

/// Episodes no run can have: a node far out of range, a negative duration.
fn forged_events(step: u64) -> Events {
    let ep = |node, duration| EpisodeMsg {
        node,
        start: 0.5,
        end: 0.6,
        duration,
        direction: 1,
    };
    Events {
        v: PROTOCOL_VERSION,
        step,
        time: 0.7,
        episodes: vec![ep(u32::MAX, 0.1), ep(3, -0.1), ep(4, 1e9)],
    }
}

/// The count after `kind: ` in the plant's "rejected messages" line.
fn rejected(stderr: &str, kind: &str) -> u64 {
    let line = stderr
        .lines()
        .find(|l| l.contains("rejected messages: Rejections"))
        .unwrap_or("");
    line.split(&format!("{kind}: "))
        .nth(1)
        .and_then(|r| r.split(|ch: char| !ch.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

/// The number before `what` in a line of `stderr` that contains `line` (the recorder's closing
/// line, the controller's refusals).
fn count_in(stderr: &str, line: &str, what: &str) -> u64 {
    stderr
        .lines()
        .filter(|l| l.contains(line))
        .find_map(|l| {
            l.split(what)
                .next()
                .and_then(|s| s.rsplit(' ').next())
                .and_then(|n| n.trim_start_matches('(').parse().ok())
        })
        .unwrap_or(0)
}

/// The number before `what` in the bridge's closing line.
fn bridge_count(stderr: &str, what: &str) -> u64 {
    count_in(stderr, "recording closed", what)
}

/// The number before `what` in the controller's line of what it refused at arrival.
fn controller_refused(stderr: &str, what: &str) -> u64 {
    count_in(stderr, "refused at arrival", what)
}

/// The largest peak resident memory (KiB) seen for each pid until `stop` (a process that ended
/// keeps its last reading).
fn sample_peaks(pids: Vec<u32>, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<Vec<u64>> {
    std::thread::spawn(move || {
        let mut peaks = vec![0u64; pids.len()];
        loop {
            for (peak, pid) in peaks.iter_mut().zip(&pids) {
                if let Some((_, hwm)) = rss_kib(*pid) {
                    *peak = (*peak).max(hwm);
                }
            }
            if stop.load(Ordering::Relaxed) {
                return peaks;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    })
}

/// The processes of a run watched while an attack goes on: each must stay within [`BUDGET_MIB`]
/// of the resident memory it had when the watch began.
struct Budgets {
    names: Vec<&'static str>,
    idle: Vec<u64>,
    stop: Arc<AtomicBool>,
    sampling: std::thread::JoinHandle<Vec<u64>>,
}

impl Budgets {
    fn watch(procs: &[(&'static str, &Proc)]) -> Self {
        let idle = procs
            .iter()
            .map(|(name, p)| rss_kib(p.pid()).unwrap_or_else(|| panic!("{name} ended")).0)
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let sampling = sample_peaks(procs.iter().map(|(_, p)| p.pid()).collect(), stop.clone());
        Self {
            names: procs.iter().map(|(name, _)| *name).collect(),
            idle,
            stop,
            sampling,
        }
    }

    /// Stops watching (call it once the processes ended) and checks every budget.
    fn check(self) {
        self.stop.store(true, Ordering::Relaxed);
        let peaks = self.sampling.join().unwrap();
        for ((name, idle), peak) in self.names.iter().zip(&self.idle).zip(peaks) {
            let growth = peak.saturating_sub(*idle) as f64 / 1024.0;
            eprintln!(
                "{name}: idle {idle} KiB, peak during the attack {peak} KiB: +{growth:.1} MiB"
            );
            assert!(
                growth < BUDGET_MIB,
                "{name} grew by {growth:.1} MiB during the attack (budget {BUDGET_MIB} MiB)"
            );
        }
    }
}

/// What an honest listener of the run counts of the plant's events and metrics: each message of
/// the plant's run instance once (by its sequence number), the episodes in them and the blocks.
#[derive(Default)]
struct Honest {
    seen: std::collections::HashSet<(String, u64)>,
    episodes: u64,
    blocks: u64,
}

impl Honest {
    /// Counts `sample` if it is the plant's (`run` instance, `plant` id) and not seen before.
    fn count(
        &mut self,
        sample: &zenoh::sample::Sample,
        run: &crawler_protocol::RunNonce,
        plant: &crawler_protocol::ProcessId,
    ) {
        let Some(att) = sample.attachment().map(|a| a.to_bytes().into_owned()) else {
            return;
        };
        let Ok(h) = crawler_protocol::Header::decode(&att) else {
            return;
        };
        if h.run != *run || h.sender != *plant || h.role != Role::Plant {
            return;
        }
        let key = sample.key_expr().as_str().to_string();
        if !self.seen.insert((key.clone(), h.seq)) {
            return;
        }
        let bytes = sample.payload().to_bytes();
        if key.ends_with("/events") {
            if let Ok(e) = crawler_protocol::decode::<Events>(&bytes) {
                self.episodes += e.episodes.len() as u64;
            }
        } else if key.ends_with("/metrics") {
            self.blocks += 1;
        }
    }
}

type Shared<T> = Arc<Mutex<T>>;
