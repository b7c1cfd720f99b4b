//! The `ribbon` command: parses the command line, runs the subcommand, maps errors to exit codes
//! (0 ok, 1 failure, 2 bad arguments or bad input; clap's own usage errors also exit 2).

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = ribbon::cli::Cli::parse();
    match ribbon::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}
