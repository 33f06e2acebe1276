//! On-target test and benchmark of model-core on a Cortex-M4F emulated by QEMU (mps2-an386):
//! every tier over a 0–50 kPa x 5–55 °C grid of raw FDC1004 readings and over the hard cases,
//! the default tier's inverse on the hard calibrations, against f64 references computed on the
//! host (golden file from the build script), then the instructions per taxel conversion from
//! SysTick under `-icount shift=0`.
//!
//! Prints one `key=value` line per result over semihosting and exits with status 0 only if every
//! check passed. `cargo xtask m4-test` builds, runs and parses it.
#![no_std]
#![no_main]

mod checks;
mod counting;
// Shared with build.rs, which uses the encoding half.
#[allow(dead_code)]
mod format;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use model_core::inverse::{Libm, Micromath, SaturatingInverse};
use model_core::{
    Baseline, InverseCurve, ReadingValue, SampleInput, SplitCapacitance, TaxelInverses,
    TaxelReading, TemperatureTracker, Tier,
};
use panic_semihosting as _;

use counting::{Context, Counter, Input};
use format::Header;

/// The golden vectors, written by build.rs.
static GOLDEN: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/golden.bin"));

/// Most grid points the benchmark keeps (the generator writes 101 x 11).
const GRID_CAPACITY: usize = 1111;
/// Inputs measured one by one for the min/max: whole kPa at 25 °C.
const SINGLE_CAPACITY: usize = 51;
/// Repetitions of the whole grid for the mean.
const GRID_REPETITIONS: u32 = 4;
/// Repetitions of one input for its own count (40 / 64 = 0.6 instruction resolution).
const SINGLE_REPETITIONS: u32 = 64;

