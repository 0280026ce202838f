//! The plant and a controller, both FMUs, wired by an SSP 1.0 file (`examples/fmu/crawler.ssd`,
//! packed by `scripts/build-ssp.sh` with the controller FMU built from
//! `examples/fmu/wave_controller.py` by pythonfmu), loaded by ecos and by libcosim.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use serde_json::Value;

use super::libcosim::{paper_on_nanoseconds, step_ns};
use super::{
    assert_same_as_simulate, bits, example, fmu, importers, path_str, run_python,
    simulate_scenario_with,
};

/// `crawler.ssp`, packed once per test process from the tests' plant FMU.
fn ssp() -> &'static Path {
    static SSP: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &SSP.get_or_init(|| {
        crawler_e2e::python(); // the venv with pythonfmu
        let dir = tempfile::tempdir().expect("temp dir");
        let (code, text) = build_ssp(&[path_str(&fmu(2)), path_str(dir.path())]);
        assert_eq!(code, 0, "build-ssp.sh failed: {text}");
        let path = dir.path().join("crawler.ssp");
        (dir, path)
    })
    .1
}

/// Runs `scripts/build-ssp.sh` with `args`: exit code, standard output and error.
fn build_ssp(args: &[&str]) -> (i32, String) {
    let out = Command::new("bash")
        .arg(crawler_e2e::repo_root().join("scripts/build-ssp.sh"))
        .args(args)
        .output()
        .expect("run scripts/build-ssp.sh");
    (
        out.status.code().unwrap_or(-1),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// The value the SSD's parameter set gives the parameter `name` of the controller.
fn ssd_value(name: &str) -> String {
    let ssd = std::fs::read_to_string(crawler_e2e::repo_root().join("examples/fmu/crawler.ssd"))
        .expect("examples/fmu/crawler.ssd");
    let tag = format!("<ssv:Parameter name=\"{name}\"><ssv:Real value=\"");
    let at = ssd
        .find(&tag)
        .unwrap_or_else(|| panic!("the SSD sets {name}"))
        + tag.len();
    ssd[at..at + ssd[at..].find('"').unwrap()].to_string()
}

/// What the SSP system computes: the paper scenario on a nanosecond clock driven by the wave of
/// the SSD's controller parameters (`crawler-plant simulate`, the execution loop with the wave
/// held, which tests/tests/one_result.rs shows equal to the co-simulation over zenoh).
fn reference() -> (Value, f64, f64) {
    let (f0, omega) = (ssd_value("f0"), ssd_value("omega"));
    let reference = simulate_scenario_with(
        &paper_on_nanoseconds(),
        &["--f0", f0.as_str(), "--omega", omega.as_str()],
    );
    (reference, f0.parse().unwrap(), omega.parse().unwrap())
}

/// The plant in the master `who` ran the reference's run, driven by the controller's wave.
fn assert_ssp_run(who: &str, r: &Value, reference: &Value, f0: f64, omega: f64) {
    assert_eq!(
        r["ticks_per_second"], 1_000_000_000,
        "{who}: the SSD's clock"
    );
    assert_eq!(
        bits(&r["h"]),
        bits(&reference["parameters"]["step"]),
        "{who}"
    );
    // the controller's outputs reached the plant's inputs (the plant's own starts are the
    // paper's f0 = 0.5 N and omega = 74.3 rad/s)
    assert_eq!(r["wave"]["wave_f0"].as_f64(), Some(f0), "{who}");
    assert_eq!(r["wave"]["wave_omega"].as_f64(), Some(omega), "{who}");
    assert_same_as_simulate(who, r, reference);
}

#[test]
fn ecos_runs_the_plant_and_the_controller_fmu_of_the_ssp_file_bit_for_bit_like_simulate() {
    let (reference, f0, omega) = reference();
    let ns = step_ns(&reference);
    let steps = reference["macro_steps"].as_u64().unwrap();
    let r = importers(&[
        "ssp-ecos",
        path_str(ssp()),
        &ns.to_string(),
        &steps.to_string(),
    ]);
    assert_ssp_run("ecos, SSP", &r, &reference, f0, omega);
    // ecos adds the step to its float clock: within a nanosecond of the plant's at the end
    let t = r["time"].as_f64().unwrap();
    assert!(
        (t - reference["t_end"].as_f64().unwrap()).abs() < 1e-9,
        "ecos time {t}"
    );
}

#[test]
fn libcosim_runs_the_plant_and_the_controller_fmu_of_the_ssp_file_bit_for_bit_like_simulate() {
    let (reference, f0, omega) = reference();
    let ns = step_ns(&reference);
    let steps = reference["macro_steps"].as_u64().unwrap();
    let r = importers(&[
        "ssp-libcosim",
        path_str(ssp()),
        &ns.to_string(),
        &steps.to_string(),
    ]);
    assert_eq!(r["ok"], true, "libcosim failed: {}", r["error"]);
    assert_eq!(r["time_ns"].as_u64(), Some(steps * ns));
    assert_ssp_run("libcosim, SSP", &r, &reference, f0, omega);
}

#[test]
fn ecos_goes_on_when_the_plant_refuses_its_steps() {
    // without the parameter set the plant keeps its own clock (H = 990415.142 ns) and refuses
    // steps of 990415 ns; ecos 0.7.2 advances its time anyway, with the plant at rest
    let r = importers(&["ssp-ecos", path_str(ssp()), "990415", "20", "-"]);
    assert_eq!(r["ticks_per_second"], 0);
    let t = r["time"].as_f64().unwrap();
    assert!((t - 20.0 * 990415e-9).abs() < 1e-12, "ecos time {t}");
    assert_eq!(r["outputs"]["mean_displacement"].as_f64(), Some(0.0));
    assert_eq!(r["outputs"]["mean_speed"].as_f64(), Some(0.0));
}

#[test]
fn the_fmu_doc_ssp_example_runs_as_shown() {
    let code = example("docs/fmu.md", "from ecospy").expect("docs/fmu.md shows ecos on the SSP");
    let code = code.replace("target/fmu/crawler.ssp", path_str(ssp()));
    assert!(code.lines().count() <= 8, "the example stays short");
    let v: f64 = run_python(&code).trim().parse().expect("V printed");
    let (reference, _, _) = reference();
    assert_eq!(
        v.to_bits(),
        reference["velocity"].as_f64().unwrap().to_bits(),
        "docs/fmu.md's ecos example V = {v}, simulate {}",
        reference["velocity"]
    );
}

#[test]
fn build_ssp_packs_the_ssd_and_both_fmus_and_names_what_is_missing() {
    let listing = Command::new(crawler_e2e::python())
        .args([
            "-c",
            "import sys, zipfile; print(sorted(zipfile.ZipFile(sys.argv[1]).namelist()))",
            path_str(ssp()),
        ])
        .output()
        .unwrap();
    assert_eq!(
        String::from_utf8_lossy(&listing.stdout).trim(),
        "['SystemStructure.ssd', 'resources/controller.fmu', 'resources/crawler_physics.fmu']"
    );
    // a controller FMU of one's own: packed as resources/controller.fmu, byte for byte
    let out = tempfile::tempdir().unwrap();
    let mine = out.path().join("mine.fmu");
    std::fs::write(&mine, b"not an FMU, but the script only packs it").unwrap();
    let (code, text) = build_ssp(&[
        "--controller",
        path_str(&mine),
        path_str(&fmu(2)),
        path_str(out.path()),
    ]);
    assert_eq!(code, 0, "{text}");
    let same = Command::new(crawler_e2e::python())
        .args([
            "-c",
            "import sys, zipfile\n\
             z = zipfile.ZipFile(sys.argv[1])\n\
             sys.exit(z.read('resources/controller.fmu') != open(sys.argv[2], 'rb').read())",
            path_str(&out.path().join("crawler.ssp")),
            path_str(&mine),
        ])
        .status()
        .unwrap();
    assert!(same.success(), "--controller packed another file");
    // a missing plant FMU or controller: named, nothing written
    let empty = tempfile::tempdir().unwrap();
    let missing = empty.path().join("crawler_physics.fmu");
    let (code, text) = build_ssp(&[path_str(&missing), path_str(empty.path())]);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("crawler_physics.fmu is missing") && text.contains("build-fmu.sh"),
        "{text}"
    );
    let (code, text) = build_ssp(&[
        "--controller",
        path_str(&missing),
        path_str(&fmu(2)),
        path_str(empty.path()),
    ]);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("is missing"), "{text}");
    assert!(!empty.path().join("crawler.ssp").exists());
    let (code, text) = build_ssp(&["--nonsense"]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("unknown option --nonsense"), "{text}");
}
