//! On-target test and benchmark of model-core on a Cortex-M4F emulated by QEMU (mps2-an386):
//! every tier over a 0–50 kPa x 5–55 °C grid of raw FDC1004 readings and over the hard cases,
//! against f64 references computed on the host (golden file from the build script), then the
//! instructions per taxel conversion from SysTick under `-icount shift=0`.
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
use model_core::{ReadingValue, SampleInput, SplitCapacitance, TaxelReading, Tier};
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
        "m4-bench opt-level={} grid_points={} hard_cases={}",
        env!("M4_BENCH_OPT_LEVEL"),
        header.grid_count,
        header.hard_case_count
    );
    let Some(taxel) = checks::GridTaxel::new(&header.grid_setup) else {
        hprintln!("error: the grid's calibration or tare was refused");
        return 1;
    };
    if cfg!(feature = "instruction-mix") {
        return instruction_mix_probe(&header, &taxel);
    }
    let mut misses = checks::grid(GOLDEN, &header, &taxel);
    misses += checks::hard_cases(GOLDEN, &header);
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
                .model
                .convert(
                    Tier::default(),
                    input.value,
                    Some(&taxel.baseline),
                    input.inverse_permittivity_ratio,
                    taxel.calibration.thresholds(),
                )
                .relative_change()
                .unwrap_or(0.0);
            inputs.samples[slot] =
                SampleInput::new([record.reading; 4], Some(record.temperature_c));
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
    let context = Context {
        model: &taxel.model,
        baseline: &taxel.baseline,
        thresholds: taxel.calibration.thresholds(),
    };
    let single = &inputs.single[..inputs.single_count];
    for tier in Tier::ALL {
        counting::convert_loop(context, tier, single, 1);
        counting::convert_overhead_loop(context, tier, single, 1);
    }
    hprintln!(
        "mix tiers={} inputs_per_tier={}",
        Tier::ALL.len(),
        single.len()
    );
    0
}

