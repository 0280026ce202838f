//! A recording session (`crawler-recorder record`): subscribe to a run, record it until it ends (or
//! Ctrl-C, or no message for `--idle-timeout` seconds), close the file properly (merged chunks,
//! footer) and say what it holds.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver};

use crawler_cli::Exit;
use crawler_protocol::{RunKeys, RunLimits};
use crawler_transport::{Credential, Network};

use crate::output::Output;
use crate::viewer::{self, Link, Viewer};
use crate::{compact, Incoming, Recorder, RecorderOptions};

pub mod connection;

use connection::{arrival_refusals, Believed, Connection, Inbox};

/// How long the viewer may take to answer before the recorder says it is not there.
const VIEWER_GRACE: Duration = Duration::from_secs(3);

/// How long the end of the run waits for the viewer to confirm what it was sent.
const VIEWER_FLUSH: Duration = Duration::from_secs(10);

/// Everything `crawler-recorder record` was told.
#[derive(Debug, Clone)]
pub struct Settings {
    /// The run and how to reach it.
    pub network: Network,
    /// Output file.
    pub out: PathBuf,
    /// What to record.
    pub opts: RecorderOptions,
    /// Messages the inbox holds at most.
    pub inbox: usize,
    /// End the file with Rerun's footer.
    pub footer: bool,
    /// Merge the file's chunks at close.
    pub optimize: bool,
    /// A viewer to stream to live (its gRPC address).
    pub connect: Option<String>,
    /// Start that viewer.
    pub spawn: bool,
    /// The viewer's executable.
    pub viewer_exe: Option<PathBuf>,
    /// Give up after this many seconds without a message.
    pub idle_timeout: Option<f64>,
}

impl Settings {
    /// Checks every setting (errors name the flag, the value and what is allowed); returns the
    /// viewer's address, if any.
    pub fn validate(&self) -> anyhow::Result<Option<rerun::external::re_uri::ProxyUri>> {
        let o = &self.opts;
        anyhow::ensure!(
            o.every >= 1,
            "invalid --every = {}: allowed an integer >= 1",
            o.every
        );
        anyhow::ensure!(
            (1..=4096).contains(&o.lanes),
            "invalid --lanes = {}: allowed 1 to 4096",
            o.lanes
        );
        anyhow::ensure!(
            (1..=65536).contains(&o.heatmap_rows),
            "invalid --heatmap-rows = {}: allowed 1 to 65536",
            o.heatmap_rows
        );
        if let Some(b) = o.block_states {
            anyhow::ensure!(
                (1..=4096).contains(&b),
                "invalid --block = {b}: allowed 1 to 4096 states"
            );
        }
        anyhow::ensure!(
            (16..=1 << 20).contains(&self.inbox),
            "invalid --inbox = {}: allowed 16 to 1048576",
            self.inbox
        );
        if let Some(t) = self.idle_timeout {
            anyhow::ensure!(
                t.is_finite() && t > 0.0 && t < 1e9,
                "invalid --idle-timeout = {}: allowed a number of seconds, 0 < idle-timeout < 1e9",
                crawler_cli::number(t)
            );
        }
        Output::new(&self.out)?;
        let url = match (&self.connect, self.spawn) {
            (Some(u), _) => Some(viewer::parse_url(u)?),
            (None, true) => Some(viewer::parse_url(viewer::DEFAULT_URL)?),
            (None, false) => None,
        };
        if let (Some(u), true) = (&url, self.spawn) {
            anyhow::ensure!(
                u.origin.is_localhost(),
                "invalid --connect = {u} with --spawn: allowed a loopback address (the viewer is started on this machine)"
            );
        }
        Ok(url)
    }
}

/// How the loop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ended {
    /// The run ended (or its plant went away).
    Finished,
    /// Ctrl-C (SIGINT, SIGTERM).
    Interrupted,
    /// No message for `--idle-timeout` seconds.
    Idle,
}

/// A session's state.
struct Session {
    s: Settings,
    keys: RunKeys,
    output: Output,
    recorder: Recorder,
    viewer: Option<Viewer>,
    inbox: Inbox,
    stop: Receiver<()>,
    started: Instant,
    id: crawler_protocol::ProcessId,
    /// The run instance and the plant, once learnt from the plant's sealed answer.
    believed: Believed,
    credential: Option<Credential>,
}

