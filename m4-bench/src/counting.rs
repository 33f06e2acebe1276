//! Instruction counts from SysTick under `qemu -icount shift=0`: virtual time advances 1 ns per
//! executed instruction and SysTick runs from the 25 MHz processor clock, so one tick is exactly
//! 40 instructions. A count is (ticks around `calls` calls - ticks around the same loop with the
//! call replaced by `black_box` of its inputs) x 40 / calls.

use core::hint::black_box;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use model_core::inverse::{InverseCurve, TableInverse};
use model_core::{
    Baseline, FaultThresholds, PadModel, PadOutput, ReadingValue, SampleInput, SplitCapacitance,
    TaxelCalibration, TaxelFlags, TaxelInverses, TaxelModel, TaxelOutput, TemperatureLaw,
    TemperatureTracker, TemperatureUsed, Tier,
};

/// Instructions per SysTick tick with `-icount shift=0` and a 25 MHz SysTick.
pub const INSTRUCTIONS_PER_TICK: u64 = 40;

const RELOAD: u32 = 0x00FF_FFFF;

/// SysTick as a free-running 24-bit down-counter.
pub struct Counter {
    _syst: SYST,
}

impl Counter {
    /// Starts SysTick from the processor clock, no interrupt.
    pub fn new(mut syst: SYST) -> Self {
        syst.disable_interrupt();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        syst.enable_counter();
        Self { _syst: syst }
    }

    /// Instructions executed by `work` (a region must stay under 2^24 ticks, 0.67 G
    /// instructions).
    pub fn instructions(&self, work: impl FnOnce()) -> u64 {
        let start = SYST::get_current();
        work();
        let end = SYST::get_current();
        u64::from(start.wrapping_sub(end) & RELOAD) * INSTRUCTIONS_PER_TICK
    }

    /// Instructions per call: `(work - overhead) / calls`.
    pub fn per_call(&self, calls: u32, work: impl FnOnce(), overhead: impl FnOnce()) -> f32 {
        let work = self.instructions(work) as f32;
        let overhead = self.instructions(overhead) as f32;
        (work - overhead) / calls.max(1) as f32
    }
}

/// One prepared conversion input: a classified reading and the sample's temperature factor.
#[derive(Clone, Copy)]
pub struct Input {
    /// The classified reading.
    pub value: ReadingValue,
    /// eps(25 °C) / eps(T).
    pub inverse_permittivity_ratio: f32,
}

impl Default for Input {
    fn default() -> Self {
        Self {
            value: ReadingValue::Unavailable,
            inverse_permittivity_ratio: 1.0,
        }
    }
}

/// What one conversion needs besides its input.
#[derive(Clone, Copy)]
pub struct Context<'a> {
    /// The taxel's model (with the tier being counted).
    pub model: &'a TaxelModel,
    /// The taxel's calibration.
    pub calibration: &'a TaxelCalibration,
    /// Its baseline.
    pub baseline: &'a Baseline,
    /// Fault thresholds.
    pub thresholds: &'a FaultThresholds,
}

/// `TaxelModel::convert` over `inputs`, `repetitions` times.
#[inline(never)]
pub fn convert_loop(context: Context<'_>, inputs: &[Input], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            let output = black_box(context.model).convert(
                black_box(context.calibration),
                black_box(input.value),
                Some(black_box(context.baseline)),
                black_box(input.inverse_permittivity_ratio),
                black_box(context.thresholds),
            );
            black_box(output);
        }
    }
}

/// [`convert_loop`] without the conversion.
#[inline(never)]
pub fn convert_overhead_loop(context: Context<'_>, inputs: &[Input], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            black_box(context.model);
            black_box(context.calibration);
            black_box(input.value);
            black_box(context.baseline);
            black_box(input.inverse_permittivity_ratio);
            black_box(context.thresholds);
            black_box(TaxelOutput::fault(TaxelFlags::empty(), None));
        }
    }
}

/// `TaxelInverses::pressure_kpa` (the tier dispatch and the inverse alone) over `inputs`.
#[inline(never)]
pub fn inverse_loop(inverses: &TaxelInverses, tier: Tier, inputs: &[f32], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            black_box(black_box(inverses).pressure_kpa(black_box(tier), black_box(*input)));
        }
    }
}

/// The table's `InverseCurve::pressure_kpa` called directly (no dispatch).
#[inline(never)]
pub fn table_loop(table: &TableInverse, inputs: &[f32], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            black_box(black_box(table).pressure_kpa(black_box(*input)));
        }
    }
}

/// A tier's inverse called directly (no dC/C0, no dispatch) over `inputs`.
#[inline(never)]
pub fn direct_inverse_loop<I: InverseCurve>(inverse: &I, inputs: &[f32], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            black_box(black_box(inverse).pressure_kpa(black_box(*input)));
        }
    }
}

/// `TaxelReading::value` (the raw-code decode and range checks) of taxel 0's reading of each
/// sample.
#[inline(never)]
pub fn reading_value_loop(samples: &[SampleInput], repetitions: u32) {
    for _ in 0..repetitions {
        for sample in samples {
            black_box(black_box(sample.readings[0]).value());
        }
    }
}

/// [`reading_value_loop`] without the decode.
#[inline(never)]
pub fn reading_value_overhead_loop(samples: &[SampleInput], repetitions: u32) {
    for _ in 0..repetitions {
        for sample in samples {
            black_box(sample.readings[0]);
            black_box(ReadingValue::Unavailable);
        }
    }
}

