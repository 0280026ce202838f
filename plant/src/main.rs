//! `crawler-plant`: the crawler plant, in process (`simulate`) or as a co-simulation slave (`run`).

fn main() -> std::process::ExitCode {
    crawler_plant::cli::main(std::env::args_os())
}
