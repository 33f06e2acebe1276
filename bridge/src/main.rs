//! `taxel-bridge` (also `taxel bridge`): see `taxel-bridge --help`.

use std::process::ExitCode;

use clap::Parser;
use taxel_bridge::command::{run, BridgeArgs};
use taxel_host::console::error_message;
use taxel_host::noteln;

fn main() -> ExitCode {
    let args = BridgeArgs::parse();
    match run(&args) {
        Ok(code) => code,
        Err(error) => {
            noteln!("error: {}", error_message(&error));
            ExitCode::FAILURE
        }
    }
}
