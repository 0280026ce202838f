//! # crawler-transport
//!
//! Opens the zenoh sessions of the soft-crawler processes. By default every process is
//! loopback-only: the plant listens on a unix socket or on `127.0.0.1`, multicast scouting is off
//! and endpoints are explicit, so nothing on the LAN can see or inject into a run. A zenoh JSON5
//! configuration file (`--zenoh-config`) replaces these defaults, for runs across hosts with
//! mutual TLS (`docs/two-hosts/`).
//!
//! Topology of a run: the plant's session is a zenoh router listening on the run's *rendezvous
//! endpoint* (by default a unix socket in the run's private directory, [`runtime_dir`]); the
//! controller and the bridge are zenoh clients of it: they connect, retrying until it appears (so
//! any process may start first, [`open_in_background`]), listen nowhere, and everything between
//! them goes through the plant's router.
//!
//! Authentication (`docs/security.md`): the run's [`credential`] gives a zenoh password (the
//! plant admits only sessions that know it) and a message key (every message carries an
//! envelope, its run instance, sender and sequence number, and a [`seal`] over it); a process
//! sends and receives through its [`participant`], whose [`gate`] checks each arriving payload
//! (size, seal, run instance, sender, exactly once) before anything is queued, and [`budget`]
//! bounds every inbox in bytes.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};
use clap::Args;
use crawler_protocol::{validate_run_id, Role};

pub mod budget;
pub mod credential;
pub mod gate;
pub mod participant;
pub mod reassembly;
pub mod runtime_dir;
pub mod seal;

pub use crawler_protocol::{ProcessId, RunNonce};
pub use credential::Credential;
pub use participant::Participant;
pub use seal::Seal;

/// Network flags shared by every binary.
#[derive(Args, Debug, Clone)]
pub struct NetworkArgs {
    /// Run id: the runs on one network are separated by it (1-64 of A-Z a-z 0-9 _ -).
    /// Default: `default`.
    #[arg(long)]
    pub run_id: Option<String>,
    /// Rendezvous endpoint of the run (the plant listens there), loopback only:
    /// `unixsock-stream/PATH`, `tcp/127.0.0.1:PORT` or `tcp/[::1]:PORT`.
    /// Default: `unixsock-stream/<runtime dir>/zenoh.sock` in the run's private directory.
    #[arg(long)]
    pub endpoint: Option<String>,
    /// A zenoh JSON5 configuration file replacing the loopback-only defaults (several hosts,
    /// TLS, access control). `--endpoint` is then ignored; the file decides how sessions
    /// authenticate, the run's credential still seals every message.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// The run's credential (mode 0600). The plant creates a fresh one when the file does not
    /// exist; the controller and the recorder wait for it and read it. Default:
    /// `<runtime dir>/credential`, the run's private directory (`$XDG_RUNTIME_DIR/crawler/<run>`
    /// or `<tmp>/crawler-<uid>/<run>`), which the plant fills and cleans up itself.
    #[arg(long, value_name = "FILE")]
    pub credential: Option<PathBuf>,
    /// Run without authentication: no credential, no zenoh password, no message seals. Any
    /// process of this machine that can reach the endpoint can then join, read and disturb the
    /// run. Every process of the run must be given the same choice.
    #[arg(long, conflicts_with = "credential")]
    pub no_auth: bool,
}

/// How the processes of a run authenticate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Auth {
    /// Not at all (`--no-auth`).
    Off,
    /// With the credential at this path.
    Credential {
        /// The credential file.
        path: PathBuf,
        /// True if it was named on the command line (`--credential`): the user owns it, the plant
        /// neither replaces nor removes it.
        explicit: bool,
    },
}

