//! The `ribbon` command: parses the command line, runs the subcommand, maps errors to exit codes
//! (0 ok, 1 failure, 2 bad arguments or bad input, 3 `merge` planned another stage, 4 a study's
//! results written but its surrogate not trusted; clap's own usage errors also exit 2).

#![warn(missing_docs)]

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = ribbon::cli::Cli::parse();
    match ribbon::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            let code = error.exit_code();
            // Another stage to run is the documented outcome of a staged merge, not an error.
            if code == ribbon::distributed::NEXT_STAGE_EXIT_CODE {
                eprintln!("{error}");
            } else {
                // A long message: a headline, then its details and what to do, indented.
                eprintln!("error: {}", ribbon::text::laid_out(&error.to_string()));
            }
            ExitCode::from(code)
        }
    }
}
