//! The documented two-host configuration (`docs/two-hosts/`) works, with host A's address
//! replaced by 127.0.0.1: the co-simulation runs through it, and its access control really
//! filters (without the interface the peers come through, no controller can join).

use std::path::{Path, PathBuf};
use std::time::Duration;

use crawler_e2e::{bin, repo_root, Proc, Run};

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The documented file `name`, pointed at 127.0.0.1:`port`, with `edit` applied.
fn config(run: &Run, name: &str, port: u16, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(repo_root().join("docs/two-hosts").join(name)).unwrap();
    assert!(text.contains("tcp/192.168.1.10:7447"), "{name}: {text}");
    let text = edit(text.replace("tcp/192.168.1.10:7447", &format!("tcp/127.0.0.1:{port}")));
    let path = run.path(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn spawn(run: &Run, exe: &str, args: &[&str], cfg: &Path) -> Proc {
    let mut a: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    a.extend([
        "--run-id".into(),
        run.id.clone(),
        "--zenoh-config".into(),
        cfg.display().to_string(),
    ]);
    Proc::spawn(exe, &bin(exe), &a, run.dir.path())
}

#[test]
fn documented_two_host_configuration_runs_a_cosimulation() {
    let run = Run::new("twohost");
    let port = free_port();
    let plant_cfg = config(&run, "plant.json5", port, |t| t);
    let ctl_cfg = config(&run, "controller.json5", port, |t| t);
    let ckpt = run.path("p.ckpt").display().to_string();
    let plant = spawn(
        &run,
        "crawler-plant",
        &["run", "--t-end", "6", "--json", "--checkpoint", &ckpt],
        &plant_cfg,
    );
    let ctl = spawn(
        &run,
        "crawler-controller",
        &["run", "--policy", "wave"],
        &ctl_cfg,
    );
    let p = plant.wait(Duration::from_secs(120));
    let c = ctl.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    let report: serde_json::Value = serde_json::from_str(&p.stdout).unwrap();
    assert_eq!(report["steps"].as_u64().map(|s| s > 0), Some(true));
}

#[test]
fn documented_access_control_filters_other_interfaces() {
    let run = Run::new("twohostacl");
    let port = free_port();
    // Allow only eth0: the controller comes through lo, so the plant must never see it.
    let plant_cfg = config(&run, "plant.json5", port, |t| {
        let t2 = t.replace(r#"interfaces: ["eth0", "lo"]"#, r#"interfaces: ["eth0"]"#);
        assert_ne!(t2, t, "the documented subject lists eth0 and lo");
        t2
    });
    let ctl_cfg = config(&run, "controller.json5", port, |t| t);
    let ckpt = run.path("p.ckpt").display().to_string();
    let plant = spawn(
        &run,
        "crawler-plant",
        &[
            "run",
            "--t-end",
            "6",
            "--wait-timeout",
            "3",
            "--checkpoint",
            &ckpt,
        ],
        &plant_cfg,
    );
    let ctl = spawn(
        &run,
        "crawler-controller",
        &["run", "--policy", "wave", "--wait-timeout", "3"],
        &ctl_cfg,
    );
    let p = plant.wait(Duration::from_secs(30));
    let c = ctl.wait(Duration::from_secs(30));
    assert_eq!(p.status.code(), Some(4), "plant: {}", p.stderr);
    assert!(
        p.stderr.contains("no controller joined"),
        "plant: {}",
        p.stderr
    );
    assert!(!c.status.success(), "controller: {}", c.stderr);
}
