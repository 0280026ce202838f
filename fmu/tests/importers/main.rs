//! The packaged FMUs in importers and validators we did not write: FMPy (validate, simulate,
//! state round trip, two instances), fmu-manipulation-toolbox's `fmutool -check`, ecos; libcosim
//! on its nanosecond clock (the parameter `ticks_per_second`, [`libcosim`]); the plant and a
//! controller FMU wired by an SSP file in ecos and libcosim ([`ssp`]).
//!
//! The FMUs are built and packaged once per test process by `scripts/build-fmu.sh` (`cargo test`
//! builds the library only as an rlib, so the script's `cargo build --release -p crawler-fmu`
//! links the shared library; it reuses what the test build compiled); the Python packages come
//! from the project's venv, which `scripts/setup.sh` installs before the tests (`crawler_e2e::python()`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use serde_json::Value;

mod libcosim;
mod ssp;

/// Directory holding `crawler_physics.fmu` and `crawler_plant_fmi3.fmu`.
fn fmus() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let bin = PathBuf::from(env!("CARGO_BIN_EXE_crawler-fmu"));
        let profile_dir = bin.parent().unwrap().to_path_buf();
        let release = profile_dir.file_name().and_then(|p| p.to_str()) == Some("release");
        assert!(
            release,
            "run the FMU tests with --release (the script builds release)"
        );
        let out = Command::new("bash")
            .arg(crawler_e2e::repo_root().join("scripts/build-fmu.sh"))
            .arg(dir.path())
            .env("CARGO_TARGET_DIR", profile_dir.parent().unwrap())
            .output()
            .expect("run scripts/build-fmu.sh");
        assert!(
            out.status.success(),
            "build-fmu.sh failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let path = dir.path().to_path_buf();
        (dir, path)
    })
    .1
}

/// The target directory the tests' FMUs were built in (the one `scripts/build-fmu.sh` uses).
fn target_dir() -> PathBuf {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_crawler-fmu"));
    bin.parent().unwrap().parent().unwrap().to_path_buf()
}

