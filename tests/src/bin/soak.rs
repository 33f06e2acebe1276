//! The soak of the host library (see `taxel_tests::soak`), its figures written into
//! docs/RELIABILITY.md between the soak markers:
//! `cargo run --release -p taxel-tests --bin soak [-- DEVICE_SECONDS [SPEED]]` (default: one
//! hour of device time at 20× real time, 2 devices × 8 pads).

use std::process::ExitCode;

use taxel_tests::soak::{render_markdown, run_soak, SoakConfig};

const COMMAND: &str = "cargo run --release -p taxel-tests --bin soak";
const REPORT: &str = "docs/RELIABILITY.md";
const START: &str = "<!-- soak: start -->";
const END: &str = "<!-- soak: end -->";

fn main() -> ExitCode {
    let mut arguments = std::env::args().skip(1);
    let device_seconds = arguments
        .next()
        .and_then(|text| text.parse().ok())
        .unwrap_or(3600.0);
    let speed = arguments
        .next()
        .and_then(|text| text.parse().ok())
        .unwrap_or(20.0);
    let config = SoakConfig {
        devices: 2,
        pads: 8,
        device_seconds,
        speed,
    };
    let directory = match tempfile::tempdir() {
        Ok(directory) => directory,
        Err(error) => {
            eprintln!("error: a temporary directory: {error}");
            return ExitCode::FAILURE;
        }
    };
    eprintln!("soak: {config:?}");
    let outcome = match run_soak(config, directory.path()) {
        Ok(outcome) => outcome,
        Err(error) => {
            eprintln!("error: {error:#}");
            return ExitCode::FAILURE;
        }
    };
    let section = format!(
        "{START}\n{}{END}\n",
        render_markdown(&config, &outcome, COMMAND)
    );
    eprint!("{section}");
    let report = std::fs::read_to_string(REPORT).unwrap_or_default();
    let updated = match (report.find(START), report.find(END)) {
        (Some(start), Some(end)) if start < end => {
            format!(
                "{}{section}{}",
                &report[..start],
                &report[end + END.len() + 1..]
            )
        }
        _ => format!("{}\n{section}", report.trim_end()),
    };
    let written = taxel_host::output_file::OutputFile::create(std::path::Path::new(REPORT))
        .and_then(|mut file| {
            std::io::Write::write_all(&mut file, updated.as_bytes())?;
            file.commit()
        });
    if let Err(error) = written {
        eprintln!("error: writing {REPORT}: {error:#}");
        return ExitCode::FAILURE;
    }
    if outcome.unflagged_losses() > 0 {
        eprintln!("error: {} sets lost unflagged", outcome.unflagged_losses());
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
