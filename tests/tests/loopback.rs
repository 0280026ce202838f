//! By default every process listens only on loopback: checked in the OS socket table.

use std::collections::HashSet;
use std::time::Duration;

use crawler_e2e::Run;

/// Socket inodes held by process `pid`.
fn socket_inodes(pid: u32) -> HashSet<u64> {
    let mut out = HashSet::new();
    for entry in std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .flatten()
    {
        if let Ok(target) = std::fs::read_link(entry.path()) {
            let t = target.to_string_lossy();
            if let Some(inode) = t.strip_prefix("socket:[").and_then(|s| s.strip_suffix(']')) {
                out.insert(inode.parse().unwrap());
            }
        }
    }
    out
}

/// (local address hex, state hex, inode) of every entry of /proc/net/<table>.
fn table(name: &str) -> Vec<(String, String, u64)> {
    let text = std::fs::read_to_string(format!("/proc/net/{name}")).unwrap_or_default();
    text.lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            Some((
                f.get(1)?.to_string(),
                f.get(3)?.to_string(),
                f.get(9)?.parse().ok()?,
            ))
        })
        .collect()
}

fn is_loopback(addr: &str) -> bool {
    let ip = addr.split(':').next().unwrap();
    match ip.len() {
        8 => ip.ends_with("7F"), // 127.x.x.x, little-endian hex
        32 => {
            ip == "00000000000000000000000001000000"
                || ip.starts_with("0000000000000000FFFF0000") && ip.ends_with("7F")
        }
        _ => false,
    }
}

#[test]
fn every_process_listens_on_loopback_only_and_opens_no_udp_socket() {
    let run = Run::new("lo");
    // TCP endpoint for the plant, so that TCP listeners exist for every process
    let tcp_port = 20000 + (std::process::id() % 20000) as u16;
    let endpoint = format!("tcp/127.0.0.1:{tcp_port}");
    let run = Run { endpoint, ..run };
    let rrd = run.path("lo.rrd");
    let plant = run.plant(&["--t-end", "30"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(&["--policy", "wave", "--alpha", "0.5"]);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let mut listeners = 0;
    for p in [&plant, &bridge, &controller] {
        let inodes = socket_inodes(p.pid());
        for t in ["tcp", "tcp6"] {
            for (addr, state, inode) in table(t) {
                if inodes.contains(&inode) && state == "0A" {
                    listeners += 1;
                    assert!(
                        is_loopback(&addr),
                        "{} listens on a non-loopback address {addr} ({t})",
                        p.name
                    );
                }
            }
        }
        for t in ["udp", "udp6"] {
            for (addr, _, inode) in table(t) {
                assert!(
                    !inodes.contains(&inode),
                    "{} has a UDP socket on {addr} (multicast scouting must be off)",
                    p.name
                );
            }
        }
    }
    assert!(listeners >= 1, "no listening socket found at all");
}