impl NetworkArgs {
    /// The validated network settings.
    pub fn network(&self) -> anyhow::Result<Network> {
        let run_id = self.run_id.clone().unwrap_or_else(|| "default".to_string());
        validate_run_id(&run_id)?;
        let endpoint = match &self.endpoint {
            Some(e) => {
                check_loopback(e)?;
                e.clone()
            }
            None => default_endpoint(&run_id),
        };
        if let Some(path) = &self.zenoh_config {
            if !path.is_file() {
                bail!("invalid --zenoh-config = {}: allowed an existing zenoh JSON5 configuration file", path.display());
            }
        }
        let auth = match (&self.credential, self.no_auth) {
            (_, true) => Auth::Off,
            (Some(path), false) => {
                if path.is_dir() {
                    bail!(
                        "invalid --credential = {}: allowed a credential file (it is a directory)",
                        path.display()
                    );
                }
                Auth::Credential {
                    path: path.clone(),
                    explicit: true,
                }
            }
            (None, false) => Auth::Credential {
                path: runtime_dir::run_dir(&run_id).join("credential"),
                explicit: false,
            },
        };
        Ok(Network {
            run_id,
            endpoint,
            config_file: self.zenoh_config.clone(),
            auth,
        })
    }
}

/// Where a run's processes meet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Network {
    /// Run id.
    pub run_id: String,
    /// Rendezvous endpoint (the plant listens there).
    pub endpoint: String,
    /// A zenoh configuration file replacing the defaults.
    pub config_file: Option<PathBuf>,
    /// How the run authenticates.
    pub auth: Auth,
}

impl Network {
    /// Loopback defaults for `run_id` at `endpoint` (validated), without authentication.
    pub fn loopback(run_id: &str, endpoint: &str) -> anyhow::Result<Self> {
        validate_run_id(run_id)?;
        check_loopback(endpoint)?;
        Ok(Self {
            run_id: run_id.to_string(),
            endpoint: endpoint.to_string(),
            config_file: None,
            auth: Auth::Off,
        })
    }

    /// The same network authenticated with the credential at `path`.
    pub fn with_credential(self, path: &Path) -> Self {
        Self {
            auth: Auth::Credential {
                path: path.to_path_buf(),
                explicit: true,
            },
            ..self
        }
    }

    /// Human-readable description for "waiting for ..." messages.
    pub fn describe(&self) -> String {
        match &self.config_file {
            Some(f) => format!("run {} (zenoh config {})", self.run_id, f.display()),
            None => format!("run {} at {}", self.run_id, self.endpoint),
        }
    }

    /// Reads the run's credential, waiting up to `timeout` for it to appear (the plant creates
    /// it); `Ok(None)` for an unauthenticated run. Says once what it waits for.
    pub fn wait_for_credential(
        &self,
        who: &str,
        timeout: std::time::Duration,
        interrupted: &dyn Fn() -> bool,
    ) -> anyhow::Result<Option<Credential>> {
        let Auth::Credential { path, .. } = &self.auth else {
            return Ok(None);
        };
        let deadline = std::time::Instant::now() + timeout;
        let mut said = false;
        loop {
            match std::fs::symlink_metadata(path) {
                Ok(_) => return Credential::load(path, &self.run_id).map(Some),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => {
                    return Err(e)
                        .with_context(|| format!("cannot read the credential {}", path.display()))
                }
            }
            if !said {
                eprintln!(
                    "{who}: waiting for the run's credential {} (the plant creates it; or pass \
                     --credential FILE, or --no-auth on every process)",
                    path.display()
                );
                said = true;
            }
            if interrupted() {
                bail!(
                    "interrupted while waiting for the credential {}",
                    path.display()
                );
            }
            if std::time::Instant::now() >= deadline {
                bail!(
                    "no credential {} within {:.0} s: is the plant of run {} running as this user?",
                    path.display(),
                    timeout.as_secs_f64(),
                    self.run_id
                );
            }
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    }
}

/// The default rendezvous endpoint of a run: a unix socket in the run's private directory.
pub fn default_endpoint(run_id: &str) -> String {
    let path = runtime_dir::run_dir(run_id).join("zenoh.sock");
    format!("unixsock-stream/{}", path.display())
}

/// Accepts only endpoints that cannot be reached from another host.
pub fn check_loopback(endpoint: &str) -> anyhow::Result<()> {
    let allowed = "unixsock-stream/PATH, tcp/127.0.0.1:PORT, tcp/localhost:PORT or tcp/[::1]:PORT \
                   (use --zenoh-config for anything else)";
    let bad = || anyhow::anyhow!("invalid --endpoint = {endpoint}: allowed {allowed}");
    if let Some(path) = endpoint.strip_prefix("unixsock-stream/") {
        if path.is_empty() || path.len() > 100 || path.contains('#') || path.contains('?') {
            return Err(bad());
        }
        return Ok(());
    }
    let Some(addr) = endpoint.strip_prefix("tcp/") else {
        return Err(bad());
    };
    let (host, port) = addr.rsplit_once(':').ok_or_else(bad)?;
    port.parse::<u16>().map_err(|_| bad())?;
    let host = host.trim_start_matches('[').trim_end_matches(']');
    let loopback = host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .map(|ip| ip.is_loopback())
            .unwrap_or(false);
    if loopback {
        Ok(())
    } else {
        Err(bad())
    }
}

/// What a session presents to, or checks of, the sessions it links with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Access {
    /// Nothing: an unauthenticated run.
    Open,
    /// The run's transport password, presented when connecting (controller, recorder).
    Password(String),
    /// zenoh's user file: connecting sessions must prove they know a password in it (the plant).
    Users(PathBuf),
}

