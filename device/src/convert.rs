//! Between model/acquisition types and wire types.

use acquisition::{Counters, ProcessedSample, TemperatureOrigin};
use fdc1004::Rate;
use heapless::Vec;
use model_core::{
    BaselineRecord, Calibration, CurvePoint, PadContact, PadModel, SplitCapacitance,
    TaxelCalibrationSpec,
};
use wire::{
    BaselineWire, CountersFrame, PadIndex, PadSummary, SampleFrame, SampleRate,
    TaxelCalibrationRecord, TaxelCalibrationWire, TaxelSample, TemperatureSource,
};

use crate::HostCounters;

/// The converter rate a wire sample rate selects. The numbers stay with their owners
/// ([`SampleRate::sps`], [`Rate::samples_per_second`]); this only pairs the variants.
pub const fn converter_rate(rate: SampleRate) -> Rate {
    match rate {
        SampleRate::Sps100 => Rate::Hz100,
        SampleRate::Sps200 => Rate::Hz200,
        SampleRate::Sps400 => Rate::Hz400,
    }
}

/// The wire sample rate of a converter rate (the inverse of [`converter_rate`]).
pub const fn wire_sample_rate(rate: Rate) -> SampleRate {
    match rate {
        Rate::Hz100 => SampleRate::Sps100,
        Rate::Hz200 => SampleRate::Sps200,
        Rate::Hz400 => SampleRate::Sps400,
    }
}

/// The wire's name for where a sample's temperature came from.
pub fn wire_temperature_source(sample: &ProcessedSample, pad: &PadModel) -> TemperatureSource {
    match sample.temperature_origin {
        TemperatureOrigin::Primary => TemperatureSource::Tmp117,
        TemperatureOrigin::Fallback => TemperatureSource::McuInternal,
        TemperatureOrigin::None if pad.last_valid_temperature_c().is_some() => {
            TemperatureSource::LastKnown
        }
        TemperatureOrigin::None => TemperatureSource::None,
    }
}

/// The wire's summary of a pad's force and contact.
pub fn pad_summary(contact: &PadContact) -> PadSummary {
    PadSummary {
        force_n: contact.force_n(),
        centre_of_pressure_mm: contact.centre_of_pressure_mm(),
        partial: contact.partial(),
        contact: contact.in_contact,
    }
}

/// A processed sample set of pad `index` as a sample frame. The temperature is the one the
/// model corrected with; a faulted taxel carries no pressure.
pub fn sample_frame(
    sample: &ProcessedSample,
    pad: &PadModel,
    index: PadIndex,
    summary: PadSummary,
) -> SampleFrame {
    let temperature_source = wire_temperature_source(sample, pad);
    let temperature_c = match temperature_source {
        TemperatureSource::None => None,
        _ => Some(sample.output.temperature.temperature_c),
    };
    SampleFrame {
        pad: index,
        sequence: sample.sequence,
        timestamp_us: sample.timestamp_us,
        temperature_c,
        temperature_source,
        taxels: sample.output.taxels.map(|taxel| TaxelSample {
            pressure_kpa: taxel.pressure_kpa(),
            capacitance_pf: taxel.capacitance_pf().unwrap_or(f32::NAN),
            flags: taxel.flags().bits(),
        }),
        summary,
    }
}

/// The counters frame: the loop's counters summed over pads, and the host side's.
pub fn counters_frame(counters: &Counters, host: &HostCounters) -> CountersFrame {
    CountersFrame {
        dropped_sample_frames: host.sample_frames_dropped,
        converter_reinits: counters.converter_reinits,
        i2c_errors: counters.i2c_errors,
        temperature_sensor_errors: counters.temperature_errors,
        frames_dropped_no_host: host.frames_dropped_no_host,
        host_frames_rejected: host.host_frames_rejected,
    }
}

/// Why a taxel calibration could not be carried between the model and the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationConversionError {
    /// The calibration has no taxel of this index.
    NoSuchTaxel,
    /// The curve has more points than the destination holds.
    TooManyPoints,
}

/// One taxel's calibration, of pad `pad`, as a wire record.
pub fn calibration_record(
    calibration: &Calibration,
    pad: PadIndex,
    taxel_index: u8,
) -> Result<TaxelCalibrationRecord, CalibrationConversionError> {
    let taxel = calibration
        .taxels()
        .get(usize::from(taxel_index))
        .ok_or(CalibrationConversionError::NoSuchTaxel)?;
    let mut points = Vec::new();
    for point in taxel.curve().points() {
        points
            .push((point.pressure_kpa, point.relative_change))
            .map_err(|_| CalibrationConversionError::TooManyPoints)?;
    }
    Ok(TaxelCalibrationRecord {
        pad,
        taxel_index,
        calibration_id: calibration.id(),
        calibration: TaxelCalibrationWire {
            points,
            parasitic_pf: taxel.parasitic_pf(),
            unloaded_sensor_pf: taxel.unloaded_sensor_pf(),
        },
    })
}

/// A wire calibration as model-core plain data, its calibrated C0 included (validated later by
/// the model).
pub fn taxel_calibration_spec(
    wire: &TaxelCalibrationWire,
) -> Result<TaxelCalibrationSpec, CalibrationConversionError> {
    let mut points = Vec::new();
    for &(pressure_kpa, relative_change) in &wire.points {
        points
            .push(CurvePoint::new(pressure_kpa, relative_change))
            .map_err(|_| CalibrationConversionError::TooManyPoints)?;
    }
    Ok(TaxelCalibrationSpec {
        points,
        parasitic_pf: wire.parasitic_pf,
        unloaded_sensor_pf: wire.unloaded_sensor_pf,
    })
}

/// A model baseline as the wire carries it.
pub fn baseline_wire(record: &BaselineRecord) -> BaselineWire {
    BaselineWire {
        offset_pf: record.capacitance.offset_pf,
        fine_pf: record.capacitance.fine_pf,
        temperature_c: record.temperature_c,
    }
}

/// A wire baseline as model-core's record (validated when the model installs it). The wire
/// carries the tare only, so the record has no tracked drift (tracking is off by default).
pub fn baseline_record(wire: &BaselineWire) -> BaselineRecord {
    BaselineRecord {
        capacitance: SplitCapacitance {
            offset_pf: wire.offset_pf,
            fine_pf: wire.fine_pf,
        },
        temperature_c: wire.temperature_c,
        tracked_drift_pf: 0.0,
    }
}
