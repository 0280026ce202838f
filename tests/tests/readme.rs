//! What the README shows is what the code is: the example controller is the real `pulse` policy
//! and its registration line, every registered policy is listed, and the example runs; every
//! relative link of the README and the guide (`docs/*.md`) reaches its file and heading, every
//! command of the project's programs they show parses, and the README stays a front door.

use std::time::Duration;

use crawler_e2e::{bin, repo_root, simulate, Run};

fn squeeze(s: &str) -> String {
    s.chars()
        .filter(|c| !c.is_whitespace() && *c != ',')
        .collect()
}

fn readme() -> String {
    std::fs::read_to_string(repo_root().join("README.md")).unwrap()
}

#[test]
fn readme_shows_the_real_example_controller_and_its_registration() {
    let readme = squeeze(&readme());
    let file = std::fs::read_to_string(repo_root().join("policies/src/pulse.rs")).unwrap();
    assert!(
        readme.contains(&squeeze(&file)),
        "README.md must show policies/src/pulse.rs as it is"
    );
    let registry = std::fs::read_to_string(repo_root().join("policies/src/registry.rs")).unwrap();
    let entry = r#"Entry {
        name: "pulse",
        help: "the scenario's wave, on and off every second",
        keys: &[],
        build: crate::pulse::build,
        check: None,
    },"#;
    assert!(readme.contains(&squeeze(entry)));
    assert!(squeeze(&registry).contains(&squeeze(entry)));
}

#[test]
fn every_registered_policy_is_in_the_readme() {
    let out = std::process::Command::new(bin("crawler-controller"))
        .arg("policies")
        .output()
        .unwrap();
    assert!(out.status.success());
    let listed = String::from_utf8_lossy(&out.stdout).to_string();
    let readme = readme();
    for name in ["optimal", "wave", "resonance", "sweep", "pulse"] {
        assert!(listed.contains(name), "policies: {listed}");
        assert!(
            readme.contains(&format!("`{name}`")),
            "README misses {name}"
        );
    }
}

#[test]
fn the_example_controller_drives_a_cosimulation() {
    let run = Run::new("pulse");
    let plant = run.plant(&["--t-end", "8", "--json"]);
    let ctl = run.controller(&["--policy", "pulse"]);
    let p = plant.wait(Duration::from_secs(120));
    let c = ctl.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    let report: serde_json::Value = serde_json::from_str(&p.stdout).unwrap();
    // The actuation changes every second, so no steady window: run averages after 5 s, said so.
    assert_eq!(report["window"]["steady"], false, "{report}");
    assert!(
        c.stdout.contains("run averages"),
        "controller: {}",
        c.stdout
    );
    // Driven part of the time: it crawls forwards, slower than under the wave all along.
    let pulse = report["velocity"].as_f64().unwrap();
    let wave = simulate(&["--t-end", "8"])["velocity"].as_f64().unwrap();
    assert!(
        pulse > 0.2 * wave && pulse < 0.9 * wave,
        "pulse {pulse} m/s, wave {wave} m/s"
    );
    // The window is contiguous: the discrete momentum balance still holds to round-off.
    assert!(
        report["momentum_residual"].as_f64().unwrap() < 1e-9,
        "{report}"
    );
}

/// The README and the guide's pages (`docs/*.md`), with their paths relative to the repository.
fn pages() -> Vec<(std::path::PathBuf, String)> {
    let root = repo_root();
    let mut pages = vec![root.join("README.md")];
    let mut docs: Vec<_> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p, text)
        })
        .collect()
}

/// The lines of `text` outside fenced code blocks, and the code blocks' lines with their
/// language (the word after the opening fence).
fn split_fences(text: &str) -> (Vec<&str>, Vec<(String, &str)>) {
    let mut prose = Vec::new();
    let mut code = Vec::new();
    let mut fence: Option<String> = None;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if let Some(rest) = trimmed.strip_prefix("```") {
            fence = match fence {
                Some(_) => None,
                None => Some(rest.trim().to_string()),
            };
            continue;
        }
        match &fence {
            Some(lang) => code.push((lang.clone(), line)),
            None => prose.push(line),
        }
    }
    (prose, code)
}

