//! The programs' CPU check: print what is missing and exit.

use crate::exit::Exit;

/// Exits with a clear message (code [`Exit::Usage`]) if this CPU lacks the instructions the
/// build targets ([`crawler_physics::cpu::missing_features`]). Call it first thing in `main`.
pub fn ensure_cpu_features() {
    if let Some(why) = crawler_physics::cpu::missing_features() {
        eprintln!("error: {why}");
        std::process::exit(Exit::Usage.code().into());
    }
}