#[entry]
fn main() -> ! {
    let misses = run();
    hprintln!(
        "summary misses={} result={}",
        misses,
        if misses == 0 { "pass" } else { "fail" }
    );
    debug::exit(if misses == 0 {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    #[allow(clippy::empty_loop)]
    loop {}
}

fn run() -> u32 {
    let Some(header) = Header::decode(GOLDEN).filter(|header| header.file_bytes() == GOLDEN.len())
    else {
        hprintln!("error: golden file unreadable");
        return 1;
    };
    hprintln!(
        "m4-bench opt-level={} grid_points={} hard_cases={} hard_calibrations={} grid_repetitions={} single_repetitions={}",
        env!("M4_BENCH_OPT_LEVEL"),
        header.grid_count,
        header.hard_case_count,
        header.hard_calibration_count,
        GRID_REPETITIONS,
        SINGLE_REPETITIONS
    );
    let Some(taxel) = checks::GridTaxel::new(&header.grid_setup) else {
        hprintln!("error: the grid's calibration or tare was refused");
        return 1;
    };
    // Decided at run time, so that both builds hold the same code: the trace of the one then
    // describes the instructions counted in the other.
    if core::hint::black_box(cfg!(feature = "instruction-mix")) {
        return instruction_mix_probe(&header, &taxel);
    }
    let mut misses = checks::grid(GOLDEN, &header, &taxel);
    misses += checks::hard_cases(GOLDEN, &header);
    misses += checks::hard_calibrations(GOLDEN, &header);
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        hprintln!("error: peripherals already taken");
        return misses + 1;
    };
    misses + count(&Counter::new(peripherals.SYST), &header, &taxel)
}

/// The benchmark's inputs, prepared from the grid records.
struct Inputs {
    grid: [Input; GRID_CAPACITY],
    relative_changes: [f32; GRID_CAPACITY],
    samples: [SampleInput; GRID_CAPACITY],
    trackers: [(TemperatureTracker, f32); GRID_CAPACITY],
    grid_count: usize,
    single: [Input; SINGLE_CAPACITY],
    single_count: usize,
}

impl Inputs {
    fn new(header: &Header, taxel: &checks::GridTaxel) -> Option<Self> {
        let mut inputs = Self {
            grid: [Input::default(); GRID_CAPACITY],
            relative_changes: [0.0; GRID_CAPACITY],
            samples: [SampleInput::new([TaxelReading::Unavailable; 4], None); GRID_CAPACITY],
            trackers: [(TemperatureTracker::default(), 25.0); GRID_CAPACITY],
            grid_count: 0,
            single: [Input::default(); SINGLE_CAPACITY],
            single_count: 0,
        };
        for index in 0..(header.grid_count as usize).min(GRID_CAPACITY) {
            let record = checks::grid_record(GOLDEN, header, index)?;
            let input = Input {
                value: record.reading.value(),
                inverse_permittivity_ratio: taxel.inverse_permittivity_ratio(record.temperature_c),
            };
            let slot = inputs.grid_count;
            inputs.grid[slot] = input;
            inputs.relative_changes[slot] = taxel
                .model(Tier::default())?
                .convert(
                    taxel.taxel_calibration(),
                    input.value,
                    Some(&taxel.baseline),
                    input.inverse_permittivity_ratio,
                    taxel.calibration.thresholds(),
                )
                .relative_change()
                .unwrap_or(0.0);
            inputs.samples[slot] =
                SampleInput::new([record.reading; 4], Some(record.temperature_c));
            let mut tracker = TemperatureTracker::default();
            tracker.resolve(
                Some(record.temperature_c),
                None,
                taxel.calibration.temperature_law(),
            );
            inputs.trackers[slot] = (tracker, record.temperature_c);
            inputs.grid_count += 1;
            let whole_kpa = record.pressure_kpa == libm::roundf(record.pressure_kpa);
            if record.temperature_c == 25.0 && whole_kpa && inputs.single_count < SINGLE_CAPACITY {
                inputs.single[inputs.single_count] = input;
                inputs.single_count += 1;
            }
        }
        Some(inputs)
    }
}

/// The instruction-mix probe: each tier's conversion once over the single inputs, then the
/// same loop without it, and nothing else, so that `qemu -d exec,in_asm` with an address filter
/// on these two loops (and what they call) traces exactly them.
fn instruction_mix_probe(header: &Header, taxel: &checks::GridTaxel) -> u32 {
    let Some(inputs) = Inputs::new(header, taxel) else {
        return 1;
    };
    let single = &inputs.single[..inputs.single_count];
    for tier in Tier::ALL {
        let Some(context) = taxel_context(taxel, tier) else {
            hprintln!("error: tier {} unavailable for the grid taxel", tier.name());
            return 1;
        };
        counting::convert_loop(context, single, 1);
        counting::convert_overhead_loop(context, single, 1);
    }
    let mut capacitances = [(SplitCapacitance::default(), 1.0f32); SINGLE_CAPACITY];
    let capacitance_count = capacitance_inputs(single, &mut capacitances);
    let capacitances = &capacitances[..capacitance_count];
    let inverses = &taxel.inverses;
    let top_pressure_kpa = taxel.calibration.taxels()[0].curve().top().pressure_kpa;
    for tier in Tier::ALL {
        let mut probe = DirectProbe {
            baseline: &taxel.baseline,
            capacitances,
        };
        if with_direct_inverse(inverses, tier, top_pressure_kpa, &mut probe).is_none() {
            hprintln!("error: tier {} unavailable for the grid taxel", tier.name());
            return 1;
        }
    }
    counting::relative_change_loop(&taxel.baseline, capacitances, 1);
    counting::corrected_inversion_overhead_loop(&taxel.baseline, capacitances, 1);
    hprintln!(
        "mix tiers={} inputs_per_tier={} corrected_inputs={}",
        Tier::ALL.len(),
        single.len(),
        capacitances.len()
    );
    0
}

/// The capacitance readings among `inputs` with their temperature factors; returns how many.
fn capacitance_inputs(inputs: &[Input], capacitances: &mut [(SplitCapacitance, f32)]) -> usize {
    let mut count = 0;
    for input in inputs {
        if let (ReadingValue::Capacitance(capacitance), Some(slot)) =
            (input.value, capacitances.get_mut(count))
        {
            *slot = (capacitance, input.inverse_permittivity_ratio);
            count += 1;
        }
    }
    count
}

/// Something done with one tier's inverse called directly: generic over the inverse, so the
/// call is static and inlined as in a build fixed to one tier.
trait DirectInverseAction {
    /// Does it with `inverse`.
    fn run<I: InverseCurve>(&mut self, inverse: &I) -> f32;
}

/// Runs `action` with a tier's inverse (the saturating ones built from the fit with their
/// backend); `None` when the taxel's curve does not support the tier.
fn with_direct_inverse<A: DirectInverseAction>(
    inverses: &TaxelInverses,
    tier: Tier,
    top_pressure_kpa: f32,
    action: &mut A,
) -> Option<f32> {
    match tier {
        Tier::Linear => Some(action.run(inverses.linear())),
        Tier::PiecewiseLinear => Some(action.run(inverses.piecewise_linear())),
        Tier::MonotoneCubic => Some(action.run(inverses.monotone_cubic())),
        Tier::Table => Some(action.run(inverses.table())),
        Tier::Polynomial => inverses
            .polynomial()
            .map(|polynomial| action.run(polynomial)),
        Tier::Saturating => inverses
            .saturating_fit()
            .map(|fit| action.run(&SaturatingInverse::<Libm>::new(fit, top_pressure_kpa))),
        Tier::SaturatingMicromath => inverses
            .saturating_fit()
            .map(|fit| action.run(&SaturatingInverse::<Micromath>::new(fit, top_pressure_kpa))),
    }
}

/// Counts the corrected inversion through an inverse called directly.
struct DirectCount<'a> {
    counter: &'a Counter,
    baseline: &'a Baseline,
    capacitances: &'a [(SplitCapacitance, f32)],
    calls: u32,
}