/// The link targets of Markdown prose: `[text](target)` and `![alt](target)`, inline code left out.
fn link_targets(prose: &[&str]) -> Vec<String> {
    let mut targets = Vec::new();
    for line in prose {
        // drop inline code spans, whose brackets are not links
        let mut plain = String::new();
        for (i, part) in line.split('`').enumerate() {
            if i % 2 == 0 {
                plain.push_str(part);
            }
        }
        let mut rest = plain.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let end = after.find(')').unwrap_or(after.len());
            targets.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    targets
}

/// GitHub's anchors of a Markdown page's headings: lower case, punctuation other than `-` and
/// `_` removed, spaces as `-`, repeated headings numbered `-1`, `-2`, ...
fn anchors(text: &str) -> std::collections::BTreeSet<String> {
    let (prose, _) = split_fences(text);
    let mut seen = std::collections::BTreeMap::<String, usize>::new();
    let mut out = std::collections::BTreeSet::new();
    for line in prose {
        let Some(title) = line.strip_prefix('#') else {
            continue;
        };
        let title = title.trim_start_matches('#');
        if !title.starts_with(' ') {
            continue;
        }
        let slug: String = title
            .trim()
            .to_lowercase()
            .chars()
            .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
            .map(|c| if c == ' ' { '-' } else { c })
            .collect();
        let n = seen.entry(slug.clone()).or_insert(0);
        out.insert(if *n == 0 {
            slug.clone()
        } else {
            format!("{slug}-{n}")
        });
        *n += 1;
    }
    out
}

#[test]
fn every_relative_link_in_the_readme_and_the_guide_points_to_an_existing_file_and_heading() {
    let mut broken = Vec::new();
    let mut checked = 0;
    for (page, text) in pages() {
        let (prose, _) = split_fences(&text);
        for target in link_targets(&prose) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let file = if path.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(path)
            };
            checked += 1;
            if !file.exists() {
                broken.push(format!("{}: {target}: no such file", page.display()));
                continue;
            }
            if let Some(anchor) = anchor {
                if file.extension().is_some_and(|x| x == "md") {
                    let text = std::fs::read_to_string(&file).unwrap();
                    if !anchors(&text).contains(anchor) {
                        broken.push(format!(
                            "{}: {target}: no heading with that anchor in {}",
                            page.display(),
                            file.display()
                        ));
                    }
                }
            }
        }
    }
    assert!(
        checked > 50,
        "only {checked} links found: is the parser broken?"
    );
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

/// The project's programs as a README shows them: by name, under `target/release/` or `$B/`,
/// or as `cargo run --release -p crawler -- ...`. Returns the program and its arguments.
fn program_command(line: &str) -> Option<(String, Vec<String>)> {
    // a shell prompt (`hostA$ `), a comment, a trailing `&` and a redirection are not arguments
    let line = match line.find("$ ") {
        Some(i) if !line[..i].contains(' ') && !line[..i].is_empty() => &line[i + 2..],
        _ => line,
    };
    let line = line.split(" #").next().unwrap().trim();
    let mut words: Vec<String> = line
        .split_whitespace()
        .take_while(|w| *w != ">" && *w != "&" && *w != "|")
        .map(str::to_string)
        .collect();
    if words.first().map(String::as_str) == Some("cargo") {
        let dash = words.iter().position(|w| w == "--")?;
        let p = words.iter().position(|w| w == "-p")?;
        let name = words.get(p + 1)?.clone();
        return Some((name, words.split_off(dash + 1)));
    }
    let first = words.first()?;
    let name = first.rsplit('/').next().unwrap().to_string();
    let prefix = &first[..first.len() - name.len()];
    let known = [
        "crawler",
        "crawler-plant",
        "crawler-controller",
        "crawler-recorder",
        "crawler-sweep",
    ];
    if !known.contains(&name.as_str())
        || !(prefix.is_empty() || prefix == "target/release/" || prefix == "$B/")
    {
        return None;
    }
    Some((name, words.split_off(1)))
}