/// Most sessions the plant's router keeps at once (the controller, the recorder, a few more).
pub const MAX_SESSIONS: usize = 16;

/// Slack over the largest legal payload for zenoh's own headers and the seal, bytes.
const ZENOH_SLACK: usize = 4096;

/// The zenoh configuration (JSON) of `role` in `network` when no configuration file is given:
/// loopback only, the access of `access`, and messages reassembled up to `max_message` bytes of
/// payload.
pub fn loopback_config_json(
    role: Role,
    network: &Network,
    access: &Access,
    max_message: usize,
) -> String {
    let (listen, connect) = match role {
        Role::Plant => (vec![network.endpoint.clone()], vec![]),
        // Others dial the plant (retrying until it exists) and listen nowhere: the plant's
        // router forwards between them, and nothing can dial them.
        Role::Controller | Role::Bridge => (vec![], vec![network.endpoint.clone()]),
    };
    // The plant's session is the run's router, the others are its clients: a router relays
    // between its clients (it would not between peers, which are meant to link directly).
    let mode = if role == Role::Plant {
        "router"
    } else {
        "client"
    };
    config_json(mode, (listen, connect), access, max_message)
}

/// A peer that dials the run's endpoint in the background and listens nowhere: what tools and
/// tests use to watch or probe a run without waiting for it (the programs use
/// [`loopback_config_json`]).
pub fn probe_config_json(network: &Network, access: &Access, max_message: usize) -> String {
    config_json(
        "peer",
        (vec![], vec![network.endpoint.clone()]),
        access,
        max_message,
    )
}

fn config_json(
    mode: &str,
    (listen, connect): (Vec<String>, Vec<String>),
    access: &Access,
    max_message: usize,
) -> String {
    let usrpwd = match access {
        Access::Open => serde_json::json!({}),
        Access::Password(p) => {
            serde_json::json!({ "user": credential::ZENOH_USER, "password": p })
        }
        Access::Users(file) => serde_json::json!({ "dictionary_file": file.display().to_string() }),
    };
    serde_json::json!({
        "mode": mode,
        "listen": { "endpoints": listen, "exit_on_failure": true },
        "connect": {
            "endpoints": connect,
            "exit_on_failure": false,
            "timeout_ms": -1,
            "retry": { "period_init_ms": 100, "period_max_ms": 500, "period_increase_factor": 1.5 }
        },
        "scouting": {
            "multicast": { "enabled": false },
            "gossip": { "enabled": false }
        },
        "timestamping": { "enabled": false },
        "adminspace": { "enabled": false },
        "transport": {
            "unicast": {
                "max_sessions": MAX_SESSIONS,
                "accept_pending": MAX_SESSIONS,
                "accept_timeout": 5000,
                // one priority: at most one message per reliability is being reassembled per link
                "qos": { "enabled": false }
            },
            "link": { "rx": { "max_message_size": max_message + ZENOH_SLACK } },
            "auth": { "usrpwd": usrpwd }
        }
    })
    .to_string()
}

