//! Fingerprints the code that computes a point's results (the plant, the models and policies,
//! and this crate's evaluation), so that results computed by other code are never reused: the
//! fingerprint is part of every point's id.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs" || x == "toml") {
            out.push(p);
        }
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let ws = root.parent().expect("workspace root");
    let sources = [
        ws.join("physics/src"),
        ws.join("facts/src"),
        ws.join("models/src"),
        ws.join("policies/src"),
        ws.join("scenarios"),
        root.join("src/evaluate"),
    ];
    let mut all = Vec::new();
    for d in &sources {
        println!("cargo:rerun-if-changed={}", d.display());
        files(d, &mut all);
    }
    assert!(
        !all.is_empty(),
        "no sources found to fingerprint under {}",
        ws.display()
    );
    // paths relative to the workspace, sorted: the same tree gives the same fingerprint anywhere
    let mut rel: Vec<(String, PathBuf)> = all
        .into_iter()
        .map(|p| {
            (
                p.strip_prefix(ws)
                    .unwrap_or(&p)
                    .to_string_lossy()
                    .replace('\\', "/"),
                p,
            )
        })
        .collect();
    rel.sort();
    // FNV-1a, 64 bit: a fingerprint, not a security boundary
    let mut h: u64 = 0xcbf29ce484222325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= *b as u64;
            h = h.wrapping_mul(0x100000001b3);
        }
    };
    for (name, path) in &rel {
        eat(name.as_bytes());
        eat(&[0]);
        eat(&std::fs::read(path).expect("readable source"));
        eat(&[0]);
    }
    println!("cargo:rustc-env=CRAWLER_SWEEP_CODE={h:016x}");
}
