//! A recorder that records nothing (no plant, or stopped before the first state) leaves an
//! existing `--out` byte for byte as it was and no temporary file behind; a `--connect` viewer
//! that is not there never holds the recorder up.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A scratch directory of its own, removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Self {
        let d = std::env::temp_dir().join(format!("bridge-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Self(d)
    }
    /// Names of the files in it, sockets excluded.
    fn files(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| !n.ends_with(".sock") && !n.ends_with(".err"))
            .collect();
        v.sort();
        v
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The bridge on a run nobody else joins (its own unix socket), stderr to a file.
fn bridge(dir: &Path, tag: &str, out: &Path, extra: &[&str]) -> (Child, PathBuf) {
    let err = dir.join(format!("{tag}.err"));
    let child = Command::new(env!("CARGO_BIN_EXE_crawler-recorder"))
        .args([
            "record",
            "--run-id",
            &format!("{tag}-{}", std::process::id()),
        ])
        .args([
            "--endpoint",
            &format!("unixsock-stream/{}/z.sock", dir.display()),
        ])
        .arg("--out")
        .arg(out)
        // the file's life, not the run's authentication, is tested here
        .arg("--no-auth")
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .expect("start crawler-recorder");
    (child, err)
}

/// Waits (bounded) for the child to end; kills it and panics if it does not.
fn wait(mut child: Child, err: &Path, timeout: Duration) -> (Option<i32>, String) {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return (s.code(), std::fs::read_to_string(err).unwrap_or_default());
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "crawler-recorder did not end within {timeout:?}: {}",
                std::fs::read_to_string(err).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn wait_for(err: &Path, needle: &str, timeout: Duration) {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if std::fs::read_to_string(err)
            .unwrap_or_default()
            .contains(needle)
        {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    panic!(
        "never printed {needle:?}: {}",
        std::fs::read_to_string(err).unwrap_or_default()
    );
}

const PRECIOUS: &[u8] = b"an earlier recording that must survive";

#[test]
fn a_run_without_data_leaves_an_existing_recording_untouched() {
    let s = Scratch::new("idle");
    let out = s.0.join("keep.rrd");
    std::fs::write(&out, PRECIOUS).unwrap();
    let (child, err) = bridge(&s.0, "idle", &out, &["--idle-timeout", "1"]);
    let (code, stderr) = wait(child, &err, Duration::from_secs(30));
    assert_eq!(code, Some(4), "{stderr}");
    assert!(stderr.contains("nothing recorded"), "{stderr}");
    assert_eq!(std::fs::read(&out).unwrap(), PRECIOUS, "{stderr}");
    assert_eq!(s.files(), ["keep.rrd"], "temporary file left behind");
}

#[test]
fn ctrl_c_before_any_state_leaves_an_existing_recording_untouched() {
    let s = Scratch::new("intr");
    let out = s.0.join("keep.rrd");
    std::fs::write(&out, PRECIOUS).unwrap();
    let (child, err) = bridge(&s.0, "intr", &out, &[]);
    wait_for(&err, "crawler-recorder: recording", Duration::from_secs(30));
    // the temporary recording exists next to --out while the recorder waits
    assert_eq!(s.files().len(), 2, "{:?}", s.files());
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let (_, stderr) = wait(child, &err, Duration::from_secs(30));
    assert!(
        stderr.contains("interrupted; nothing recorded (no state arrived)"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), PRECIOUS, "{stderr}");
    assert_eq!(s.files(), ["keep.rrd"], "temporary file left behind");
}

#[test]
fn a_missing_viewer_is_reported_and_does_not_hold_the_recorder_up() {
    let s = Scratch::new("noviewer");
    // a loopback port nobody listens on
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("rerun+http://127.0.0.1:{port}/proxy");
    let out = s.0.join("x.rrd");
    let (child, err) = bridge(
        &s.0,
        "noviewer",
        &out,
        &["--connect", &url, "--idle-timeout", "5"],
    );
    // bounded: an absent viewer must not hold the end of the recording up
    let (code, stderr) = wait(child, &err, Duration::from_secs(30));
    assert_eq!(code, Some(4), "{stderr}");
    assert!(
        stderr.contains(&format!("warning: no Rerun viewer answers at {url}")),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!("no viewer answered at {url}")),
        "{stderr}"
    );
}