fn count(counter: &Counter, header: &Header, taxel: &checks::GridTaxel) -> u32 {
    let Some(inputs) = Inputs::new(header, taxel) else {
        return 1;
    };
    let context = Context {
        model: &taxel.model,
        baseline: &taxel.baseline,
        thresholds: taxel.calibration.thresholds(),
    };
    let grid_count = inputs.grid_count;
    let (grid, relative_changes, single) = (
        &inputs.grid[..grid_count],
        &inputs.relative_changes[..grid_count],
        &inputs.single[..inputs.single_count],
    );
    let grid_calls = grid_count as u32 * GRID_REPETITIONS;

    for tier in Tier::ALL {
        let mean = counter.per_call(
            grid_calls,
            || counting::convert_loop(context, tier, grid, GRID_REPETITIONS),
            || counting::convert_overhead_loop(context, tier, grid, GRID_REPETITIONS),
        );
        let (mut minimum, mut maximum, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0);
        for input in single {
            let one = core::slice::from_ref(input);
            let instructions = counter.per_call(
                SINGLE_REPETITIONS,
                || counting::convert_loop(context, tier, one, SINGLE_REPETITIONS),
                || counting::convert_overhead_loop(context, tier, one, SINGLE_REPETITIONS),
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

    let inverses = taxel.model.inverses();
    for tier in Tier::ALL {
        let mean = counter.per_call(
            grid_calls,
            || counting::inverse_loop(inverses, tier, relative_changes, GRID_REPETITIONS),
            || counting::f32_overhead_loop(relative_changes, GRID_REPETITIONS),
        );
        hprintln!(
            "count subject=inverse tier={} mean={:.2} calls={}",
            tier.name(),
            mean,
            grid_calls
        );
    }
    let mut capacitances = [(SplitCapacitance::default(), 1.0f32); GRID_CAPACITY];
    let mut capacitance_count = 0;
    for input in grid {
        if let ReadingValue::Capacitance(capacitance) = input.value {
            capacitances[capacitance_count] = (capacitance, input.inverse_permittivity_ratio);
            capacitance_count += 1;
        }
    }
    let capacitances = &capacitances[..capacitance_count];
    let corrected_calls = capacitance_count as u32 * GRID_REPETITIONS;
    let baseline = context.baseline;
    let overhead =
        || counting::corrected_inversion_overhead_loop(baseline, capacitances, GRID_REPETITIONS);
    let top_pressure_kpa = taxel.calibration.taxels()[0].curve.top().pressure_kpa;
    for tier in Tier::ALL {
        let direct = match tier {
            Tier::Linear => counter.per_call(
                corrected_calls,
                || {
                    counting::corrected_inversion_loop(
                        inverses.linear(),
                        baseline,
                        capacitances,
                        GRID_REPETITIONS,
                    )
                },
                overhead,
            ),
            Tier::PiecewiseLinear => counter.per_call(
                corrected_calls,
                || {
                    counting::corrected_inversion_loop(
                        inverses.piecewise_linear(),
                        baseline,
                        capacitances,
                        GRID_REPETITIONS,
                    )
                },
                overhead,
            ),
            Tier::MonotoneCubic => counter.per_call(
                corrected_calls,
                || {
                    counting::corrected_inversion_loop(
                        inverses.monotone_cubic(),
                        baseline,
                        capacitances,
                        GRID_REPETITIONS,
                    )
                },
                overhead,
            ),
            Tier::Table => counter.per_call(
                corrected_calls,
                || {
                    counting::corrected_inversion_loop(
                        inverses.table(),
                        baseline,
                        capacitances,
                        GRID_REPETITIONS,
                    )
                },
                overhead,
            ),
            Tier::Polynomial => {
                let Some(polynomial) = inverses.polynomial() else {
                    hprintln!("error: no polynomial fit for the grid taxel");
                    return 1;
                };
                counter.per_call(
                    corrected_calls,
                    || {
                        counting::corrected_inversion_loop(
                            polynomial,
                            baseline,
                            capacitances,
                            GRID_REPETITIONS,
                        )
                    },
                    overhead,
                )
            }
            Tier::Saturating | Tier::SaturatingMicromath => {
                let Some(fit) = inverses.saturating_fit() else {
                    hprintln!("error: no saturating fit for the grid taxel");
                    return 1;
                };
                if tier == Tier::Saturating {
                    let inverse = SaturatingInverse::<Libm>::new(fit, top_pressure_kpa);
                    counter.per_call(
                        corrected_calls,
                        || {
                            counting::corrected_inversion_loop(
                                &inverse,
                                baseline,
                                capacitances,
                                GRID_REPETITIONS,
                            )
                        },
                        overhead,
                    )
                } else {
                    let inverse = SaturatingInverse::<Micromath>::new(fit, top_pressure_kpa);
                    counter.per_call(
                        corrected_calls,
                        || {
                            counting::corrected_inversion_loop(
                                &inverse,
                                baseline,
                                capacitances,
                                GRID_REPETITIONS,
                            )
                        },
                        overhead,
                    )
                }
            }
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

    let Some(mut pad) = checks::tared_pad(&header.grid_setup) else {
        return 1;
    };
    let samples = &inputs.samples[..grid_count];
    let mut misses = 0;
    for tier in Tier::ALL {
        if pad.set_tier(tier).is_err() {
            hprintln!("error: tier {} unavailable for the pad", tier.name());
            misses += 1;
            continue;
        }
        let work = counter.instructions(|| counting::pad_loop(&mut pad, samples, 1));
        let overhead = counter.instructions(|| counting::pad_overhead_loop(&mut pad, samples, 1));
        let per_sample = (work as f32 - overhead as f32) / grid_count.max(1) as f32;
        hprintln!(
            "count subject=pad-process-per-taxel tier={} mean={:.2} calls={}",
            tier.name(),
            per_sample / 4.0,
            grid_count
        );
    }
    misses
}
