//! The `taxel` command-line tool; see `taxel --help`.

use std::process::ExitCode;

use clap::Parser;
use taxel::cli::{run, Cli};

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
