//! The `crawler-controller` program as a user meets it: output into a pipe that closes early,
//! and errors that name the flag at fault.

use std::io::Read;
use std::process::{Command, Stdio};

fn controller() -> Command {
    Command::new(env!("CARGO_BIN_EXE_crawler-controller"))
}

#[test]
fn output_into_a_pipe_that_closes_early_ends_quietly() {
    // `crawler-controller optimize --json | head -c 100`: the report (megabytes with the whole
    // grid) meets a closed pipe after the first bytes.
    let mut child = controller()
        .args(["optimize", "--json", "--no-refine"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut head = [0u8; 100];
    stdout.read_exact(&mut head).unwrap();
    assert!(
        head.starts_with(b"{\""),
        "{}",
        String::from_utf8_lossy(&head)
    );
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    assert!(stderr.is_empty(), "{stderr}");
}

#[test]
fn a_bad_flag_is_named_as_the_flag_and_the_key_it_sets() {
    for (args, expect) in [
        (
            vec!["predict", "--eps", "nan"],
            "invalid --eps (friction.eps) = NaN",
        ),
        (
            vec!["optimize", "--n-f", "1.5"],
            "invalid --n-f (friction.n_f) = 1.5",
        ),
        (
            vec![
                "figures",
                "--alpha",
                "-2",
                "--out",
                "/nonexistent/never-written",
            ],
            "invalid --alpha (actuation.alpha) = -2",
        ),
        (
            vec!["optimize", "--energy", "-1"],
            "invalid --energy (task.energy) = -1",
        ),
        (
            vec!["optimize", "--k-range", "0,10"],
            "invalid --k-range (limits.k[0]) = 0",
        ),
        (
            vec!["optimize", "--omega-range", "5"],
            "invalid --omega-range = 5: allowed MIN,MAX (two numbers)",
        ),
        (
            vec!["optimize", "--tie-tolerance", "0.5"],
            "invalid --tie-tolerance = 0.5: allowed a relative speed tolerance in [0, 0.1]",
        ),
    ] {
        let out = controller().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        // and what would have been allowed
        assert!(stderr.contains(": allowed "), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
    }
}
