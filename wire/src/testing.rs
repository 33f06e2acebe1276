//! Test support (feature `testing`): valid frames with every field at a plausible value, for the
//! tests of the crates that read the protocol. Change what a test is about with struct update
//! syntax: `SampleFrame { sequence: 7, ..testing::sample_frame(0) }`.

use crate::{
    CalibrationSource, FirmwareVersion, InfoFrame, PadGeometry, PadIndex, PadInfoFrame, PadRole,
    PadSummary, SampleFrame, SampleRate, TaxelSample, TemperatureSensor, TemperatureSource, Tier,
    PROTOCOL_VERSION,
};

/// Pad `pad`'s frame (clamped to the largest pad index) of set 0 at device time 0: four unloaded
/// taxels (0 kPa at 4.5 pF, no flags) at 25 °C from the TMP117, no force, not in contact.
pub fn sample_frame(pad: u8) -> SampleFrame {
    SampleFrame {
        pad: pad_index(pad),
        sequence: 0,
        timestamp_us: 0,
        temperature_c: Some(25.0),
        temperature_source: TemperatureSource::Tmp117,
        taxels: [TaxelSample {
            pressure_kpa: Some(0.0),
            capacitance_pf: 4.5,
            flags: 0,
        }; 4],
        summary: PadSummary {
            force_n: Some(0.0),
            centre_of_pressure_mm: None,
            partial: false,
            contact: false,
        },
    }
}

/// The Info frame of a streaming device with `pad_count` pads at 400 sets/s, in this protocol
/// version, firmware 1.0.0, board serial all 7s, the built-in default calibration, an exact
/// clock.
pub fn info_frame(pad_count: u8) -> InfoFrame {
    InfoFrame {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 1,
            minor: 0,
            patch: 0,
        },
        board_serial: [7; 12],
        calibration_id: 0,
        calibration_source: CalibrationSource::Defaults,
        rate: SampleRate::Sps400,
        model_tier: Tier::MonotoneCubic,
        streaming: true,
        text_mode: false,
        pad_count,
        clock_us_per_s: 1_000_000,
    }
}

/// Pad `pad`'s PadInfo (clamped to the largest pad index): on multiplexer channel `pad`, its own
/// TMP117 at 0x48, the built-in default calibration, the default tier, the article's geometry.
pub fn pad_info_frame(pad: u8) -> PadInfoFrame {
    let pad = pad_index(pad);
    PadInfoFrame {
        pad,
        channel: Some(pad.get()),
        temperature_sensor: TemperatureSensor::OwnTmp117 { address: 0x48 },
        calibration_id: 0,
        calibration_source: CalibrationSource::Defaults,
        model_tier: Tier::MonotoneCubic,
        role: PadRole::Unspecified,
        taxels: *PadGeometry::ARTICLE.taxels(),
    }
}

fn pad_index(pad: u8) -> PadIndex {
    PadIndex::new(pad.min(PadIndex::MAX)).unwrap_or_default()
}
