//! `crawler-sweep`: `crawler sweep` under its own name (the name the Slurm job scripts call).

fn main() -> std::process::ExitCode {
    crawler::sweep::main(std::env::args_os())
}
