//! The documented two-host configuration (`docs/two-hosts/`, certificates from
//! `scripts/make-certs.sh`) with host A's address replaced by 127.0.0.1: the co-simulation runs
//! through it over mutual TLS; a session without a certificate of this run's CA cannot connect,
//! even holding the run's credential; and the access control really filters interfaces.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crawler_e2e::{bin, json, repo_root, simulate, Proc, Run};

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Runs the documented certificate command for run `id` into `dir` (relative to the run's
/// directory), for a plant at 127.0.0.1.
fn make_certs(run: &Run, dir: &str, id: &str) {
    let out = Command::new("bash")
        .arg(repo_root().join("scripts/make-certs.sh"))
        .args([dir, id, "127.0.0.1"])
        .current_dir(run.dir.path())
        .output()
        .expect("bash");
    assert!(
        out.status.success(),
        "make-certs.sh failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The documented file `name`, pointed at 127.0.0.1:`port`, with `edit` applied (saved as
/// `<tag>-<name>` in the run's directory).
fn config(
    run: &Run,
    (name, tag): (&str, &str),
    port: u16,
    edit: impl Fn(String) -> String,
) -> PathBuf {
    let text = std::fs::read_to_string(repo_root().join("docs/two-hosts").join(name)).unwrap();
    assert!(text.contains("tls/192.168.1.10:7447"), "{name}: {text}");
    let text = edit(text.replace("tls/192.168.1.10:7447", &format!("tls/127.0.0.1:{port}")));
    let path = run.path(&format!("{tag}-{name}"));
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
        "--credential".into(),
        "certs/lab/credential".into(),
    ]);
    Proc::spawn(exe, &bin(exe), &a, run.dir.path())
}

#[test]
fn documented_two_host_configuration_runs_a_cosimulation_over_mutual_tls() {
    let run = Run::new("twohost");
    make_certs(&run, "certs/lab", &run.id);
    let port = free_port();
    let plant_cfg = config(&run, ("plant.json5", "doc"), port, |t| t);
    let ctl_cfg = config(&run, ("controller.json5", "doc"), port, |t| t);
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
    assert_eq!(
        json(&p.stdout)["state_digest"],
        simulate(&["--t-end", "6"])["state_digest"]
    );
    // the run's messages were sealed with the credential copied with the certificates
    assert!(p
        .stderr
        .contains("authenticated with the credential certs/lab/credential"));
}

#[test]
fn without_a_certificate_of_this_run_nobody_connects() {
    let run = Run::new("twohostcert");
    make_certs(&run, "certs/lab", &run.id);
    make_certs(&run, "certs/other", "other-run");
    let port = free_port();
    let plant_cfg = config(&run, ("plant.json5", "doc"), port, |t| t);
    // no client certificate at all (TLS without mTLS), trusting this run's CA
    let no_cert = config(&run, ("controller.json5", "no-cert"), port, |t| {
        let t2 = t
            .replace(r#"connect_certificate: "certs/lab/client.pem","#, "")
            .replace(r#"connect_private_key: "certs/lab/client.key","#, "")
            .replace("enable_mtls: true", "enable_mtls: false");
        assert_ne!(t2, t);
        t2
    });
    // the certificate of another run (its own CA), trusting this run's CA for the plant
    let other_cert = config(&run, ("controller.json5", "other-cert"), port, |t| {
        let t2 = t
            .replace("certs/lab/client.pem", "certs/other/client.pem")
            .replace("certs/lab/client.key", "certs/other/client.key");
        assert_ne!(t2, t);
        t2
    });
    let ckpt = run.path("p.ckpt").display().to_string();
    let plant = spawn(
        &run,
        "crawler-plant",
        &[
            "run",
            "--t-end",
            "6",
            "--wait-timeout",
            "5",
            "--checkpoint",
            &ckpt,
        ],
        &plant_cfg,
    );
    let timeout = ["run", "--policy", "wave", "--wait-timeout", "5"];
    let a = spawn(&run, "crawler-controller", &timeout, &no_cert);
    let b = spawn(&run, "crawler-controller", &timeout, &other_cert);
    let p = plant.wait(Duration::from_secs(30));
    let (a, b) = (
        a.wait(Duration::from_secs(30)),
        b.wait(Duration::from_secs(30)),
    );
    assert_eq!(p.status.code(), Some(4), "plant: {}", p.stderr);
    assert!(
        p.stderr.contains("no controller joined"),
        "plant: {}",
        p.stderr
    );
    for (what, c) in [("no certificate", a), ("another run's certificate", b)] {
        assert_eq!(c.status.code(), Some(4), "{what}: {}", c.stderr);
        assert!(
            c.stderr.contains("no plant answered"),
            "{what}: {}",
            c.stderr
        );
    }
}

#[test]
fn documented_access_control_filters_other_interfaces() {
    let run = Run::new("twohostacl");
    make_certs(&run, "certs/lab", &run.id);
    let port = free_port();
    // Allow only eth0: the controller comes through lo, so the plant must never see it.
    let plant_cfg = config(&run, ("plant.json5", "doc"), port, |t| {
        let t2 = t.replace(r#"interfaces: ["eth0", "lo"]"#, r#"interfaces: ["eth0"]"#);
        assert_ne!(t2, t, "the documented subject lists eth0 and lo");
        t2
    });
    let ctl_cfg = config(&run, ("controller.json5", "doc"), port, |t| t);
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
