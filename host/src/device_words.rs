//! Device frames in words for people: identity, counters and events as a person reads them
//! (serial in hex, versions dotted, rates with their units), never as Rust struct dumps.

use model_core::{BaselineError, Tier, TAXEL_NAMES};
use wire::{CalibrationSource, CountersFrame, DeviceEvent, EventFrame, InfoFrame};

use crate::csv_format::{format_time_us, temperature_source_words};

/// The board serial number in hex, as printed on labels and used by `--serial`.
pub fn board_serial_hex(info: &InfoFrame) -> String {
    info.board_serial
        .iter()
        .map(|byte| format!("{byte:02X}"))
        .collect()
}

/// Where the calibration came from, in words.
pub fn calibration_source_words(source: CalibrationSource) -> &'static str {
    match source {
        CalibrationSource::Defaults => "built-in default",
        CalibrationSource::Flash => "from flash",
        CalibrationSource::DefaultsAfterCorruptFlash => {
            "built-in default (the flash copy was corrupt)"
        }
        CalibrationSource::Host => "written by the host, not saved",
    }
}

/// Why a taxel could not be tared, in words.
pub fn baseline_error_words(error: &BaselineError) -> String {
    match error {
        BaselineError::NotFinite => "its reading or temperature was not a number".to_owned(),
        BaselineError::ImplausiblySmall => {
            "its capacitance is too small for a taxel (open lead?)".to_owned()
        }
        BaselineError::TooFewSamples => "too few valid readings".to_owned(),
        BaselineError::NotStill { spread_ff } => format!(
            "the pad was not still: its readings spread by {spread_ff} fF, more than the {:.0} fF converter noise explains",
            model_core::baseline::TARE_STILL_SPREAD_PF * 1000.0
        ),
    }
}

/// The tier's name.
pub fn tier_words(tier: Tier) -> String {
    tier.name().to_owned()
}

/// The device's rates in words: the converter's conversions per second and the sample sets per
/// second they give (one set is four conversions, one per taxel).
pub fn rate_words(rate_sps: u16) -> String {
    format!(
        "converter {rate_sps} conversions/s = {} sample sets/s",
        rate_sps / 4
    )
}

/// One line describing the device.
pub fn info_words(info: &InfoFrame) -> String {
    let version = info.firmware_version;
    format!(
        "firmware {}.{}.{}, protocol {}, board {}{}, calibration {} ({}), tier {}, {}",
        version.major,
        version.minor,
        version.patch,
        info.protocol_version,
        board_serial_hex(info),
        // One pad is the usual board: said only when there are more (or none).
        if info.pad_count == 1 {
            String::new()
        } else {
            format!(", {} pads", info.pad_count)
        },
        info.calibration_id,
        calibration_source_words(info.calibration_source),
        tier_words(info.model_tier),
        rate_words(info.rate.sps())
    )
}

/// The device's health counters (since its boot) in words.
pub fn counters_words(counters: &CountersFrame) -> String {
    format!(
        "since boot: {} sample frames not sent (one per pad per set), {} frames of any kind not sent (no host or queue full), {} converter re-initialisations, {} I2C errors, {} temperature-sensor errors, {} bad frames from the host",
        counters.dropped_sample_frames,
        counters.frames_dropped_no_host,
        counters.converter_reinits,
        counters.i2c_errors,
        counters.temperature_sensor_errors,
        counters.host_frames_rejected
    )
}

/// A device event in words, with its device time.
pub fn event_words(event: &EventFrame) -> String {
    let what = match event.event {
        DeviceEvent::ConverterReinitialised { reinit_count, .. } => format!(
            "the converter was reset after an error (re-initialisation {reinit_count}); samples were lost"
        ),
        DeviceEvent::TemperatureSourceChanged { source, .. } => format!(
            "temperature now from the {}",
            temperature_source_words(source)
        ),
        DeviceEvent::CalibrationFlashCorrupt => {
            "the calibration in flash was corrupt; the built-in default is in use".to_owned()
        }
        DeviceEvent::TareFinished { tared_mask, .. } => {
            let tared: Vec<&str> = TAXEL_NAMES
                .iter()
                .enumerate()
                .filter(|(taxel, _)| tared_mask & (1 << taxel) != 0)
                .map(|(_, name)| *name)
                .collect();
            if tared.is_empty() {
                "new baselines: no taxel is tared".to_owned()
            } else {
                format!("new baselines (tared: {})", tared.join(", "))
            }
        }
        DeviceEvent::TareRefused { refused_mask, .. } => {
            let refused: Vec<&str> = TAXEL_NAMES
                .iter()
                .enumerate()
                .filter(|(taxel, _)| refused_mask & (1 << taxel) != 0)
                .map(|(_, name)| *name)
                .collect();
            format!(
                "the tare could not tare {} (loaded, not still, open or shorted); they keep their previous baseline, if any",
                refused.join(", ")
            )
        }
        DeviceEvent::ContactStarted { pad } => format!("pad {}: contact started", pad.get()),
        DeviceEvent::ContactEnded { pad } => format!("pad {}: contact ended", pad.get()),
    };
    // The pad of a per-pad event, named for every pad but the first, so that a single-pad
    // device's events read as they always did (contact events name their pad anyway).
    let pad = match event.event {
        DeviceEvent::ConverterReinitialised { pad, .. }
        | DeviceEvent::TemperatureSourceChanged { pad, .. }
        | DeviceEvent::TareFinished { pad, .. }
        | DeviceEvent::TareRefused { pad, .. } => Some(pad.get()).filter(|&pad| pad > 0),
        _ => None,
    };
    let pad = pad.map(|pad| format!("pad {pad}: ")).unwrap_or_default();
    format!(
        "device event at {} s: {pad}{what}",
        format_time_us(event.timestamp_us)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use wire::FirmwareVersion;

    #[test]
    fn info_reads_as_words_with_the_serial_in_hex() {
        let info = InfoFrame {
            protocol_version: 3,
            firmware_version: FirmwareVersion {
                major: 0,
                minor: 1,
                patch: 0,
            },
            board_serial: [0x53, 0x49, 0x4d, 0, 0, 0, 0, 0, 0, 0, 0, 0x2a],
            calibration_id: 7,
            calibration_source: CalibrationSource::Flash,
            rate: wire::SampleRate::Sps400,
            model_tier: Tier::MonotoneCubic,
            streaming: true,
            text_mode: false,
            pad_count: 2,
            clock_us_per_s: 1_000_000,
        };
        let text = info_words(&info);
        assert!(text.contains(", 2 pads,"), "{text}");
        assert!(text.contains("board 53494D00000000000000002A"), "{text}");
        assert!(text.contains("firmware 0.1.0"), "{text}");
        assert!(
            text.contains("400 conversions/s = 100 sample sets/s"),
            "{text}"
        );
        assert!(!text.contains('['), "no struct dump: {text}");
    }
}
