//! # crawler-transport
//!
//! Opens the zenoh sessions of the soft-crawler processes. By default every process is
//! loopback-only: it listens on a unix socket or on `127.0.0.1`, multicast scouting is off and
//! endpoints are explicit, so nothing on the LAN can see or inject into a run. A zenoh JSON5
//! configuration file (`--zenoh-config`) replaces these defaults entirely, for runs across hosts,
//! TLS or access control.
//!
//! Topology of a run: the plant listens on the run's *rendezvous endpoint* (by default a unix
//! socket named after the run id); the controller and the bridge connect to it, retrying until it
//! appears (so any process may start first), and each listens on an ephemeral `127.0.0.1` port so
//! that gossip lets them reach each other directly.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};
use clap::Args;
use crawler_protocol::{validate_run_id, Role};

/// Network flags shared by every binary.
#[derive(Args, Debug, Clone)]
pub struct NetworkArgs {
    /// Run id: the runs on one network are separated by it (1-64 of A-Z a-z 0-9 _ -).
    /// Default: `default`.
    #[arg(long)]
    pub run_id: Option<String>,
    /// Rendezvous endpoint of the run (the plant listens there), loopback only:
    /// `unixsock-stream/PATH`, `tcp/127.0.0.1:PORT` or `tcp/[::1]:PORT`.
    /// Default: `unixsock-stream/<tmp>/crawler-<run-id>.sock`.
    #[arg(long)]
    pub endpoint: Option<String>,
    /// A zenoh JSON5 configuration file replacing the loopback-only defaults (several hosts,
    /// TLS, access control). `--endpoint` is then ignored.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
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
        Ok(Network {
            run_id,
            endpoint,
            config_file: self.zenoh_config.clone(),
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
}

impl Network {
    /// Loopback defaults for `run_id` at `endpoint` (validated).
    pub fn loopback(run_id: &str, endpoint: &str) -> anyhow::Result<Self> {
        validate_run_id(run_id)?;
        check_loopback(endpoint)?;
        Ok(Self {
            run_id: run_id.to_string(),
            endpoint: endpoint.to_string(),
            config_file: None,
        })
    }

    /// Human-readable description for "waiting for ..." messages.
    pub fn describe(&self) -> String {
        match &self.config_file {
            Some(f) => format!("run {} (zenoh config {})", self.run_id, f.display()),
            None => format!("run {} at {}", self.run_id, self.endpoint),
        }
    }
}

/// The default rendezvous endpoint of a run: a unix socket in the temporary directory.
pub fn default_endpoint(run_id: &str) -> String {
    let path = std::env::temp_dir().join(format!("crawler-{run_id}.sock"));
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

/// The zenoh configuration (JSON) of `role` in `network` when no configuration file is given.
pub fn loopback_config_json(role: Role, network: &Network) -> String {
    let (listen, connect) = match role {
        Role::Plant => (vec![network.endpoint.clone()], vec![]),
        // Others dial the plant (retrying until it exists) and listen on an ephemeral loopback
        // port, so that gossip lets them reach each other.
        Role::Controller | Role::Bridge => (
            vec!["tcp/127.0.0.1:0".to_string()],
            vec![network.endpoint.clone()],
        ),
    };
    // The plant's session is the run's router: it forwards between the controller and the
    // recorder, so they need no direct link to each other.
    let mode = if role == Role::Plant {
        "router"
    } else {
        "peer"
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
            "gossip": { "enabled": true, "multihop": false }
        },
        "timestamping": { "enabled": false },
        "adminspace": { "enabled": false }
    })
    .to_string()
}

/// The zenoh configuration of `role`: the loopback defaults, or the user's file.
pub fn config(role: Role, network: &Network) -> anyhow::Result<zenoh::Config> {
    match &network.config_file {
        Some(path) => load_config_file(path),
        None => zenoh::Config::from_json5(&loopback_config_json(role, network))
            .map_err(|e| anyhow::anyhow!("internal zenoh configuration rejected: {e}")),
    }
}

fn load_config_file(path: &Path) -> anyhow::Result<zenoh::Config> {
    zenoh::Config::from_file(path)
        .map_err(|e| anyhow::anyhow!("invalid --zenoh-config = {}: {e}", path.display()))
}

/// Opens a session for `role` in `network`.
pub fn open(role: Role, network: &Network) -> anyhow::Result<zenoh::Session> {
    use zenoh::Wait;
    let cfg = config(role, network)?;
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

/// A short random id for a process (16 hex digits), for liveliness keys and messages.
pub fn process_id() -> String {
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
    format!("{:016x}", h.finish())
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
                serde_json::from_str(&loopback_config_json(role, &net)).unwrap();
            assert_eq!(v["scouting"]["multicast"]["enabled"], false);
            for e in v["listen"]["endpoints"].as_array().unwrap() {
                check_loopback(e.as_str().unwrap()).unwrap();
            }
            config(role, &net).unwrap();
        }
    }
}
