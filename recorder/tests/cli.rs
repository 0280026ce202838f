//! The `crawler-recorder` command line: every bad flag is refused before anything is opened, with
//! the flag, the value and what is allowed, and a non-zero exit.

use std::process::Command;

fn record(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_crawler-recorder"))
        .arg("record")
        .args(args)
        .output()
        .expect("run crawler-recorder");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bad_flags_name_the_flag_the_value_and_what_is_allowed() {
    let cases: [(&[&str], &str); 9] = [
        (&["--every", "0"], "invalid --every = 0: allowed"),
        (&["--lanes", "0"], "invalid --lanes = 0: allowed"),
        (
            &["--heatmap-rows", "0"],
            "invalid --heatmap-rows = 0: allowed",
        ),
        (&["--inbox", "0"], "invalid --inbox = 0: allowed"),
        (
            &["--idle-timeout=-1"],
            "invalid --idle-timeout = -1: allowed",
        ),
        (
            &["--idle-timeout=nan"],
            "invalid --idle-timeout = NaN: allowed",
        ),
        (&["--run-id", "a b"], "invalid run_id = \"a b\": allowed"),
        (
            &["--endpoint", "tcp/0.0.0.0:7447"],
            "invalid --endpoint = tcp/0.0.0.0:7447: allowed",
        ),
        (
            &["--zenoh-config", "/nonexistent/zenoh.json5"],
            "invalid --zenoh-config = /nonexistent/zenoh.json5: allowed",
        ),
    ];
    for (args, needle) in cases {
        let (code, err) = record(args);
        assert_eq!(code, Some(1), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn an_unusable_output_is_refused_before_anything_starts() {
    let dir = std::env::temp_dir().join(format!("bridge-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let d = dir.display().to_string();
    let cases: [(&str, String); 2] = [
        (
            "/nonexistent/dir/x.rrd",
            "invalid --out = /nonexistent/dir/x.rrd: allowed a file path in an existing, writable directory (no directory /nonexistent/dir)".into(),
        ),
        (&d, format!("invalid --out = {d}: allowed a file path in an existing, writable directory (it is a directory)")),
    ];
    for (out, needle) in cases {
        let (code, err) = record(&["--out", out, "--run-id", "cli-out"]);
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains(&needle), "{err}");
        assert!(!err.contains("recording"), "started anyway: {err}");
    }
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "left a file behind"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_viewer_flags_are_refused() {
    let cases: [(&[&str], &str); 3] = [
        (
            &["--connect", "localhost:9876"],
            "invalid --connect = localhost:9876: allowed the gRPC address of a Rerun viewer",
        ),
        (
            &["--spawn", "--connect", "rerun+http://192.0.2.1:9876/proxy"],
            "with --spawn: allowed a loopback address",
        ),
        (&["--viewer-exe", "/bin/true"], "--spawn"),
    ];
    for (args, needle) in cases {
        let (code, err) = record(args);
        assert!(matches!(code, Some(1) | Some(2)), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