/// The zenoh configuration of `role`: the loopback defaults, or the user's file; either way
/// zenoh reassembles no message larger than `max_message` bytes of payload.
pub fn config(
    role: Role,
    network: &Network,
    access: &Access,
    max_message: usize,
) -> anyhow::Result<zenoh::Config> {
    // what zenoh drops for being larger than that is counted from here on
    reassembly::count();
    match &network.config_file {
        Some(path) => {
            let mut cfg = load_config_file(path)?;
            cfg.insert_json5(
                "transport/link/rx/max_message_size",
                &(max_message + ZENOH_SLACK).to_string(),
            )
            .map_err(|e| {
                anyhow::anyhow!("cannot limit the message size of {}: {e}", path.display())
            })?;
            Ok(cfg)
        }
        None => {
            zenoh::Config::from_json5(&loopback_config_json(role, network, access, max_message))
                .map_err(|e| anyhow::anyhow!("internal zenoh configuration rejected: {e}"))
        }
    }
}

fn load_config_file(path: &Path) -> anyhow::Result<zenoh::Config> {
    zenoh::Config::from_file(path)
        .map_err(|e| anyhow::anyhow!("invalid --zenoh-config = {}: {e}", path.display()))
}

/// A session being opened on another thread: a client's open returns only once it reached the
/// plant (or never, if the plant never admits it), so the caller waits on this instead, and can
/// give up, say what it waits for, or start over with another credential meanwhile.
pub struct Opening {
    rx: std::sync::mpsc::Receiver<anyhow::Result<zenoh::Session>>,
}

impl Opening {
    /// The session, if it opened within `timeout` (an error if it cannot be opened).
    pub fn wait(&self, timeout: std::time::Duration) -> Option<anyhow::Result<zenoh::Session>> {
        match self.rx.recv_timeout(timeout) {
            Ok(r) => Some(r),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => None,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => Some(Err(anyhow::anyhow!(
                "the thread opening the zenoh session ended"
            ))),
        }
    }
}

/// Opens a session for `role` like [`open`], on another thread (see [`Opening`]). The
/// configuration is checked before this returns.
pub fn open_in_background(
    role: Role,
    network: &Network,
    access: &Access,
    max_message: usize,
) -> anyhow::Result<Opening> {
    let cfg = config(role, network, access, max_message)?;
    let what = format!(
        "cannot open the zenoh session of the {} for {}",
        role.as_str(),
        network.describe()
    );
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("zenoh-open".into())
        .spawn(move || {
            use zenoh::Wait;
            let r = zenoh::open(cfg)
                .wait()
                .map_err(|e| anyhow::anyhow!("{e}").context(what));
            let _ = tx.send(r);
        })?;
    Ok(Opening { rx })
}

/// Opens the client session of `role` (controller or bridge) in `network`, presenting
/// `credential`'s password (none: unauthenticated), and waits until it reached the plant, asking
/// `give_up` about every 100 ms whether to stop waiting (then `Ok(None)`). If the credential file
/// changes meanwhile (a plant started after a stale credential was read), it starts over with
/// the new one. Returns the session and the credential it used.
pub fn connect_client(
    role: Role,
    network: &Network,
    credential: Option<Credential>,
    max_message: usize,
    give_up: &mut dyn FnMut() -> bool,
) -> anyhow::Result<Option<(zenoh::Session, Option<Credential>)>> {
    let access_of = |c: &Option<Credential>| match c {
        Some(c) => Access::Password(c.transport_password()),
        None => Access::Open,
    };
    let mut credential = credential;
    let mut opening = open_in_background(role, network, &access_of(&credential), max_message)?;
    let mut checked = std::time::Instant::now();
    loop {
        if let Some(session) = opening.wait(std::time::Duration::from_millis(100)) {
            return Ok(Some((session?, credential)));
        }
        if give_up() {
            return Ok(None);
        }
        if checked.elapsed() >= std::time::Duration::from_secs(1) {
            checked = std::time::Instant::now();
            if let Some(old) = &credential {
                if let Ok(new) = Credential::load(old.path(), &network.run_id) {
                    if new.transport_password() != old.transport_password() {
                        eprintln!(
                            "crawler-{}: the credential {} changed (a new plant); connecting with it",
                            role.as_str(),
                            old.path().display()
                        );
                        credential = Some(new);
                        // the earlier attempt keeps retrying with the old password, in vain,
                        // until the process exits
                        opening = open_in_background(
                            role,
                            network,
                            &access_of(&credential),
                            max_message,
                        )?;
                    }
                }
            }
        }
    }
}

