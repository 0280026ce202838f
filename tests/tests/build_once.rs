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
