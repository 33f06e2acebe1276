//! The `taxel` command-line tool; see `taxel --help`.

use std::process::ExitCode;

use clap::Parser;
use taxel::cli::{run, Cli};
use taxel_host::console::{error_message, is_broken_pipe};
use taxel_host::noteln;

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(code) => code,
        Err(error) if is_broken_pipe(&error) => {
            noteln!(
                "error: the output pipe was closed before everything was written (files the command writes are complete)"
            );
            ExitCode::FAILURE
        }
        Err(error) => {
            noteln!("error: {}", error_message(&error));
            ExitCode::FAILURE
        }
    }
}
