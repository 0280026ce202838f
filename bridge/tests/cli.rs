//! The `crawler-bridge` command line: every bad flag is refused before anything is opened, with
//! the flag, the value and what is allowed, and a non-zero exit.

use std::process::Command;

fn record(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_crawler-bridge"))
        .arg("record")
        .args(args)
        .output()
        .expect("run crawler-bridge");
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
fn an_unwritable_output_is_refused() {
    let (code, err) = record(&["--out", "/nonexistent/dir/x.rrd", "--run-id", "cli-out"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("cannot write recording /nonexistent/dir/x.rrd"),
        "{err}"
    );
}