/// `TemperatureTracker::resolve` (once per sample set in `PadModel::process`) with a tracker
/// that last saw the same temperature: the steady state.
#[inline(never)]
pub fn temperature_loop(
    trackers: &[(TemperatureTracker, f32)],
    law: &TemperatureLaw,
    repetitions: u32,
) {
    for _ in 0..repetitions {
        for (tracker, temperature_c) in trackers {
            let mut tracker = black_box(*tracker);
            black_box(tracker.resolve(
                black_box(Some(*temperature_c)),
                black_box(Some(25.0)),
                black_box(law),
            ));
        }
    }
}

/// [`temperature_loop`] without the call.
#[inline(never)]
pub fn temperature_overhead_loop(
    trackers: &[(TemperatureTracker, f32)],
    law: &TemperatureLaw,
    repetitions: u32,
) {
    let used = TemperatureUsed {
        temperature_c: 25.0,
        permittivity_ratio: 1.0,
        flags: TaxelFlags::empty(),
    };
    for _ in 0..repetitions {
        for (tracker, temperature_c) in trackers {
            black_box(*tracker);
            black_box(Some(*temperature_c));
            black_box(Some(25.0f32));
            black_box(law);
            black_box(used);
        }
    }
}

/// One taxel's temperature-corrected inversion: dC/C0 from the split capacitance, the baseline
/// and the sample's temperature factor (`Baseline::relative_change`), then a tier's inverse
/// called directly, as a build fixed to one tier runs it. Fault classification and the output
/// record are not in it (they are in [`convert_loop`]).
#[inline(never)]
pub fn corrected_inversion_loop<I: InverseCurve>(
    inverse: &I,
    baseline: &Baseline,
    inputs: &[(SplitCapacitance, f32)],
    repetitions: u32,
) {
    for _ in 0..repetitions {
        for (capacitance, inverse_permittivity_ratio) in inputs {
            let relative_change = black_box(baseline).relative_change(
                black_box(*capacitance),
                black_box(*inverse_permittivity_ratio),
            );
            black_box(black_box(inverse).pressure_kpa(relative_change));
        }
    }
}

/// [`corrected_inversion_loop`] with the tier chosen at run time (`TaxelInverses::pressure_kpa`).
#[inline(never)]
pub fn corrected_inversion_dispatched_loop(
    inverses: &TaxelInverses,
    tier: Tier,
    baseline: &Baseline,
    inputs: &[(SplitCapacitance, f32)],
    repetitions: u32,
) {
    for _ in 0..repetitions {
        for (capacitance, inverse_permittivity_ratio) in inputs {
            let relative_change = black_box(baseline).relative_change(
                black_box(*capacitance),
                black_box(*inverse_permittivity_ratio),
            );
            black_box(black_box(inverses).pressure_kpa(black_box(tier), relative_change));
        }
    }
}

/// `Baseline::relative_change` alone: the dC/C0 part of [`corrected_inversion_loop`], the floor
/// under every tier's corrected inversion.
#[inline(never)]
pub fn relative_change_loop(
    baseline: &Baseline,
    inputs: &[(SplitCapacitance, f32)],
    repetitions: u32,
) {
    for _ in 0..repetitions {
        for (capacitance, inverse_permittivity_ratio) in inputs {
            black_box(black_box(baseline).relative_change(
                black_box(*capacitance),
                black_box(*inverse_permittivity_ratio),
            ));
        }
    }
}

/// The loops of [`corrected_inversion_loop`] and [`relative_change_loop`] without the work.
#[inline(never)]
pub fn corrected_inversion_overhead_loop(
    baseline: &Baseline,
    inputs: &[(SplitCapacitance, f32)],
    repetitions: u32,
) {
    for _ in 0..repetitions {
        for (capacitance, inverse_permittivity_ratio) in inputs {
            black_box(baseline);
            black_box(*capacitance);
            black_box(black_box(*inverse_permittivity_ratio));
        }
    }
}

/// An f32 function of one f32 over `inputs` (generic, so the call is direct, as in real code).
#[inline(never)]
pub fn function_loop<F: Fn(f32) -> f32>(function: F, inputs: &[f32], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            black_box(function(black_box(*input)));
        }
    }
}

/// The loop of [`inverse_loop`], [`table_loop`] and [`function_loop`] without the call.
#[inline(never)]
pub fn f32_overhead_loop(inputs: &[f32], repetitions: u32) {
    for _ in 0..repetitions {
        for input in inputs {
            black_box(black_box(*input));
        }
    }
}

/// `PadModel::process` (four taxels, temperature resolution, tare and tracking checks) over
/// `samples`.
#[inline(never)]
pub fn pad_loop(pad: &mut PadModel, samples: &[SampleInput], repetitions: u32) {
    for _ in 0..repetitions {
        for sample in samples {
            black_box(black_box(&mut *pad).process(black_box(sample)));
        }
    }
}

/// [`pad_loop`] without the call.
#[inline(never)]
pub fn pad_overhead_loop(pad: &mut PadModel, samples: &[SampleInput], repetitions: u32) {
    let output = PadOutput {
        taxels: [TaxelOutput::fault(TaxelFlags::empty(), None); 4],
        temperature: TemperatureUsed {
            temperature_c: 25.0,
            permittivity_ratio: 1.0,
            flags: TaxelFlags::empty(),
        },
    };
    for _ in 0..repetitions {
        for sample in samples {
            black_box(black_box(&mut *pad));
            black_box(sample);
            black_box(output);
        }
    }
}
