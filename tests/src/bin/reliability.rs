//! Writes docs/RELIABILITY.md: every fault of the reliability issue injected end to end through the
//! simulated device, with what came out. `cargo run --release -p taxel-tests --bin reliability`.

use std::process::ExitCode;

use taxel_tests::pad_faults::{self, run_pad_fault, PadFaultKind};
use taxel_tests::reliability::{render_markdown, run_fault, FaultKind};

const COMMAND: &str = "cargo run --release -p taxel-tests --bin reliability";
const REPETITIONS: u32 = 20;

fn main() -> ExitCode {
    let output = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "docs/RELIABILITY.md".to_string());
    let mut outcomes = Vec::new();
    for kind in FaultKind::ALL {
        eprintln!("{}: {REPETITIONS} runs", kind.name());
        match run_fault(kind, REPETITIONS) {
            Ok(outcome) => outcomes.push(outcome),
            Err(error) => {
                eprintln!("error: {}: {error}", kind.name());
                return ExitCode::FAILURE;
            }
        }
    }
    let mut pad_outcomes = Vec::new();
    for kind in PadFaultKind::ALL {
        eprintln!("{}: {REPETITIONS} runs", kind.name());
        match run_pad_fault(kind, REPETITIONS) {
            Ok(outcome) => pad_outcomes.push(outcome),
            Err(error) => {
                eprintln!("error: {}: {error}", kind.name());
                return ExitCode::FAILURE;
            }
        }
    }
    let markdown = render_markdown(
        &outcomes,
        &pad_faults::render_markdown(&pad_outcomes),
        COMMAND,
    );
    // The soak's section (written by the soak command) is kept as it is.
    let markdown = match std::fs::read_to_string(&output).ok().and_then(|previous| {
        let start = previous.find("<!-- soak: start -->")?;
        Some(previous[start..].to_owned())
    }) {
        Some(soak) => format!("{}\n\n{soak}", markdown.trim_end()),
        None => markdown,
    };
    // Through a temporary name: an interrupted run leaves the previous report, not half of one.
    let written = taxel_host::output_file::OutputFile::create(std::path::Path::new(&output))
        .and_then(|mut file| {
            std::io::Write::write_all(&mut file, markdown.as_bytes())?;
            file.commit()
        });
    if let Err(error) = written {
        eprintln!("error: writing {output}: {error:#}");
        return ExitCode::FAILURE;
    }
    let mut bad: Vec<_> = outcomes
        .iter()
        .filter(|outcome| {
            outcome.wrong_pressures > 0
                || outcome.sets_lost_silently() > 0
                || outcome.recovery_us.len() < outcome.repetitions as usize
        })
        .map(|outcome| outcome.kind.name())
        .collect();
    bad.extend(
        pad_outcomes
            .iter()
            .filter(|outcome| {
                outcome.wrong_pressures > 0
                    || outcome.frames_missing > 0
                    || outcome.other_frames_flagged > 0
                    || outcome.failing_frames_flagged < outcome.failing_frames_during
                    || outcome.recovery_us.len() < outcome.repetitions as usize
            })
            .map(|outcome| outcome.kind.name()),
    );
    eprintln!("wrote {output}");
    if bad.is_empty() {
        ExitCode::SUCCESS
    } else {
        eprintln!("error: faults with wrong pressures, unaccounted losses or no recovery: {bad:?}");
        ExitCode::FAILURE
    }
}