/// Runs `scripts/build-fmu.sh` with `args` and `CARGO_TARGET_DIR=target`: exit code and
/// standard error.
fn build_fmu(args: &[&str], target: &Path) -> (i32, String) {
    let out = Command::new("bash")
        .arg(crawler_e2e::repo_root().join("scripts/build-fmu.sh"))
        .args(args)
        .env("CARGO_TARGET_DIR", target)
        .output()
        .expect("run scripts/build-fmu.sh");
    (
        out.status.code().unwrap_or(-1),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

fn fmu(version: u8) -> PathBuf {
    fmus().join(if version == 2 {
        "crawler_physics.fmu"
    } else {
        "crawler_plant_fmi3.fmu"
    })
}

/// Runs the importers script with `args`; its JSON answer.
fn importers(args: &[&str]) -> Value {
    let script = crawler_e2e::repo_root().join("fmu/tests/python/importers.py");
    let out = Command::new(crawler_e2e::python())
        .arg(script)
        .args(args)
        .output()
        .expect("run importers.py");
    assert!(
        out.status.success(),
        "importers.py {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "importers.py {args:?} printed no JSON ({e}):\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

fn bits(v: &Value) -> u64 {
    v.as_f64().expect("a number").to_bits()
}

#[test]
fn fmpy_validate_finds_no_problem_in_either_fmu() {
    for version in [2, 3] {
        let answer = importers(&["validate", path_str(&fmu(version))]);
        let problems = answer["problems"].as_array().unwrap();
        assert!(
            problems.is_empty(),
            "FMI {version}: fmpy validate found {} problems: {problems:#?}",
            problems.len()
        );
    }
}

#[test]
fn fmutool_check_is_clean_for_either_fmu() {
    let fmutool = crawler_e2e::python().parent().unwrap().join("fmutool");
    for version in [2, 3] {
        let out = Command::new(&fmutool)
            .args(["-input", path_str(&fmu(version)), "-check"])
            .output()
            .expect("run fmutool");
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.status.success(),
            "FMI {version}: fmutool -check failed:\n{text}"
        );
        assert!(
            text.contains(&format!("compliant with FMI-{version}.0")),
            "FMI {version}: {text}"
        );
        assert!(
            text.contains(&format!(
                "No semantic error against the FMI-{version} standard"
            )),
            "FMI {version}: {text}"
        );
        assert!(!text.contains("ERROR"), "FMI {version}: {text}");
    }
}

/// `crawler-plant simulate --json` on the paper scenario (the FMU's defaults).
fn simulate_in_process() -> Value {
    let out = Command::new(crawler_e2e::bin("crawler-plant"))
        .args(["simulate", "--json"])
        .output()
        .expect("run crawler-plant simulate");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("simulate --json")
}

/// `crawler-plant simulate --json` on the scenario `text` (written to a temporary file).
fn simulate_scenario(text: &str) -> Value {
    simulate_scenario_with(text, &[])
}

/// `crawler-plant simulate --json` on the scenario `text` with the flags `args`.
fn simulate_scenario_with(text: &str, args: &[&str]) -> Value {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("scenario.toml");
    std::fs::write(&path, text).expect("write the scenario");
    let out = Command::new(crawler_e2e::bin("crawler-plant"))
        .args(["simulate", "--json", "--scenario", path_str(&path)])
        .args(args)
        .output()
        .expect("run crawler-plant simulate");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("simulate --json")
}

/// An importer's final state digest and outputs equal `crawler-plant simulate`'s report, bit
/// for bit (`who` names the importer in messages).
fn assert_same_as_simulate(who: &str, answer: &Value, reference: &Value) {
    let o = &answer["outputs"];
    assert_eq!(
        answer["digest"], reference["state_digest"],
        "{who}: final u and v differ from crawler-plant simulate"
    );
    for (output, field) in [
        ("velocity", "velocity"),
        ("power", "power"),
        ("mileage", "mileage"),
        ("max_stress", "max_stress"),
        ("max_strain", "max_strain"),
        ("stuck_fraction", "stuck_fraction"),
        ("mean_friction_selection", "mean_friction_selection"),
    ] {
        assert_eq!(
            bits(&o[output]),
            bits(&reference[field]),
            "{who}: {output} = {} in the importer, {} in crawler-plant simulate",
            o[output],
            reference[field]
        );
    }
    assert_eq!(
        bits(&o["steady_periods"]),
        bits(&reference["window"]["periods"]),
        "{who}"
    );
    assert_eq!(
        bits(&o["episode_rate"]),
        bits(&reference["events"]["per_node_per_period"]),
        "{who}"
    );
    assert!(
        reference["window"]["periods"].as_f64().unwrap() >= 1.0,
        "{who}: the run must reach its steady metrics for the comparison to mean something"
    );
}

#[test]
fn fmpy_simulate_matches_crawler_plant_simulate_bit_for_bit() {
    let reference = simulate_in_process();
    for version in [2, 3] {
        let fmpy = importers(&["simulate", path_str(&fmu(version))]);
        assert_eq!(
            fmpy["steps"], reference["macro_steps"],
            "FMI {version}: the default experiment is the run of simulate"
        );
        assert_same_as_simulate(&format!("FMPy, FMI {version}"), &fmpy, &reference);
        // FMPy's own time arithmetic (t = n h) ends where the plant's clock (n H) does
        let t_end = reference["t_end"].as_f64().unwrap();
        let t = fmpy["final_time"].as_f64().unwrap();
        assert!((t - t_end).abs() <= 1e-12 * t_end, "{t} vs {t_end}");
    }
}

#[test]
fn fmpy_default_interval_is_16_h_and_ends_one_h_short() {
    // FMPy 0.3.32 without output_interval: H from the model description, doubled until the run
    // has at most 1000 intervals; a fixed-step FMU cannot take a shorter last step, so FMPy
    // stops at the last whole interval (what docs/fmu.md says)
    let steps = simulate_in_process()["macro_steps"].as_u64().unwrap();
    assert_eq!(steps, 10_097, "docs/fmu.md counts the paper run's steps");
    for version in [2, 3] {
        let r = importers(&["default", path_str(&fmu(version))]);
        let h = r["h"].as_f64().unwrap();
        let interval = r["interval"].as_f64().unwrap();
        assert!(
            (interval - 16.0 * h).abs() <= 1e-12 * interval,
            "FMI {version}: {interval} s is not 16 H"
        );
        assert_eq!(r["rows"], 632, "FMI {version}");
        let last = r["final_time"].as_f64().unwrap();
        assert!(
            (last - 10_096.0 * h).abs() <= 1e-9 * last,
            "FMI {version}: ends at {last} s, not 10096 H"
        );
        let stop = r["stop_time"].as_f64().unwrap();
        assert!((stop - last - h).abs() <= 1e-9 * stop, "FMI {version}");
    }
}

#[test]
fn fmpy_state_round_trip_is_exact_also_in_a_fresh_instance() {
    for version in [2, 3] {
        let r = importers(&["state", path_str(&fmu(version)), "0.5", "1.0"]);
        let straight = &r["straight"];
        assert!(r["bytes"].as_u64().unwrap() > 0);
        for key in ["replay", "fresh_replay"] {
            assert_eq!(
                &r[key], straight,
                "FMI {version}: {key} differs from the straight run"
            );
        }
        assert_eq!(
            r["restored_at_t1"], r["fresh_at_t1"],
            "FMI {version}: the state restored from bytes differs from the one kept in memory"
        );
        assert_ne!(
            r["restored_at_t1"]["digest"], straight["digest"],
            "the restore went back in time"
        );
    }
}

#[test]
fn two_instances_with_other_parameters_in_one_process_do_not_interfere() {
    for version in [2, 3] {
        let r = importers(&["two", path_str(&fmu(version))]);
        assert_eq!(r["together"]["a"], r["alone"]["a"], "FMI {version}");
        assert_eq!(r["together"]["b"], r["alone"]["b"], "FMI {version}");
        assert_ne!(
            r["together"]["a"]["digest"], r["together"]["b"]["digest"],
            "FMI {version}: the parameters were not applied"
        );
    }
}

#[test]
fn ecos_simulates_the_fmi2_fmu_like_the_in_process_slave() {
    let steps = 2000u64;
    let r = importers(&["ecos", path_str(&fmu(2)), &steps.to_string()]);
    // the same run in process
    let mut slave = crawler_fmu::defaults::slave("reference").unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    for n in 0..steps {
        assert_eq!(
            slave.do_step(n as f64 * h, h),
            crawler_physics::slave::StepStatus::Ok
        );
    }
    assert_eq!(
        r["digest"].as_str().unwrap(),
        crawler_physics::report::state_digest(slave.plant()),
        "ecos's run differs from the in-process slave"
    );
    let mean = slave.float64_scalar(crawler_physics::model_description::vr::MEAN_DISPLACEMENT);
    assert_eq!(
        bits(&r["outputs"]["mean_displacement"]),
        mean.unwrap().to_bits()
    );
    let t = r["time"].as_f64().unwrap();
    assert!((t - steps as f64 * h).abs() < 1e-9, "ecos time {t}");
}

/// The Python example in `file` (relative to the repository) that starts with `start`, with the
/// FMU's path replaced by the packaged one; `None` if the file shows none.
fn example(file: &str, start: &str) -> Option<String> {
    let text = std::fs::read_to_string(crawler_e2e::repo_root().join(file)).unwrap();
    let at = text.find(&format!("```python\n{start}"))?;
    let code = &text[at + "```python\n".len()..];
    let code = &code[..code.find("```").unwrap()];
    Some(code.replace("target/fmu/crawler_physics.fmu", path_str(&fmu(2))))
}

/// Runs Python `code`; its standard output.
fn run_python(code: &str) -> String {
    let out = Command::new(crawler_e2e::python())
        .args(["-c", code])
        .output()
        .expect("run the example");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The number printed after `label` in `stdout`.
fn printed(stdout: &str, label: &str) -> f64 {
    stdout
        .split(label)
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no {label:?} in {stdout}"))
}

#[test]
fn the_fmu_doc_fmpy_example_runs_as_shown() {
    // docs/fmu.md's, and the README's while it shows one
    let examples: Vec<(&str, String)> = ["docs/fmu.md", "README.md"]
        .into_iter()
        .filter_map(|f| example(f, "from fmpy import").map(|code| (f, code)))
        .collect();
    assert!(
        examples.iter().any(|(f, _)| *f == "docs/fmu.md"),
        "docs/fmu.md shows an FMPy example"
    );
    // the same run as `crawler-plant simulate --eps 1 --f0 0.2` (printed to 5 digits)
    let out = Command::new(crawler_e2e::bin("crawler-plant"))
        .args(["simulate", "--json", "--eps", "1", "--f0", "0.2"])
        .output()
        .expect("run crawler-plant simulate");
    let reference: Value = serde_json::from_slice(&out.stdout).expect("simulate --json");
    let v_ref = reference["velocity"].as_f64().unwrap();
    for (file, code) in examples {
        assert!(
            code.lines().count() <= 12,
            "{file}: the example stays short"
        );
        let v = printed(&run_python(&code), "steady V = ");
        assert!(
            (v - v_ref).abs() <= 5e-5 * v_ref.abs(),
            "{file}: example V = {v}, simulate {v_ref}"
        );
    }
}

#[test]
fn build_fmu_prebuilt_packages_what_cargo_built_and_refuses_a_missing_or_stale_library() {
    let built = fmus();
    // --prebuilt after the script's own build: the same archives, member for member
    let out = tempfile::tempdir().unwrap();
    let (code, text) = build_fmu(&["--prebuilt", path_str(out.path())], &target_dir());
    assert_eq!(code, 0, "{text}");
    let same = Command::new(crawler_e2e::python())
        .args([
            "-c",
            "import sys, zipfile\n\
             a, b = (zipfile.ZipFile(p) for p in sys.argv[1:])\n\
             names = sorted(a.namelist())\n\
             sys.exit(names != sorted(b.namelist()) or any(a.read(n) != b.read(n) for n in names))",
        ])
        .args([
            path_str(&built.join("crawler_physics.fmu")),
            path_str(&out.path().join("crawler_physics.fmu")),
        ])
        .status()
        .unwrap();
    assert!(same.success(), "--prebuilt packaged other files");
    // an empty target directory: the missing file and the command that builds it
    let empty = tempfile::tempdir().unwrap();
    let (code, text) = build_fmu(&["--prebuilt", path_str(out.path())], empty.path());
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("libcrawler_fmu.so is missing")
            && text.contains("cargo build --release -p crawler-fmu"),
        "{text}"
    );
    // what `cargo test` leaves: a newer library in release/deps than in release/
    let stale = tempfile::tempdir().unwrap();
    let release = stale.path().join("release");
    std::fs::create_dir_all(release.join("deps")).unwrap();
    std::fs::write(release.join("libcrawler_fmu.so"), "old").unwrap();
    std::fs::write(release.join("deps/libcrawler_fmu.so"), "new").unwrap();
    std::fs::copy(
        env!("CARGO_BIN_EXE_crawler-fmu"),
        release.join("crawler-fmu"),
    )
    .unwrap();
    let (code, text) = build_fmu(&["--prebuilt", path_str(out.path())], stale.path());
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("is older than"), "{text}");
    // the options are listed, and an unknown one is refused
    let (code, text) = build_fmu(&["--help"], empty.path());
    assert_eq!(code, 0);
    assert!(
        text.contains("--prebuilt") && text.contains("--portable"),
        "{text}"
    );
    let (code, text) = build_fmu(&["--prebuilt-ish"], empty.path());
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("unknown option --prebuilt-ish"), "{text}");
}