#[test]
fn every_program_command_in_the_readme_and_the_guide_parses() {
    let mut bad = Vec::new();
    let mut checked = 0;
    for (page, text) in pages() {
        let (_, code) = split_fences(&text);
        for (lang, line) in code {
            if lang != "sh" {
                continue;
            }
            let Some((program, args)) = program_command(line) else {
                continue;
            };
            // the subcommands: the leading words (`run`, `plant simulate`, `sweep collect`)
            let subcommands: Vec<&String> = args
                .iter()
                .take_while(|w| w.chars().all(|c| c.is_ascii_lowercase()))
                .take(2)
                .collect();
            let out = std::process::Command::new(bin(&program))
                .args(&subcommands)
                .arg("--help")
                .output()
                .unwrap();
            checked += 1;
            let help = String::from_utf8_lossy(&out.stdout).to_string();
            if !out.status.success() {
                bad.push(format!(
                    "{}: `{line}`: `{program} {} --help` fails: {}",
                    page.display(),
                    subcommands
                        .iter()
                        .map(|s| s.as_str())
                        .collect::<Vec<_>>()
                        .join(" "),
                    String::from_utf8_lossy(&out.stderr)
                ));
                continue;
            }
            // every flag before a bare `--` (after it: another program's flags) is the program's
            for flag in args
                .iter()
                .take_while(|w| *w != "--")
                .filter(|w| w.starts_with("--") && *w != "--help")
            {
                let flag = flag.split('=').next().unwrap();
                let known = help
                    .split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                    .any(|w| w == flag);
                if !known {
                    bad.push(format!(
                        "{}: `{line}`: {program} {} has no flag {flag}",
                        page.display(),
                        subcommands
                            .iter()
                            .map(|s| s.as_str())
                            .collect::<Vec<_>>()
                            .join(" ")
                    ));
                }
            }
        }
    }
    assert!(
        checked >= 10,
        "only {checked} commands found: is the parser broken?"
    );
    assert!(
        bad.is_empty(),
        "commands that do not parse:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_readme_is_a_front_door_of_at_most_about_300_lines_with_the_two_commands() {
    let readme = readme();
    let lines = readme.lines().count();
    assert!(
        lines <= 320,
        "README.md has {lines} lines; the rest belongs in docs/"
    );
    for command in [
        "cargo run --release -p crawler -- run",
        "cargo test --release --workspace",
        "scripts/setup.sh",
    ] {
        assert!(readme.contains(command), "README.md misses `{command}`");
    }
    let ci = std::fs::read_to_string(repo_root().join(".ci/run")).unwrap();
    assert!(
        ci.contains("scripts/setup.sh") && ci.contains("cargo test --release --workspace"),
        ".ci/run must run the README's set-up step and test command"
    );
}

/// The main job's printout in the README is the main job's: the in-process run of its policy
/// (`optimal`) on its scenario (`scenarios/paper.toml`), which the co-simulation equals bit for
/// bit (tests/tests/one_result.rs), ends in the state digest and the wave the README shows.
#[test]
fn the_readmes_main_job_printout_has_the_main_jobs_state_digest_and_wave() {
    let readme = readme();
    let block = readme
        .split("## What the main job prints")
        .nth(1)
        .expect("the section on the main job's printout");
    let shown = |key: &str| -> String {
        block
            .lines()
            .find_map(|l| l.trim().strip_prefix(key))
            .unwrap_or_else(|| panic!("the README's printout has no line {key:?}"))
            .trim()
            .to_string()
    };
    let digest = shown("state digest");
    let scenario = crawler_physics::scenario::Scenario::from_file(
        &repo_root().join("scenarios/paper.toml"),
        &crawler_physics::scenario::Overrides::default(),
    )
    .unwrap();
    let run = crawler_policies::in_process::run_named(
        &scenario,
        "optimal",
        &crawler_policies::Params::none(),
    )
    .expect("the optimal policy runs in process");
    assert_eq!(
        digest, run.report.state_digest,
        "the README's main job printout is stale: run the main job and paste its printout"
    );
    let wave = run.last_wave.expect("the optimal policy commands a wave");
    let line = shown("scenario paper:");
    assert!(
        line.contains(&format!("f0 = {:.4} N", wave.f0)),
        "README: {line:?}, the run's f0 = {} N",
        wave.f0
    );
}
