//! Arbitrary input bits through the whole model, on the article's calibration or on a generated
//! hard one (the first 8 bytes pick it), through every tier: never a panic, never NaN or
//! infinity out, and a pressure within the curve unless the taxel is flagged as a fault.
#![no_main]

use libfuzzer_sys::fuzz_target;
use model_core::{
    Calibration, CalibrationSpec, CurvePoint, PadModel, SampleInput, TaxelReading, Tier,
};
use reference_curves::hard_calibration;

/// The article's calibration for seed 0, else a generated hard curve on every taxel.
fn calibration(seed: u64) -> Calibration {
    if seed == 0 {
        return Calibration::default();
    }
    let (points, _) = hard_calibration(seed);
    let mut spec = CalibrationSpec::default();
    for taxel in spec.taxels.iter_mut() {
        taxel.points.clear();
        for (pressure_kpa, relative_change) in &points {
            let _ = taxel
                .points
                .push(CurvePoint::new(*pressure_kpa, *relative_change));
        }
    }
    Calibration::new(&spec).unwrap_or_default()
}

fn reading(chunk: &[u8]) -> TaxelReading {
    let word = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
    match chunk[4] % 3 {
        0 => TaxelReading::CapacitancePf(f32::from_bits(word)),
        1 => TaxelReading::Raw {
            code: word as i32 >> (chunk[4] % 9),
            capdac: chunk[4],
        },
        _ => TaxelReading::Unavailable,
    }
}

fuzz_target!(|bytes: &[u8]| {
    let Some((seed, bytes)) = bytes.split_first_chunk::<8>() else {
        return;
    };
    let calibration = calibration(u64::from_le_bytes(*seed) % 4096);
    let top_kpa = calibration
        .taxels()
        .iter()
        .map(|taxel| taxel.curve().top().pressure_kpa)
        .fold(0.0f32, f32::max);
    let mut pad = PadModel::new(calibration);
    let mut chunks = bytes.chunks_exact(25);
    for (index, chunk) in chunks.by_ref().enumerate() {
        if index == 0 {
            pad.start_tare(u16::from(chunk[24] % 4));
        }
        if let Some(tier) = Tier::from_id(chunk[24] % Tier::ALL.len() as u8) {
            let _ = pad.set_tier(tier);
        }
        let readings = [
            reading(&chunk[0..5]),
            reading(&chunk[5..10]),
            reading(&chunk[10..15]),
            reading(&chunk[15..20]),
        ];
        let temperature = f32::from_bits(u32::from_le_bytes([
            chunk[20], chunk[21], chunk[22], chunk[23],
        ]));
        let output = pad.process(&SampleInput::new(readings, Some(temperature)));
        assert!(output.temperature.temperature_c.is_finite());
        for taxel in output.taxels {
            match taxel.pressure_kpa() {
                Some(pressure) => {
                    assert!(pressure.is_finite() && (0.0..=top_kpa).contains(&pressure))
                }
                None => assert!(taxel.flags().is_fault()),
            }
            if let Some(capacitance) = taxel.capacitance_pf() {
                assert!(capacitance.is_finite());
            }
            if let Some(relative) = taxel.relative_change() {
                assert!(relative.is_finite() || taxel.flags().is_fault());
            }
        }
    }
});