/// Records the run `s` describes; the exit status says how it ended.
pub fn record(s: Settings) -> anyhow::Result<Exit> {
    let url = s.validate()?;
    let keys = RunKeys::new(&s.network.run_id)?;
    let output = Output::new(&s.out)?;
    // from here on Ctrl-C ends the recording properly (and removes an unused temporary file)
    let (stop_tx, stop) = bounded::<()>(4);
    ctrlc::set_handler(move || {
        let _ = stop_tx.try_send(());
    })?;
    let temp = output.create()?.to_path_buf();
    let (viewer, viewer_sink) = start_viewer(url, &s)?;
    let sinks = crate::recorder::open(&temp, s.footer, viewer_sink)?;
    let recorder = Recorder::new(sinks, s.opts)?;
    let interrupted = || !stop.is_empty();
    let credential = s.network.wait_for_credential(
        "crawler-recorder",
        Duration::from_secs_f64(s.idle_timeout.unwrap_or(86_400.0)),
        &interrupted,
    )?;
    if credential.is_none() {
        eprintln!("crawler-recorder: warning: unauthenticated (--no-auth): the recording cannot tell the run's messages from anyone else's");
    }
    eprintln!(
        "crawler-recorder: recording {} into {}{} (waiting for the plant)",
        s.network.describe(),
        s.out.display(),
        viewer
            .as_ref()
            .map(|v| format!(" and live to the viewer at {}", v.url()))
            .unwrap_or_default()
    );
    let session = Session {
        inbox: Inbox::new(s.inbox),
        s,
        keys,
        output,
        recorder,
        viewer,
        stop,
        started: Instant::now(),
        id: crawler_transport::process_id(),
        believed: Believed::default(),
        credential,
    };
    session.run()
}

