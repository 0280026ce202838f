//! `crawler-controller`: predictions, the optimal policy, figures, and controllers for co-simulation.

fn main() -> std::process::ExitCode {
    crawler_controller::cli::main(std::env::args_os())
}
