//! Where a conversion's options come from: the command line, and for what it does not give
//! the recording's device state (found beside the input), pad by pad: each pad its own recorded
//! calibration, tier and baselines, or pad 0's when the file describes pad 0 only; without a
//! device state, the built-in defaults and a tare on the first row. The sentence that says so
//! goes to the user.

use anyhow::Context;
use model_core::{Calibration, Tier};

use super::{ConvertOptions, ConvertSettings, PadOptions, TareSource};
use crate::recording::{device_state_path, RecordedDeviceState, RecordedPadState};

/// One pad's options from the command line and, for what it does not give, the pad's recorded
/// state (`None`: no device state; the built-in defaults and a tare on the first row).
fn pad_options(
    args: &ConvertSettings,
    file_calibration: Option<&Calibration>,
    recorded: Option<&RecordedPadState>,
) -> anyhow::Result<PadOptions> {
    let calibration = match (file_calibration, recorded) {
        (Some(calibration), _) => calibration.clone(),
        (None, Some(recorded)) => recorded.calibration()?,
        (None, None) => Calibration::default(),
    };
    let tier = match (args.tier, recorded) {
        (Some(tier), _) => tier,
        (None, Some(recorded)) => Tier::from_name(&recorded.tier).with_context(|| {
            format!(
                "the recording's tier '{}' of pad {} is unknown here",
                recorded.tier, recorded.pad
            )
        })?,
        (None, None) => Tier::default(),
    };
    let tare = match (args.tare_rows, recorded) {
        (Some(rows), _) => TareSource::Rows(rows),
        (None, Some(recorded)) if !recorded.baselines.is_empty() => {
            TareSource::Recorded(recorded.baselines.clone())
        }
        (None, _) => TareSource::Rows(1),
    };
    Ok(PadOptions {
        calibration,
        tier,
        tare,
    })
}

/// What a device state of several pads gave the pads other than pad 0, in words.
fn other_pads_words(args: &ConvertSettings, state: &RecordedDeviceState) -> String {
    let pad_count = state.pad_count;
    let without = state.pads_without_state();
    if !without.is_empty() {
        let names: Vec<String> = without.iter().map(u8::to_string).collect();
        let pads = if names.len() == 1 { "pad" } else { "pads" };
        return format!(
            "for each of the {pad_count} pads (the device state does not hold the state of {pads} {}, as files written before every pad's state was recorded hold pad 0's only: pad 0's calibration, tier and baselines are used for {pads} {}, whose pressures may differ from the device's)",
            names.join(", "),
            names.join(", ")
        );
    }
    let own: Vec<&str> = [
        (args.calibration.is_none(), "calibration"),
        (args.tier.is_none(), "tier"),
        (args.tare_rows.is_none(), "baselines"),
    ]
    .iter()
    .filter_map(|&(own, what)| own.then_some(what))
    .collect();
    if own.is_empty() {
        return format!("for each of the {pad_count} pads");
    }
    let pads: Vec<String> = state
        .other_pads
        .iter()
        .map(|pad| {
            format!(
                "pad {}: calibration id {} ({}), tier {}, {} baseline sets",
                pad.pad,
                pad.calibration.id,
                pad.calibration_source,
                pad.tier,
                pad.baselines.len()
            )
        })
        .collect();
    format!(
        "for each of the {pad_count} pads with its own recorded {} ({})",
        own.join(", "),
        pads.join("; ")
    )
}

/// The options a conversion runs with, and a sentence saying where each came from.
pub fn resolve_options(args: &ConvertSettings) -> anyhow::Result<(ConvertOptions, String)> {
    let input = args.raw.as_ref().or(args.input.as_ref());
    let state_path = match (&args.device_state, input) {
        _ if args.no_device_state => None,
        (Some(path), _) => Some(path.clone()),
        (None, Some(input)) if input.as_os_str() != "-" => {
            Some(device_state_path(input)).filter(|path| path.exists())
        }
        (None, _) => None,
    };
    let state = match &state_path {
        Some(path) => Some(RecordedDeviceState::read(path)?),
        None => None,
    };
    let file_calibration = match &args.calibration {
        Some(path) => Some(
            crate::calibration_file::read(path)
                .with_context(|| format!("reading the calibration {}", path.display()))?,
        ),
        None => None,
    };
    let pad_zero_state = state.as_ref().and_then(|state| state.pad_state(0));
    let pad_zero = pad_options(args, file_calibration.as_ref(), pad_zero_state.as_ref())?;
    let mut said = Vec::new();
    match (&args.calibration, &state) {
        (Some(path), _) => said.push(format!(
            "the calibration in {} (id {})",
            path.display(),
            pad_zero.calibration.id()
        )),
        (None, Some(state)) => said.push(format!(
            "the device's calibration recorded with it (id {}, {})",
            pad_zero.calibration.id(),
            state.calibration_source
        )),
        (None, None) => said.push(
            "the built-in default calibration (the article's curve; no device-state file beside the input)"
                .to_owned(),
        ),
    }
    said.push(format!("tier {}", pad_zero.tier.name()));
    match &pad_zero.tare {
        TareSource::Recorded(changes) => said.push(format!(
            "the device's baselines ({} recorded)",
            changes.len()
        )),
        TareSource::Rows(rows) => said.push(format!("a tare on the first {rows} readable row(s)")),
    }
    let pad_count = state.as_ref().map_or(1, |state| state.pad_count.max(1));
    let mut other_pads = Vec::new();
    if let Some(state) = state.as_ref().filter(|_| pad_count > 1) {
        said.push(other_pads_words(args, state));
        for pad in 1..pad_count {
            let recorded = state.pad_state(pad).or_else(|| pad_zero_state.clone());
            other_pads.push(
                pad_options(args, file_calibration.as_ref(), recorded.as_ref())
                    .with_context(|| format!("pad {pad}"))?,
            );
        }
    }
    let source = match &state_path {
        Some(path) => format!(
            "converting with {} (from {})",
            said.join(", "),
            path.display()
        ),
        None => format!("converting with {}", said.join(", ")),
    };
    let PadOptions {
        calibration,
        tier,
        tare,
    } = pad_zero;
    Ok((
        ConvertOptions {
            calibration,
            tier,
            tare,
            pad_count,
            other_pads,
        },
        source,
    ))
}