/// Starts the viewer link if asked (never failing the run because of the viewer: it says so and
/// records the file).
fn start_viewer(
    url: Option<rerun::external::re_uri::ProxyUri>,
    s: &Settings,
) -> anyhow::Result<(Option<Viewer>, Option<viewer::ViewerSink>)> {
    let Some(u) = url else {
        return Ok((None, None));
    };
    let spawned = !s.spawn
        || match viewer::spawn(&u, s.viewer_exe.as_deref()) {
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
    if !spawned {
        return Ok((None, None));
    }
    let (v, sink) = Viewer::connect(u)?;
    Ok((Some(v), Some(sink)))
}

impl Session {
    fn run(mut self) -> anyhow::Result<Exit> {
        let stop = self.stop.clone();
        let idle = self.s.idle_timeout;
        let started = self.started;
        let mut give_up =
            || !stop.is_empty() || idle.is_some_and(|t| started.elapsed().as_secs_f64() > t);
        let Some(conn) = self.connect(RunLimits::before_model(), &mut give_up)? else {
            return self.no_plant();
        };
        let (ended, conn) = self.run_loop(conn)?;
        if ended != Ended::Idle {
            // what already arrived is recorded before the file is closed (only that: a run that
            // goes on keeps sending)
            let waiting = self.inbox.rx.len() + self.inbox.status_rx.len();
            for _ in 0..waiting {
                let Ok((_, msg)) = self
                    .inbox
                    .rx
                    .try_recv()
                    .or_else(|_| self.inbox.status_rx.try_recv())
                else {
                    break;
                };
                self.recorder.handle(msg.split().0)?;
            }
        }
        let code = self.close_and_report(ended)?;
        if let Some(c) = conn {
            c.close();
        }
        Ok(code)
    }

    fn connect(
        &mut self,
        limit: usize,
        give_up: &mut dyn FnMut() -> bool,
    ) -> anyhow::Result<Option<Connection>> {
        Connection::open(
            &self.s.network,
            &mut self.credential,
            limit,
            (&self.inbox, self.id, &self.believed),
            give_up,
        )
    }

    /// No plant came (or Ctrl-C while waiting): nothing recorded, `--out` as it was.
    fn no_plant(mut self) -> anyhow::Result<Exit> {
        if let Some(v) = self
            .viewer
            .as_ref()
            .filter(|v| v.link() == Link::Connecting)
        {
            eprintln!(
                "crawler-recorder: warning: no Rerun viewer answers at {} (start one with `rerun --bind 127.0.0.1`, or pass --spawn)",
                v.url()
            );
        }
        let interrupted = !self.stop.is_empty();
        let (_, said) = self.close(false)?;
        eprintln!(
            "crawler-recorder: {}; nothing recorded (no state arrived), {} left as it was{said}",
            if interrupted {
                "interrupted"
            } else {
                "no plant"
            },
            self.s.out.display(),
        );
        Ok(if interrupted {
            Exit::Interrupted
        } else {
            Exit::Timeout
        })
    }

    /// Records messages until the run ends; the connection, unless a reconnection was cut short.
    fn run_loop(&mut self, mut conn: Connection) -> anyhow::Result<(Ended, Option<Connection>)> {
        let mut model_known = false;
        let mut next_query = Instant::now();
        let mut last_message = Instant::now();
        let mut viewer_warned = false;
        loop {
            crossbeam_channel::select! {
                recv(self.stop) -> _ => return Ok((Ended::Interrupted, Some(conn))),
                recv(self.inbox.plant_rx) -> msg => {
                    if let Ok(msg) = msg {
                        self.recorder.handle(msg)?;
                    }
                },
                recv(self.inbox.rx) -> msg => {
                    if let Ok((_, msg)) = msg {
                        self.recorder.handle(msg.split().0)?;
                        last_message = Instant::now();
                    }
                },
                recv(self.inbox.status_rx) -> msg => {
                    if let Ok((_, msg)) = msg {
                        self.recorder.handle(msg.split().0)?;
                        last_message = Instant::now();
                    }
                },
                default(Duration::from_millis(100)) => {},
            }
            if !self.output.promoted() && self.recorder.counts().states > 0 {
                // the run produced a recording: it replaces --out from now on
                self.output.promote()?;
            }
            if !viewer_warned {
                viewer_warned = self.warn_if_no_viewer();
            }
            self.inbox.sink.relieve();
            self.recorder.dropped(self.inbox.sink.dropped());
            self.recorder.maybe_flush()?;
            if self.recorder.finished() && self.inbox.is_empty() {
                return Ok((Ended::Finished, Some(conn)));
            }
            let r = &self.inbox.refused;
            self.recorder
                .refused_at_arrival(r.oversize(), arrival_refusals(r));
            if !model_known && Instant::now() >= next_query {
                next_query = Instant::now() + Duration::from_millis(200);
                match self.find_model(conn)? {
                    (Some(c), known) => {
                        conn = c;
                        model_known = known;
                    }
                    (None, _) => return Ok((Ended::Interrupted, None)),
                }
            }
            if self
                .s
                .idle_timeout
                .is_some_and(|t| last_message.elapsed().as_secs_f64() > t)
            {
                return Ok((Ended::Idle, Some(conn)));
            }
        }
    }

    /// Warns once if the viewer did not answer within [`VIEWER_GRACE`]; true once said (or no
    /// need to).
    fn warn_if_no_viewer(&self) -> bool {
        let Some(v) = &self.viewer else {
            return true;
        };
        if v.link() == Link::Connecting && self.started.elapsed() > VIEWER_GRACE {
            eprintln!(
                "crawler-recorder: warning: no Rerun viewer answers at {} (start one with `rerun --bind 127.0.0.1`, or pass --spawn); recording to the file, the viewer gets the data if it comes up",
                v.url()
            );
            return true;
        }
        v.link() != Link::Connecting
    }

    /// Asks the plant for its model (and pipe); on an answer, records from then on every state
    /// (reconnecting first if the run's messages are larger than the connection reassembles).
    /// Returns the connection (`None`: interrupted while reconnecting) and whether the model is
    /// known.
    fn find_model(&mut self, conn: Connection) -> anyhow::Result<(Option<Connection>, bool)> {
        let Some((info, plant, run)) = conn.query_model(&self.keys) else {
            return Ok((Some(conn), false));
        };
        // the run instance and the plant, from a sealed answer to a fresh challenge (not from
        // liveliness): from now on the plant's keys are taken only from it
        self.believed.run.learn(run);
        self.believed.plant.set(&[plant]);
        self.recorder.handle(Incoming::PlantUp(plant.to_string()))?;
        let limits = RunLimits::new(info.cells as usize);
        if limits.largest() > conn.limit {
            // a very large grid: reconnect able to reassemble its largest messages
            conn.close();
            let stop = self.stop.clone();
            let mut give_up = || !stop.is_empty();
            return Ok((self.connect(limits.largest(), &mut give_up)?, false));
        }
        conn.state_gate.set_limit(limits.state());
        // the pipe as the plant resolved it (a plant that does not answer: no map drawn), taken
        // with the model so that every state from now on is drawn on it
        let environment = conn.query_environment(&self.keys);
        self.recorder.set_model(&info, environment)?;
        // Our subscriptions reached the plant before this reply did (same link, in order): from
        // here on nothing the plant publishes is missed.
        eprintln!(
            "crawler-recorder: plant found ({} cells, last step {}); recording every state from now on",
            info.cells, info.last_step
        );
        Ok((Some(conn), true))
    }

    /// Ends the recording: writes what is pending, closes the file (with its footer), merges its
    /// chunks (`optimize`, unless a second Ctrl-C says not to wait), moves it to `--out` if the
    /// run produced one (else removes it, leaving `--out` as it was), and flushes the viewer
    /// (bounded). Returns whether the run produced a recording and what to say of the viewer.
    fn close(&mut self, optimize: bool) -> anyhow::Result<(bool, String)> {
        self.recorder.finish()?;
        let recorded = self.recorder.counts().states > 0;
        if recorded {
            self.output.promote()?;
            if optimize && self.s.optimize {
                let stop = self.stop.clone();
                match compact::optimize(self.output.out(), self.s.footer, &|| !stop.is_empty()) {
                    Ok(Some(m)) => eprintln!(
                        "crawler-recorder: chunks merged: {} -> {} (the equivalent of `rerun rrd optimize`)",
                        m.before, m.after
                    ),
                    Ok(None) => eprintln!(
                        "crawler-recorder: interrupted again: the recording's chunks left unmerged (`rerun rrd optimize` merges them)"
                    ),
                    Err(e) => eprintln!(
                        "crawler-recorder: warning: the recording's chunks could not be merged, it is complete all the same: {e:#}"
                    ),
                }
            }
        }
        let Some(v) = &self.viewer else {
            return Ok((recorded, String::new()));
        };
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
        Ok((recorded, format!("; {said} at {}", v.url())))
    }

    /// Closes the recording and says how the run ended and what the recording holds.
    fn close_and_report(&mut self, ended: Ended) -> anyhow::Result<Exit> {
        let inbox = &self.inbox.refused;
        self.recorder
            .refused_at_arrival(inbox.oversize(), arrival_refusals(inbox));
        self.recorder.dropped(self.inbox.sink.dropped());
        let (recorded, viewer) = self.close(true)?;
        let out = self.s.out.display();
        let c = self.recorder.counts();
        let how = match ended {
            Ended::Interrupted => "interrupted; recording closed properly",
            Ended::Finished => "run finished; recording closed",
            Ended::Idle => "no message for the idle timeout; recording closed",
        };
        // sent before the recorder knew the run's instance (the plant's first status, when the
        // recorder starts first): not for it, and not a refusal of anything of the run's
        let early = match self.inbox.refused.early() {
            0 => String::new(),
            n => format!(" ({n} sent before the plant was found, not recorded)"),
        };
        if recorded {
            eprintln!(
                "crawler-recorder: {how} {out}: {}; {} metric blocks ({} of them clock blocks), {} stick episodes (whole run), {} rejected ({} invalid), {} refused at arrival{early}, {} dropped{viewer}",
                self.recorder.closing_note(),
                c.metric_blocks,
                c.clock_blocks,
                c.episodes,
                c.rejected,
                c.invalid,
                c.refused,
                c.dropped,
            );
        } else {
            let how = match ended {
                Ended::Interrupted => "interrupted",
                Ended::Finished => "run ended",
                Ended::Idle => "no message for the idle timeout",
            };
            eprintln!(
                "crawler-recorder: {how}; nothing recorded (no state arrived), {out} left as it was{viewer}"
            );
        }
        // Ctrl-C (SIGINT, SIGTERM) ends with 130 like every program of the project, after the
        // recording was closed properly
        Ok(match ended {
            Ended::Interrupted => Exit::Interrupted,
            Ended::Finished => Exit::Finished,
            Ended::Idle => Exit::Timeout,
        })
    }
}