impl DirectInverseAction for DirectCount<'_> {
    fn run<I: InverseCurve>(&mut self, inverse: &I) -> f32 {
        let (baseline, capacitances) = (self.baseline, self.capacitances);
        self.counter.per_call(
            self.calls,
            || {
                counting::corrected_inversion_loop(
                    inverse,
                    baseline,
                    capacitances,
                    GRID_REPETITIONS,
                )
            },
            || {
                counting::corrected_inversion_overhead_loop(
                    baseline,
                    capacitances,
                    GRID_REPETITIONS,
                )
            },
        )
    }
}

/// Counts an inverse called directly, alone (no dC/C0, no dispatch).
struct InverseAloneCount<'a> {
    counter: &'a Counter,
    relative_changes: &'a [f32],
    calls: u32,
}

impl DirectInverseAction for InverseAloneCount<'_> {
    fn run<I: InverseCurve>(&mut self, inverse: &I) -> f32 {
        let relative_changes = self.relative_changes;
        self.counter.per_call(
            self.calls,
            || counting::direct_inverse_loop(inverse, relative_changes, GRID_REPETITIONS),
            || counting::f32_overhead_loop(relative_changes, GRID_REPETITIONS),
        )
    }
}

/// Runs the corrected inversion once over the inputs, then the empty loop, for the trace.
struct DirectProbe<'a> {
    baseline: &'a Baseline,
    capacitances: &'a [(SplitCapacitance, f32)],
}

impl DirectInverseAction for DirectProbe<'_> {
    fn run<I: InverseCurve>(&mut self, inverse: &I) -> f32 {
        counting::corrected_inversion_loop(inverse, self.baseline, self.capacitances, 1);
        counting::corrected_inversion_overhead_loop(self.baseline, self.capacitances, 1);
        0.0
    }
}

/// What converting with the grid's taxel and a tier needs besides the input.
fn taxel_context(taxel: &checks::GridTaxel, tier: Tier) -> Option<Context<'_>> {
    Some(Context {
        model: taxel.model(tier)?,
        calibration: taxel.taxel_calibration(),
        baseline: &taxel.baseline,
        thresholds: taxel.calibration.thresholds(),
    })
}

