//! `crawler-recorder`: records a co-simulation run into a Rerun `.rrd` file.

fn main() -> std::process::ExitCode {
    crawler_recorder::cli::main(std::env::args_os())
}
