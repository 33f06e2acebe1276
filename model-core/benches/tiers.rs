//! Host time per taxel conversion for every tier: `TaxelModel::convert` (temperature correction,
//! classification and inverse) and the tier's inverse alone, over the same 0–50 kPa x 5–55 °C
//! grid of raw FDC1004 readings as the on-target benchmark (m4-bench).
//!
//! Each iteration converts the whole grid as a host tool converts a recording: readings read
//! from memory, results written to memory, the model and the tier opaque to the compiler
//! (`black_box` once per pass, not per call: per-call `black_box` of the reading and the result
//! adds store-forwarding stalls on x86 that tripled the time). Criterion's time per iteration
//! divided by the grid's size (its `Elements` throughput) is the time per conversion.
//! `cargo xtask report` reads the results from criterion's JSON files. The research tiers are
//! timed only with `--features research-tiers`, which the report passes.
//!
//! Group `batch` times the host's batch path, `PadModel::process_all`, over the same grid as
//! sample sets of four taxels (each at another pressure, in a scrambled order), per taxel
//! conversion; `batch-inverse` its inverse alone (`ActiveInverse::pressures_kpa`).
//!
//! Groups `convert`, `inverse`, `batch` and `batch-inverse` measure the thread's CPU time, so
//! time slices the scheduler gives to other processes (a shared build machine) are not counted;
//! `convert-wall` measures the conversion again in wall-clock time as a cross-check.

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use model_core::{
    Baseline, Calibration, CalibrationSpec, FaultThresholds, PadModel, ReadingValue, SampleInput,
    TaxelCalibration, TaxelFlags, TaxelInverses, TaxelModel, TaxelOutput, TaxelReading,
    TemperatureTracker, Tier,
};

/// Parasitic capacitance of the benchmarked taxel, pF (as in m4-bench's grid).
const PARASITIC_PF: f32 = 6.0;
/// Unloaded sensor capacitance at 25 °C, pF.
const SENSOR_PF: f32 = 4.5;
/// CAPDAC setting of the readings (9.375 pF).
const CAPDAC: u8 = 3;

struct Grid {
    /// The tared pad every taxel's figures come from.
    pad: PadModel,
    /// The grid as sample sets: per temperature, its pressures in a scrambled order, each set's
    /// four taxels at four different pressures.
    sets: Vec<SampleInput>,
    calibration: TaxelCalibration,
    inverses: TaxelInverses,
    baseline: Baseline,
    thresholds: FaultThresholds,
    inputs: Vec<(ReadingValue, f32)>,
    relative_changes: Vec<f32>,
}

fn raw(capacitance_pf: f32) -> TaxelReading {
    let code = ((capacitance_pf - f32::from(CAPDAC) * 3.125) * 524_288.0).round() as i32;
    TaxelReading::Raw {
        code,
        capdac: CAPDAC,
    }
}

fn grid() -> Option<Grid> {
    let mut spec = CalibrationSpec::default();
    for taxel in spec.taxels.iter_mut() {
        taxel.parasitic_pf = PARASITIC_PF;
    }
    let calibration = Calibration::new(&spec).ok()?;
    let law = calibration.temperature_law().clone();
    let mut pad = PadModel::new(calibration);
    pad.start_tare(1);
    pad.process(&SampleInput::new(
        [raw(PARASITIC_PF + SENSOR_PF); 4],
        Some(25.0),
    ));
    let model = pad.taxel(0)?.clone();
    let taxel_calibration = pad.calibration().taxels()[0].clone();
    let inverses = TaxelInverses::new(taxel_calibration.curve());
    let baseline = pad.baselines()[0]?;
    let thresholds = *pad.calibration().thresholds();
    let mut inputs = Vec::new();
    let mut relative_changes = Vec::new();
    let mut sets = Vec::new();
    for temperature_step in 0..=10 {
        let temperature_c = 5.0 + 5.0 * temperature_step as f32;
        let used = TemperatureTracker::default().resolve(Some(temperature_c), None, &law);
        let inverse_ratio = 1.0 / used.permittivity_ratio;
        for pressure_step in 0..=100 {
            let pressure_kpa = 0.5 * pressure_step as f32;
            let relative_change = inverses.relative_change_at(pressure_kpa);
            let capacitance_pf =
                PARASITIC_PF + SENSOR_PF * (1.0 + relative_change) * used.permittivity_ratio;
            let value = raw(capacitance_pf).value();
            inputs.push((value, inverse_ratio));
            let output = model.convert(
                &taxel_calibration,
                value,
                Some(&baseline),
                inverse_ratio,
                &thresholds,
            );
            relative_changes.push(output.relative_change().unwrap_or(0.0));
        }
        // 37 is coprime with the 101 pressures: each taxel visits every pressure once per
        // temperature, in an order no predictor follows.
        let reading_at = |step: usize| {
            let pressure_kpa = 0.5 * ((step * 37) % 101) as f32;
            let relative_change = inverses.relative_change_at(pressure_kpa);
            raw(PARASITIC_PF + SENSOR_PF * (1.0 + relative_change) * used.permittivity_ratio)
        };
        for step in 0..=100 {
            let readings = [0, 25, 50, 75].map(|offset| reading_at(step + offset));
            sets.push(SampleInput::new(readings, Some(temperature_c)));
        }
    }
    Some(Grid {
        pad,
        sets,
        calibration: taxel_calibration,
        inverses,
        baseline,
        thresholds,
        inputs,
        relative_changes,
    })
}

/// CPU time of the benchmarking thread (criterion's formatting of durations).
struct ThreadCpuTime {
    wall: WallTime,
}