fn count(counter: &Counter, header: &Header, taxel: &checks::GridTaxel) -> u32 {
    let Some(inputs) = Inputs::new(header, taxel) else {
        return 1;
    };
    let grid_count = inputs.grid_count;
    let (grid, relative_changes, single) = (
        &inputs.grid[..grid_count],
        &inputs.relative_changes[..grid_count],
        &inputs.single[..inputs.single_count],
    );
    let grid_calls = grid_count as u32 * GRID_REPETITIONS;

    for tier in Tier::ALL {
        let Some(context) = taxel_context(taxel, tier) else {
            hprintln!("error: tier {} unavailable for the grid taxel", tier.name());
            return 1;
        };
        let mean = counter.per_call(
            grid_calls,
            || counting::convert_loop(context, grid, GRID_REPETITIONS),
            || counting::convert_overhead_loop(context, grid, GRID_REPETITIONS),
        );
        let (mut minimum, mut maximum, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0);
        for input in single {
            let one = core::slice::from_ref(input);
            let instructions = counter.per_call(
                SINGLE_REPETITIONS,
                || counting::convert_loop(context, one, SINGLE_REPETITIONS),
                || counting::convert_overhead_loop(context, one, SINGLE_REPETITIONS),
            );
            minimum = minimum.min(instructions);
            maximum = maximum.max(instructions);
            sum += instructions;
        }
        hprintln!(
            "count subject=convert tier={} mean={:.2} min={:.2} max={:.2} single_mean={:.2} calls={} single_inputs={}",
            tier.name(),
            mean,
            minimum,
            maximum,
            sum / single.len().max(1) as f32,
            grid_calls,
            single.len()
        );
    }

    let inverses = &taxel.inverses;
    let top_pressure_kpa = taxel.calibration.taxels()[0].curve().top().pressure_kpa;
    for tier in Tier::ALL {
        let mean = counter.per_call(
            grid_calls,
            || counting::inverse_loop(inverses, tier, relative_changes, GRID_REPETITIONS),
            || counting::f32_overhead_loop(relative_changes, GRID_REPETITIONS),
        );
        let mut alone = InverseAloneCount {
            counter,
            relative_changes,
            calls: grid_calls,
        };
        let Some(direct) = with_direct_inverse(inverses, tier, top_pressure_kpa, &mut alone) else {
            hprintln!("error: tier {} unavailable for the grid taxel", tier.name());
            return 1;
        };
        hprintln!(
            "count subject=inverse tier={} mean={:.2} direct={:.2} calls={}",
            tier.name(),
            mean,
            direct,
            grid_calls
        );
    }
    let mut capacitances = [(SplitCapacitance::default(), 1.0f32); GRID_CAPACITY];
    let capacitance_count = capacitance_inputs(grid, &mut capacitances);
    let capacitances = &capacitances[..capacitance_count];
    let corrected_calls = capacitance_count as u32 * GRID_REPETITIONS;
    let baseline = &taxel.baseline;
    let overhead =
        || counting::corrected_inversion_overhead_loop(baseline, capacitances, GRID_REPETITIONS);
    for tier in Tier::ALL {
        let mut direct_count = DirectCount {
            counter,
            baseline,
            capacitances,
            calls: corrected_calls,
        };
        let Some(direct) = with_direct_inverse(inverses, tier, top_pressure_kpa, &mut direct_count)
        else {
            hprintln!("error: tier {} unavailable for the grid taxel", tier.name());
            return 1;
        };
        let dispatched = counter.per_call(
            corrected_calls,
            || {
                counting::corrected_inversion_dispatched_loop(
                    inverses,
                    tier,
                    baseline,
                    capacitances,
                    GRID_REPETITIONS,
                )
            },
            overhead,
        );
        hprintln!(
            "count subject=corrected-inversion tier={} mean={:.2} dispatched={:.2} calls={}",
            tier.name(),
            direct,
            dispatched,
            corrected_calls
        );
    }

    let relative_change = counter.per_call(
        corrected_calls,
        || counting::relative_change_loop(baseline, capacitances, GRID_REPETITIONS),
        overhead,
    );
    hprintln!(
        "count subject=relative-change mean={:.2} calls={}",
        relative_change,
        corrected_calls
    );

    let table = counter.per_call(
        grid_calls,
        || counting::table_loop(inverses.table(), relative_changes, GRID_REPETITIONS),
        || counting::f32_overhead_loop(relative_changes, GRID_REPETITIONS),
    );
    hprintln!(
        "count subject=table-direct mean={:.2} calls={}",
        table,
        grid_calls
    );

    let mut logarithm_inputs = [0.0f32; 64];
    let mut exponential_inputs = [0.0f32; 64];
    for (index, (logarithm, exponential)) in logarithm_inputs
        .iter_mut()
        .zip(exponential_inputs.iter_mut())
        .enumerate()
    {
        *logarithm = 1.0 + 7.0 * index as f32 / 63.0;
        *exponential = -5.0 * index as f32 / 63.0;
    }
    let functions_calls = 64 * GRID_REPETITIONS;
    let functions: [(&str, f32); 4] = [
        (
            "libm-logf",
            counter.per_call(
                functions_calls,
                || counting::function_loop(libm::logf, &logarithm_inputs, GRID_REPETITIONS),
                || counting::f32_overhead_loop(&logarithm_inputs, GRID_REPETITIONS),
            ),
        ),
        (
            "libm-expf",
            counter.per_call(
                functions_calls,
                || counting::function_loop(libm::expf, &exponential_inputs, GRID_REPETITIONS),
                || counting::f32_overhead_loop(&exponential_inputs, GRID_REPETITIONS),
            ),
        ),
        (
            "micromath-ln",
            counter.per_call(
                functions_calls,
                || {
                    counting::function_loop(
                        micromath::F32Ext::ln,
                        &logarithm_inputs,
                        GRID_REPETITIONS,
                    )
                },
                || counting::f32_overhead_loop(&logarithm_inputs, GRID_REPETITIONS),
            ),
        ),
        (
            "f32-min",
            counter.per_call(
                functions_calls,
                || {
                    counting::function_loop(
                        |x: f32| x.min(4.0),
                        &logarithm_inputs,
                        GRID_REPETITIONS,
                    )
                },
                || counting::f32_overhead_loop(&logarithm_inputs, GRID_REPETITIONS),
            ),
        ),
    ];
    for (name, mean) in functions {
        hprintln!(
            "count subject={} mean={:.2} calls={}",
            name,
            mean,
            functions_calls
        );
    }

    let samples = &inputs.samples[..grid_count];
    let reading_value = counter.per_call(
        grid_calls,
        || counting::reading_value_loop(samples, GRID_REPETITIONS),
        || counting::reading_value_overhead_loop(samples, GRID_REPETITIONS),
    );
    hprintln!(
        "count subject=reading-value mean={:.2} calls={}",
        reading_value,
        grid_calls
    );
    let trackers = &inputs.trackers[..grid_count];
    let law = taxel.calibration.temperature_law();
    let temperature = counter.per_call(
        grid_calls,
        || counting::temperature_loop(trackers, law, GRID_REPETITIONS),
        || counting::temperature_overhead_loop(trackers, law, GRID_REPETITIONS),
    );
    hprintln!(
        "count subject=temperature-resolve mean={:.2} calls={}",
        temperature,
        grid_calls
    );

    let Some(mut pad) = checks::tared_pad(&header.grid_setup) else {
        return 1;
    };
    let mut misses = 0;
    for tier in Tier::ALL {
        if pad.set_tier(tier).is_err() {
            hprintln!("error: tier {} unavailable for the pad", tier.name());
            misses += 1;
            continue;
        }
        // Block by block of one temperature, the pad brought to it first in plausible steps
        // (uncounted), so that every counted sample set is the steady state of a pad at that
        // temperature, not the slew after an implausible jump between blocks.
        let (mut work, mut overhead, mut sets) = (0u64, 0u64, 0u32);
        let mut start = 0;
        while start < samples.len() {
            let temperature_c = samples[start].temperature_c;
            let length = samples[start..]
                .iter()
                .take_while(|sample| sample.temperature_c == temperature_c)
                .count();
            let block = &samples[start..start + length];
            if let Some(target_c) = temperature_c {
                checks::warm_up(&mut pad, &header.grid_setup, target_c);
            }
            work += counter.instructions(|| counting::pad_loop(&mut pad, block, GRID_REPETITIONS));
            overhead += counter
                .instructions(|| counting::pad_overhead_loop(&mut pad, block, GRID_REPETITIONS));
            sets += length as u32 * GRID_REPETITIONS;
            start += length;
        }
        let per_set = (work as f32 - overhead as f32) / sets.max(1) as f32;
        hprintln!(
            "count subject=pad-process tier={} per_set={:.2} mean={:.2} calls={}",
            tier.name(),
            per_set,
            per_set / 4.0,
            sets
        );
    }
    // The SetUseCase command's work: every supported tier's error on all four taxels.
    let selection = counter.instructions(|| {
        let _ = core::hint::black_box(
            core::hint::black_box(&pad).select_tier_for(&model_core::UseCase::GRIPPER),
        );
    });
    hprintln!("count subject=select-use-case mean={} calls=1", selection);
    misses
}
