//! # crawler-cli
//!
//! What the soft-crawler programs (`crawler-plant`, `crawler-controller`, `crawler-recorder`,
//! `crawler`) share on the command line, kept out of the libraries:
//!
//! - [`scenario_args`]: the scenario file and the common overrides (`--eps --n-f --f0 --k
//!   --omega --alpha --cells --t-end`);
//! - [`progress`]: the progress bar of long runs;
//! - [`exit`]: the one table of process exit codes;
//! - [`cpu`]: stop with a clear message on a CPU that lacks the build's instructions;
//! - [`stdout`]: results on standard output, where a closed pipe ends the output, not the program
//!   with a panic;
//! - [`number`]: a flag's value in an error message (exponent form where it would be long).

pub mod cpu;
pub mod exit;
pub mod progress;
pub mod scenario_args;
pub mod stdout;

pub use crawler_physics::error::number;
pub use exit::Exit;
pub use scenario_args::ScenarioArgs;