impl Measurement for ThreadCpuTime {
    type Intermediate = cpu_time::ThreadTime;
    type Value = Duration;

    fn start(&self) -> Self::Intermediate {
        cpu_time::ThreadTime::now()
    }

    fn end(&self, start: Self::Intermediate) -> Self::Value {
        start.elapsed()
    }

    fn add(&self, first: &Self::Value, second: &Self::Value) -> Self::Value {
        *first + *second
    }

    fn zero(&self) -> Self::Value {
        Duration::ZERO
    }

    fn to_f64(&self, value: &Self::Value) -> f64 {
        value.as_nanos() as f64
    }

    fn formatter(&self) -> &dyn ValueFormatter {
        self.wall.formatter()
    }
}

fn convert_group<M: Measurement>(criterion: &mut Criterion<M>, name: &str, grid: &Grid) {
    let mut convert = criterion.benchmark_group(name);
    convert.throughput(Throughput::Elements(grid.inputs.len() as u64));
    let mut outputs = vec![TaxelOutput::fault(TaxelFlags::empty(), None); grid.inputs.len()];
    for tier in Tier::ALL {
        let Some(model) = TaxelModel::with_tier(&grid.calibration, tier) else {
            continue;
        };
        convert.bench_function(tier.name(), |bencher| {
            bencher.iter(|| {
                let model = black_box(&model);
                for ((value, inverse_ratio), output) in grid.inputs.iter().zip(outputs.iter_mut()) {
                    *output = model.convert(
                        &grid.calibration,
                        *value,
                        Some(&grid.baseline),
                        *inverse_ratio,
                        &grid.thresholds,
                    );
                }
                black_box(&mut outputs);
            })
        });
    }
    convert.finish();
}

fn inverse_group<M: Measurement>(criterion: &mut Criterion<M>, grid: &Grid) {
    let mut inverse = criterion.benchmark_group("inverse");
    inverse.throughput(Throughput::Elements(grid.relative_changes.len() as u64));
    let mut outputs = vec![0.0f32; grid.relative_changes.len()];
    // Only the tiers this build has (`--features research-tiers` for all of them): another would
    // time the default tier's fallback under its name.
    for tier in Tier::ALL
        .into_iter()
        .filter(|tier| grid.inverses.supports(*tier))
    {
        inverse.bench_function(tier.name(), |bencher| {
            bencher.iter(|| {
                let inverses = black_box(&grid.inverses);
                let tier = black_box(tier);
                for (relative_change, output) in
                    grid.relative_changes.iter().zip(outputs.iter_mut())
                {
                    *output = inverses.pressure_kpa(tier, *relative_change);
                }
                black_box(&mut outputs);
            })
        });
    }
    inverse.finish();
}

/// `PadModel::process_all`, the host's batch path, over the grid's sample sets: time per taxel
/// conversion (the whole model of a set, a quarter each), with the batch inverse alone beside it.
fn batch_group<M: Measurement>(criterion: &mut Criterion<M>, grid: &Grid) {
    let mut batch = criterion.benchmark_group("batch");
    batch.throughput(Throughput::Elements(4 * grid.sets.len() as u64));
    for tier in Tier::ALL {
        let mut pad = grid.pad.clone();
        if pad.set_tier(tier).is_err() {
            continue;
        }
        batch.bench_function(tier.name(), |bencher| {
            bencher.iter_batched_ref(
                || pad.clone(),
                |pad| {
                    let mut sum_kpa = 0.0f32;
                    black_box(pad).process_all(grid.sets.iter().copied(), |_, output| {
                        sum_kpa += output.taxels[0].pressure_kpa().unwrap_or(0.0);
                    });
                    black_box(sum_kpa);
                },
                criterion::BatchSize::SmallInput,
            )
        });
    }
    batch.finish();
    let mut batch_inverse = criterion.benchmark_group("batch-inverse");
    batch_inverse.throughput(Throughput::Elements(grid.relative_changes.len() as u64));
    let mut values = grid.relative_changes.clone();
    for tier in Tier::ALL {
        let Some(model) = TaxelModel::with_tier(&grid.calibration, tier) else {
            continue;
        };
        batch_inverse.bench_function(tier.name(), |bencher| {
            bencher.iter(|| {
                values.copy_from_slice(&grid.relative_changes);
                for chunk in values.chunks_mut(model_core::BATCH_SAMPLE_SETS) {
                    black_box(&model)
                        .inverse()
                        .pressures_kpa(grid.calibration.curve(), chunk);
                }
                black_box(&mut values);
            })
        });
    }
    batch_inverse.finish();
}

fn grid_or_exit() -> Grid {
    grid().unwrap_or_else(|| {
        eprintln!("the default calibration or its tare was refused");
        std::process::exit(1);
    })
}

fn cpu_time(criterion: &mut Criterion<ThreadCpuTime>) {
    let grid = grid_or_exit();
    convert_group(criterion, "convert", &grid);
    inverse_group(criterion, &grid);
    batch_group(criterion, &grid);
}

fn wall_time(criterion: &mut Criterion) {
    convert_group(criterion, "convert-wall", &grid_or_exit());
}

criterion_group! {
    name = cpu_time_benches;
    config = Criterion::default()
        .with_measurement(ThreadCpuTime { wall: WallTime })
        .sample_size(50)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = cpu_time
}
criterion_group! {
    name = wall_time_benches;
    config = Criterion::default()
        .sample_size(50)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = wall_time
}
criterion_main!(cpu_time_benches, wall_time_benches);
