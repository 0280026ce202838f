//! The recorder's executable, next to this one. Through `cargo run` it is brought up to date
//! first (`cargo build` is a no-op when it is fresh); otherwise it must sit next to this program.

use std::path::Path;
use std::process::Command;

use crate::children::Programs;

/// Makes sure the recorder of `programs` exists.
pub fn ensure(programs: &Programs) -> anyhow::Result<()> {
    if let Ok(cargo) = std::env::var("CARGO") {
        let release = programs
            .exe
            .parent()
            .is_some_and(|d| d.ends_with("release"));
        let mut cmd = Command::new(cargo);
        cmd.args([
            "build",
            "--bin",
            "crawler-recorder",
            "-p",
            "crawler-recorder",
        ]);
        if let Ok(dir) = std::env::var("CARGO_MANIFEST_DIR") {
            cmd.arg("--manifest-path")
                .arg(Path::new(&dir).join("../Cargo.toml"));
        }
        if release {
            cmd.arg("--release");
        }
        anyhow::ensure!(cmd.status()?.success(), "building the recorder failed");
    }
    anyhow::ensure!(
        programs.recorder.is_file(),
        "{} not found; build it with: cargo build --release --workspace",
        programs.recorder.display()
    );
    Ok(())
}
