//! The README's two commands build each dependency once: the main job (`cargo run --release -p
//! crawler -- run`) resolves every shared dependency with the same features as the test command
//! (`cargo test --release --workspace`, which adds every crate's dev-dependencies), so the test
//! command compiles only what the main job did not (tests, the other programs), never a second
//! copy of a dependency the main job built. Cargo compiles a package once per feature set; a
//! dev-dependency that turns on one more feature deep in the tree (rustix under the Rerun stack)
//! would otherwise rebuild everything above it.

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

use crawler_e2e::repo_root;

/// `cargo tree` of `args`: each package (name and version) with its feature sets.
fn features(args: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(repo_root())
        .args(["tree", "--locked", "--offline", "--prefix", "none"])
        .args(["-f", "{p} [{f}]"])
        .args(args)
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut map: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let line = line.trim_end_matches(" (*)");
        let (Some(open), true) = (line.rfind(" ["), line.ends_with(']')) else {
            continue;
        };
        // "name vX.Y.Z (path or proc-macro)" -> "name vX.Y.Z"
        let mut words = line[..open].split(' ');
        let package = format!(
            "{} {}",
            words.next().unwrap_or(""),
            words.next().unwrap_or("")
        );
        let feats = line[open + 2..line.len() - 1].to_string();
        map.entry(package).or_default().insert(feats);
    }
    map
}

#[test]
fn the_main_job_builds_every_shared_dependency_as_the_tests_do() {
    let main_job = features(&["-p", "crawler", "-e", "normal,build"]);
    let tests = features(&["--workspace", "-e", "normal,build,dev"]);
    assert!(
        main_job.len() > 100,
        "the main job's tree looks wrong: {} packages",
        main_job.len()
    );
    let differ: Vec<String> = main_job
        .iter()
        .filter(|(p, f)| tests.get(*p) != Some(f))
        .map(|(p, f)| format!("{p}: main job {f:?}, tests {:?}", tests.get(p)))
        .collect();
    assert!(
        differ.is_empty(),
        "these dependencies would be built twice (turn the tests' features on in crawler/Cargo.toml):\n{}",
        differ.join("\n")
    );
}

/// `cargo run -p NAME` needs to know which program to run: a package with several binaries must
/// name one as `default-run`, or the README's command stops with "could not determine which
/// binary to run" before building anything.
#[test]
fn cargo_run_of_every_program_package_the_readme_names_picks_one_binary() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(repo_root())
        .args([
            "metadata",
            "--no-deps",
            "--format-version",
            "1",
            "--offline",
        ])
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let readme = std::fs::read_to_string(repo_root().join("README.md")).unwrap();
    let mut checked = 0;
    for package in meta["packages"].as_array().expect("packages") {
        let name = package["name"].as_str().unwrap();
        if !readme.contains(&format!("cargo run --release -p {name} ")) {
            continue;
        }
        let bins: Vec<&str> = package["targets"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|t| t["kind"].as_array().unwrap().iter().any(|k| k == "bin"))
            .map(|t| t["name"].as_str().unwrap())
            .collect();
        let default_run = package["default_run"].as_str();
        assert!(
            bins.len() == 1 || default_run.is_some_and(|d| bins.contains(&d)),
            "`cargo run -p {name}` cannot choose among the binaries {bins:?} (default-run: {default_run:?})"
        );
        if bins.len() > 1 {
            assert_eq!(
                default_run,
                Some(name),
                "`cargo run -p {name}` runs the program {name}"
            );
        }
        checked += 1;
    }
    assert!(
        checked >= 1,
        "the README names no `cargo run --release -p` command"
    );
}