/// Opens a session for `role` in `network` with `access`, reassembling messages of at most
/// `max_message` bytes. A client's open returns once it reached the plant; see
/// [`connect_client`].
pub fn open(
    role: Role,
    network: &Network,
    access: &Access,
    max_message: usize,
) -> anyhow::Result<zenoh::Session> {
    use zenoh::Wait;
    let cfg = config(role, network, access, max_message)?;
    zenoh::open(cfg)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| {
            format!(
                "cannot open the zenoh session of the {} for {}",
                role.as_str(),
                network.describe()
            )
        })
}

/// A random id for a process (16 lowercase hex digits), for its envelopes, liveliness key and
/// messages.
pub fn process_id() -> ProcessId {
    let mut b = [0u8; 8];
    if getrandom::fill(&mut b).is_err() {
        // no random source: the clock and the pid still make a collision very unlikely
        use std::collections::hash_map::RandomState;
        use std::hash::{BuildHasher, Hasher};
        let mut h = RandomState::new().build_hasher();
        h.write_u32(std::process::id());
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_nanos())
                .unwrap_or(0),
        );
        b = h.finish().to_le_bytes();
    }
    let hex: String = b.iter().map(|x| format!("{x:02x}")).collect();
    ProcessId::parse(&hex).expect("16 lowercase hex digits")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_loopback_endpoints_are_accepted() {
        for ok in [
            "unixsock-stream//tmp/x.sock",
            "tcp/127.0.0.1:7447",
            "tcp/localhost:1",
            "tcp/[::1]:7447",
        ] {
            assert!(check_loopback(ok).is_ok(), "{ok}");
        }
        for bad in [
            "tcp/0.0.0.0:7447",
            "tcp/192.168.1.2:7447",
            "udp/127.0.0.1:7447",
            "tcp/127.0.0.1",
            "tcp/[::]:1",
            "quic/x",
            "",
        ] {
            let e = check_loopback(bad).unwrap_err().to_string();
            assert!(
                e.contains("--endpoint") && e.contains("allowed"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn default_configs_are_loopback_only_without_multicast() {
        let net = Network::loopback("r1", "tcp/127.0.0.1:7447").unwrap();
        for role in [Role::Plant, Role::Controller, Role::Bridge] {
            let v: serde_json::Value =
                serde_json::from_str(&loopback_config_json(role, &net, &Access::Open, 1000))
                    .unwrap();
            assert_eq!(v["scouting"]["multicast"]["enabled"], false);
            let listen = v["listen"]["endpoints"].as_array().unwrap();
            for e in listen {
                check_loopback(e.as_str().unwrap()).unwrap();
            }
            // only the plant listens
            assert_eq!(listen.len(), usize::from(role == Role::Plant));
            assert_eq!(
                v["transport"]["link"]["rx"]["max_message_size"],
                1000 + ZENOH_SLACK
            );
            config(role, &net, &Access::Open, 1000).unwrap();
        }
        // authenticated: the plant checks a user file, the others present the password
        let users = PathBuf::from("/nonexistent/users");
        let v: serde_json::Value = serde_json::from_str(&loopback_config_json(
            Role::Plant,
            &net,
            &Access::Users(users),
            1000,
        ))
        .unwrap();
        assert_eq!(
            v["transport"]["auth"]["usrpwd"]["dictionary_file"],
            "/nonexistent/users"
        );
        let v: serde_json::Value = serde_json::from_str(&loopback_config_json(
            Role::Controller,
            &net,
            &Access::Password("pw".into()),
            1000,
        ))
        .unwrap();
        assert_eq!(v["transport"]["auth"]["usrpwd"]["user"], "crawler");
        assert_eq!(v["transport"]["auth"]["usrpwd"]["password"], "pw");
    }
}
