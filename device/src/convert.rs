//! Between model/acquisition types and wire types.

use acquisition::{Counters, ProcessedSample, TemperatureOrigin};
use heapless::Vec;
use model_core::{Calibration, CurvePoint, PadModel, TaxelCalibrationSpec};
use wire::{
    CountersFrame, SampleFrame, TaxelCalibrationRecord, TaxelCalibrationWire, TaxelSample,
    TemperatureSource,
};

use crate::HostCounters;

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

/// A processed sample set as a sample frame. The temperature is the one the model corrected
/// with; a faulted taxel carries no pressure.
pub fn sample_frame(sample: &ProcessedSample, pad: &PadModel) -> SampleFrame {
    let temperature_source = wire_temperature_source(sample, pad);
    let temperature_c = match temperature_source {
        TemperatureSource::None => None,
        _ => Some(sample.output.temperature.temperature_c),
    };
    SampleFrame {
        sequence: sample.sequence,
        timestamp_us: sample.timestamp_us,
        temperature_c,
        temperature_source,
        taxels: sample.output.taxels.map(|taxel| TaxelSample {
            pressure_kpa: taxel.pressure_kpa(),
            capacitance_pf: taxel.capacitance_pf().unwrap_or(f32::NAN),
            flags: taxel.flags().bits(),
        }),
    }
}

/// The counters frame.
pub fn counters_frame(counters: &Counters, host: &HostCounters) -> CountersFrame {
    CountersFrame {
        dropped_sample_sets: counters.dropped_sets,
        converter_reinits: counters.converter_reinits(),
        i2c_errors: counters.i2c_errors,
        temperature_sensor_errors: counters.temperature_errors,
        frames_dropped_no_host: host.frames_dropped_no_host,
        host_frames_rejected: host.host_frames_rejected,
    }
}

/// One taxel's calibration as a wire record; `None` for a taxel index out of range.
pub fn calibration_record(
    calibration: &Calibration,
    taxel_index: u8,
) -> Option<TaxelCalibrationRecord> {
    let taxel = calibration.taxels().get(usize::from(taxel_index))?;
    Some(TaxelCalibrationRecord {
        taxel_index,
        calibration_id: calibration.id(),
        calibration: TaxelCalibrationWire {
            points: taxel
                .curve
                .points()
                .iter()
                .map(|point| (point.pressure_kpa, point.relative_change))
                .collect(),
            parasitic_pf: taxel.parasitic_pf,
        },
    })
}

/// A wire calibration as model-core plain data (validated later by the model).
pub fn taxel_calibration_spec(wire: &TaxelCalibrationWire) -> TaxelCalibrationSpec {
    TaxelCalibrationSpec {
        points: wire
            .points
            .iter()
            .map(|(pressure_kpa, relative_change)| CurvePoint::new(*pressure_kpa, *relative_change))
            .collect::<Vec<_, { model_core::calibration::MAX_CURVE_POINTS }>>(),
        parasitic_pf: wire.parasitic_pf,
    }
}
