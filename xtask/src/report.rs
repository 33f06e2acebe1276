//! docs/PERFORMANCE.md and docs/speed-vs-error.svg from the measurements: every number in them
//! comes from a run of `cargo xtask report` (or is a target, a constant of model-core, or a
//! parameter of the method), none is typed in.

use std::fmt::Write;

use model_core::conditioning::{CONVERTER_NOISE_PF, NOMINAL_SENSOR_PF};
use model_core::inverse::POLYNOMIAL_DEGREE;
use model_core::use_case::MEASURED_INSTRUCTIONS;
use model_core::{SelectionError, TaxelFlags, Tier, TierChoice};

use crate::bench_output::BenchRun;
use crate::firmware::{Footprint, FLASH_BUDGET_BYTES, STATIC_RAM_BUDGET_BYTES};
use crate::host::{HostTime, LeaveOneOut, UseCaseSelection};
use crate::mix::{Mix, MixReport};
use crate::simulator::{Latency, SimulatorFigures};
use crate::svg::{Guide, Link, Plot, Point};

/// Targets of the performance work: the default tier's numerical error on the M4, kPa.
pub const DEFAULT_TIER_MAX_ERROR_KPA: f64 = 0.05;
/// Default tier: instructions per temperature-corrected inversion.
pub const DEFAULT_TIER_MAX_INSTRUCTIONS: f64 = 100.0;
/// Default tier: instructions per taxel of `PadModel::process`.
pub const PROCESS_MAX_INSTRUCTIONS_PER_TAXEL: f64 = 200.0;
/// See [`DEFAULT_TIER_MAX_ERROR_KPA`].
pub const FAST_TIER_DISTANCE_KPA: f64 = 0.5;
/// See [`DEFAULT_TIER_MAX_ERROR_KPA`].
pub const FAST_TIER_MAX_INSTRUCTIONS: f64 = 30.0;
/// See [`DEFAULT_TIER_MAX_ERROR_KPA`].
pub const HOST_MIN_CONVERSIONS_PER_SECOND: f64 = 100e6;

/// Pressures at which converter noise is reported, kPa.
pub const NOISE_PRESSURES_KPA: [f32; 3] = [5.0, 25.0, 45.0];

/// Single-precision registers of the Cortex-M4F's FPU (FPv4-SP: s0–s31).
const FP_REGISTERS: u32 = 32;

/// Where the report ran.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// `rustc --version`.
    pub rustc: String,
    /// `qemu-system-arm --version`, first line.
    pub qemu: String,
    /// Host CPU model (/proc/cpuinfo).
    pub cpu: String,
    /// Logical CPUs available.
    pub cpus: usize,
    /// /proc/loadavg's 1, 5 and 15 minute load averages just before criterion ran.
    pub load_average: String,
}

/// Everything the report shows.
#[derive(Debug, Clone)]
pub struct ReportData {
    /// m4-bench as the firmware is built (opt-level "z"): the tested and counted build.
    pub shipped: BenchRun,
    /// m4-bench at opt-level 3, for comparison.
    pub opt3: BenchRun,
    /// Instruction mix (or why it is missing).
    pub mix: Result<MixReport, String>,
    /// Host thread CPU time per `TaxelModel::convert`, per tier.
    pub host_convert: Vec<(Tier, HostTime)>,
    /// Host wall-clock time per `TaxelModel::convert`, per tier.
    pub host_convert_wall: Vec<(Tier, HostTime)>,
    /// Host thread CPU time per `TaxelInverses::pressure_kpa`, per tier.
    pub host_inverse: Vec<(Tier, HostTime)>,
    /// Leave-one-out (max, rms, per point) per tier (None: the reduced curves do not support it).
    pub leave_one_out: Vec<(Tier, Option<LeaveOneOut>)>,
    /// rms pressure noise per tier at [`NOISE_PRESSURES_KPA`].
    pub noise_kpa: Vec<(Tier, [f64; 3])>,
    /// The use cases.
    pub use_cases: Vec<UseCaseSelection>,
    /// Per degree, the polynomial fit's largest distance from the default model, kPa (host,
    /// article's curve; None: the fit is refused).
    pub polynomial_degrees: Vec<(usize, Option<f64>)>,
    /// Where it ran.
    pub machine: Machine,
    /// The firmware's footprint (or why it is missing).
    pub firmware: Result<Footprint, String>,
    /// The simulator's throughput and latency (or why they are missing).
    pub simulator: Result<SimulatorFigures, String>,
}

fn lookup<T: Copy>(pairs: &[(Tier, T)], tier: Tier) -> Option<T> {
    pairs
        .iter()
        .find(|(candidate, _)| *candidate == tier)
        .map(|(_, value)| *value)
}

fn flag_names(bits: u16) -> String {
    if bits == 0 {
        return "-".to_string();
    }
    TaxelFlags::NAMES
        .iter()
        .filter(|(flag, _)| bits & flag.bits() != 0)
        .map(|(_, name)| *name)
        .collect::<Vec<_>>()
        .join(", ")
}

fn kpa(value: f64) -> String {
    if value == 0.0 {
        "0".to_string()
    } else if value.abs() >= 0.01 {
        format!("{value:.3}")
    } else {
        format!("{value:.1e}")
    }
}

fn optional<T>(value: Option<T>, format: impl Fn(T) -> String) -> String {
    value.map_or_else(|| "n/a".to_string(), format)
}

fn one_decimal(value: Option<f64>) -> String {
    optional(value, |value| format!("{value:.1}"))
}

/// How a taxel conversion is counted: the instruction targets are held against the first and the
/// last; the full model step is shown between them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Measure {
    /// `Baseline::relative_change` then the tier's inverse called directly: numerics.md's unit.
    CorrectedInversion,
    /// `TaxelModel::convert`: classification, dC/C0, dispatched inverse, output record.
    FullStep,
    /// `PadModel::process` per taxel: a quarter of a sample set's.
    PadProcess,
}

impl Measure {
    fn label(self) -> &'static str {
        match self {
            Measure::CorrectedInversion => {
                "temperature-corrected inversion (dC/C0, then the tier's inverse called directly), grid mean"
            }
            Measure::FullStep => {
                "`TaxelModel::convert` (fault classification, dC/C0, dispatched inverse, output record), grid mean"
            }
            Measure::PadProcess => {
                "`PadModel::process` of a sample set / 4 (raw decode, temperature, every taxel's `convert`, tare and tracking bookkeeping), grid mean"
            }
        }
    }

    fn count(self, run: &BenchRun, tier: Tier) -> Option<f64> {
        match self {
            Measure::CorrectedInversion => run.corrected_count(tier).ok().map(|count| count.direct),
            Measure::FullStep => run.convert_count(tier).ok().map(|count| count.mean),
            Measure::PadProcess => run.pad_count(tier).ok().map(|count| count.per_taxel),
        }
    }
}

/// A tier's figures gathered from every source.
struct TierFigures {
    tier: Tier,
    max_from_default_kpa: Option<f64>,
    host: Option<HostTime>,
}

fn figures(data: &ReportData) -> Vec<TierFigures> {
    Tier::ALL
        .into_iter()
        .map(|tier| TierFigures {
            tier,
            max_from_default_kpa: data
                .shipped
                .grid_result(tier)
                .ok()
                .map(|result| result.max_from_reference_curve_kpa),
            host: lookup(&data.host_convert, tier),
        })
        .collect()
}

/// The cheapest tier of `run` by `measure` among those within [`FAST_TIER_DISTANCE_KPA`] of the
/// default model (distances from the shipped build's grid): (tier, instructions, distance).
fn fastest_close(data: &ReportData, run: &BenchRun, measure: Measure) -> Option<(Tier, f64, f64)> {
    figures(data)
        .iter()
        .filter_map(|figure| {
            let distance = figure.max_from_default_kpa?;
            let count = measure.count(run, figure.tier)?;
            (distance <= FAST_TIER_DISTANCE_KPA).then_some((figure.tier, count, distance))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TargetKind {
    DefaultError,
    DefaultCorrected,
    FastCorrected,
    DefaultProcess,
    Host,
}

struct Target {
    kind: TargetKind,
    what: String,
    measure: String,
    measured: String,
    met: bool,
    gap: String,
    opt3: String,
}

fn instruction_gap(count: f64, target: f64) -> (bool, String) {
    if count <= target {
        (true, format!("{:.1} to spare", target - count))
    } else {
        (
            false,
            format!(
                "missed by {:.1} instructions ({:.2}x the target)",
                count - target,
                count / target
            ),
        )
    }
}

fn instruction_target(
    data: &ReportData,
    kind: TargetKind,
    what: String,
    measure: Measure,
    tier: Tier,
    target: f64,
) -> Option<Target> {
    let count = measure.count(&data.shipped, tier)?;
    let detail = |run: &BenchRun| match measure {
        Measure::CorrectedInversion => run
            .corrected_count(tier)
            .ok()
            .map(|count| format!(" ({:.1} through the run-time dispatch)", count.dispatched)),
        Measure::FullStep => run
            .convert_count(tier)
            .ok()
            .map(|count| format!(" ({:.1}–{:.1} over single inputs)", count.min, count.max)),
        Measure::PadProcess => run
            .pad_count(tier)
            .ok()
            .map(|count| format!(" ({:.1} per set of four)", count.per_set)),
    };
    let (met, gap) = instruction_gap(count, target);
    Some(Target {
        kind,
        what,
        measure: measure.label().to_string(),
        measured: format!("{count:.1}{}", detail(&data.shipped).unwrap_or_default()),
        met,
        gap,
        opt3: optional(measure.count(&data.opt3, tier), |count| {
            format!("{count:.1}{}", detail(&data.opt3).unwrap_or_default())
        }),
    })
}

fn targets(data: &ReportData) -> Vec<Target> {
    let mut targets = Vec::new();
    let default = Tier::default();
    if let Ok(grid) = data.shipped.grid_result(default) {
        targets.push(Target {
            kind: TargetKind::DefaultError,
            what: format!(
                "default tier ({}): max numerical error on the M4 <= {DEFAULT_TIER_MAX_ERROR_KPA} kPa",
                default.name()
            ),
            measure: format!(
                "largest difference from the f64 reference over the {}-point grid",
                data.shipped.grid_points
            ),
            measured: format!("{} kPa", kpa(grid.max_error_kpa)),
            met: grid.max_error_kpa <= DEFAULT_TIER_MAX_ERROR_KPA,
            gap: format!(
                "{:.0}x margin",
                DEFAULT_TIER_MAX_ERROR_KPA / grid.max_error_kpa.max(1e-12)
            ),
            opt3: optional(data.opt3.grid_result(default).ok(), |grid| {
                format!("{} kPa", kpa(grid.max_error_kpa))
            }),
        });
    }
    targets.extend(instruction_target(
        data,
        TargetKind::DefaultCorrected,
        format!(
            "default tier ({}): <= {DEFAULT_TIER_MAX_INSTRUCTIONS:.0} M4 instructions per \
             temperature-corrected inversion",
            default.name()
        ),
        Measure::CorrectedInversion,
        default,
        DEFAULT_TIER_MAX_INSTRUCTIONS,
    ));
    if let Some((tier, _, distance)) =
        fastest_close(data, &data.shipped, Measure::CorrectedInversion)
    {
        if let Some(mut target) = instruction_target(
            data,
            TargetKind::FastCorrected,
            format!(
                "fastest tier within {FAST_TIER_DISTANCE_KPA} kPa of the default tier: <= \
                 {FAST_TIER_MAX_INSTRUCTIONS:.0} M4 instructions per temperature-corrected \
                 inversion"
            ),
            Measure::CorrectedInversion,
            tier,
            FAST_TIER_MAX_INSTRUCTIONS,
        ) {
            target.measured = format!(
                "{}, {} kPa from the default model: {}",
                tier.name(),
                kpa(distance),
                target.measured
            );
            target.opt3 = optional(
                fastest_close(data, &data.opt3, Measure::CorrectedInversion),
                |(tier, count, _)| format!("{}: {count:.1}", tier.name()),
            );
            targets.push(target);
        }
    }
    targets.extend(instruction_target(
        data,
        TargetKind::DefaultProcess,
        format!(
            "full per-taxel `PadModel::process`, default tier ({}): <= \
             {PROCESS_MAX_INSTRUCTIONS_PER_TAXEL:.0} M4 instructions",
            default.name()
        ),
        Measure::PadProcess,
        default,
        PROCESS_MAX_INSTRUCTIONS_PER_TAXEL,
    ));
    let fastest_host = figures(data)
        .iter()
        .filter_map(|figure| figure.host.map(|host| (figure.tier, host)))
        .min_by(|a, b| a.1.nanoseconds.total_cmp(&b.1.nanoseconds));
    if let Some((tier, host)) = fastest_host {
        let met = host.per_second() >= HOST_MIN_CONVERSIONS_PER_SECOND;
        let close =
            fastest_close(data, &data.shipped, Measure::FullStep).and_then(|(close, _, _)| {
                let host = lookup(&data.host_convert, close)?;
                (close != tier).then(|| {
                    format!(
                        "; {} (fastest within {FAST_TIER_DISTANCE_KPA} kPa of the default on \
                         the M4): {:.1} M/s",
                        close.name(),
                        host.per_second() / 1e6
                    )
                })
            });
        targets.push(Target {
            kind: TargetKind::Host,
            what: format!(
                "host: >= {:.0} M taxel conversions/s on one core, fastest tier",
                HOST_MIN_CONVERSIONS_PER_SECOND / 1e6
            ),
            measure: "`TaxelModel::convert`, criterion, thread CPU time".to_string(),
            measured: format!(
                "{}: {:.1} M/s ({:.2} ns per conversion){}",
                tier.name(),
                host.per_second() / 1e6,
                host.nanoseconds,
                close.unwrap_or_default()
            ),
            met,
            gap: if met {
                format!(
                    "{:.1}x the target",
                    host.per_second() / HOST_MIN_CONVERSIONS_PER_SECOND
                )
            } else {
                format!(
                    "{:.1} M/s short",
                    (HOST_MIN_CONVERSIONS_PER_SECOND - host.per_second()) / 1e6
                )
            },
            opt3: "(host build)".to_string(),
        });
    }
    targets
}

/// The speed-vs-error picture.
pub fn plot(data: &ReportData) -> Plot {
    const COLOURS: [&str; 8] = [
        "#7f7f7f", "#2ca02c", "#1f77b4", "#ff7f0e", "#d62728", "#9467bd", "#8c564b", "#e377c2",
    ];
    let mut points = Vec::new();
    let mut links = Vec::new();
    for (index, figure) in figures(data).into_iter().enumerate() {
        let colour = COLOURS[index % COLOURS.len()];
        let Some(y) = figure.max_from_default_kpa else {
            continue;
        };
        let corrected = Measure::CorrectedInversion.count(&data.shipped, figure.tier);
        let full = Measure::FullStep.count(&data.shipped, figure.tier);
        if let Some(x) = corrected {
            points.push(Point {
                label: Some(figure.tier.name().to_string()),
                x,
                y,
                filled: true,
                colour,
            });
        }
        if let Some(x) = full {
            points.push(Point {
                label: corrected.is_none().then(|| figure.tier.name().to_string()),
                x,
                y,
                filled: false,
                colour,
            });
        }
        if let (Some(from), Some(to)) = (corrected, full) {
            links.push(Link {
                from: (from, y),
                to: (to, y),
                colour,
            });
        }
    }
    Plot {
        title: format!(
            "model-core on the Cortex-M4F, shipped build (opt-level \"{}\"): cost vs error",
            data.shipped.opt_level
        ),
        x_label: "M4 instructions per taxel conversion (QEMU icount, mean over the grid)"
            .to_string(),
        y_label: "max |P - P_default| over the grid on the M4, kPa (log)".to_string(),
        notes: vec![
            "filled: temperature-corrected inversion (dC/C0 + the tier's inverse, as numerics.md counts a conversion);".to_string(),
            "hollow: full model step TaxelModel::convert (+ fault classification, tier dispatch, output record).".to_string(),
            "y: largest deviation from the f64 default model (monotone cubic) over the grid, numerical error included;".to_string(),
            "for monotone-cubic itself that is its numerical error. Dashed: the targets.".to_string(),
        ],
        points,
        guides: vec![
            Guide::Horizontal(
                FAST_TIER_DISTANCE_KPA,
                format!("{FAST_TIER_DISTANCE_KPA} kPa from the default tier"),
            ),
            Guide::Horizontal(
                DEFAULT_TIER_MAX_ERROR_KPA,
                format!("{DEFAULT_TIER_MAX_ERROR_KPA} kPa"),
            ),
            Guide::Vertical(
                FAST_TIER_MAX_INSTRUCTIONS,
                format!("{FAST_TIER_MAX_INSTRUCTIONS:.0}: fastest close tier"),
            ),
            Guide::Vertical(
                DEFAULT_TIER_MAX_INSTRUCTIONS,
                format!("{DEFAULT_TIER_MAX_INSTRUCTIONS:.0}: default tier"),
            ),
        ],
        links,
    }
}

/// docs/PERFORMANCE.md.
pub fn markdown(data: &ReportData) -> String {
    let mut text = String::new();
    let out = &mut text;
    let _ = writeln!(
        out,
        "# Performance of model-core, the firmware and the simulator\n"
    );
    let _ = writeln!(
        out,
        "<!-- Generated by `cargo xtask report`: do not edit by hand, run it again. -->\n"
    );
    let _ = writeln!(
        out,
        "**Generated** by `cargo xtask report` (a few minutes, most of it criterion); never \
         edited by hand. Machine: {} ({} logical CPUs), {}, {}. The on-target part alone, with \
         its checks, is `cargo xtask m4-test` (CI runs it); the simulator part alone is `cargo \
         xtask sim-bench`.\n",
        data.machine.cpu, data.machine.cpus, data.machine.rustc, data.machine.qemu
    );
    let _ = writeln!(
        out,
        "M4 figures are from the build the firmware ships: opt-level \"{}\", fat LTO, one codegen \
         unit (m4-bench's `release` profile, which `cargo xtask m4-test` checks against the \
         root `[profile.firmware]`). The same code at opt-level {} is the second column \
         wherever it is shown: what the counts would be if speed rather than flash were \
         optimised for.\n",
        data.shipped.opt_level, data.opt3.opt_level
    );

    let _ = writeln!(out, "## Targets\n");
    let _ = writeln!(
        out,
        "| target | measured as | measured, opt-level \"{}\" (shipped) | met | gap | opt-level {} |\n|---|---|---|---|---|---|",
        data.shipped.opt_level, data.opt3.opt_level
    );
    for target in targets(data) {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} |",
            target.what,
            target.measure,
            target.measured,
            if target.met { "yes" } else { "**no**" },
            target.gap,
            target.opt3
        );
    }
    let _ = writeln!(
        out,
        "\nMet or missed is decided on the shipped build. numerics.md counts a taxel conversion \
         as the temperature-corrected inversion (dC/C0 from the reading, the baseline and the \
         temperature factor, then the tier's inverse); `PadModel::process` is what the firmware \
         calls per sample set, for four taxels. \"Within {FAST_TIER_DISTANCE_KPA} kPa of the \
         default tier\" is the largest distance from the f64 default model over the grid on the \
         M4 (error table).\n"
    );
    gaps(out, data);

    measurement_method(out, data);
    cost_table(out, data);
    context_table(out, data);
    host_table(out, data);
    error_table(out, data);
    hard_calibrations(out, &data.shipped);
    mix_table(out, data);
    polynomial_degree_table(out, data);

    let _ = writeln!(out, "## Speed against error\n");
    let _ = writeln!(
        out,
        "![M4 instructions per taxel conversion against the largest deviation from the default \
         model](speed-vs-error.svg)\n\n\
         One row of points per tier, in the shipped build (opt-level \"{}\"): filled, the \
         temperature-corrected inversion; hollow, the full model step `TaxelModel::convert`; the \
         line joins the two. x is the mean M4 instruction count over the grid; y is the largest \
         distance from the f64 default model (monotone cubic) over the grid on the M4, so what \
         choosing the tier costs in accuracy, numerical error included; the default tier's own \
         point is its numerical error. The opt-level {} counts are in the cost table.\n",
        data.shipped.opt_level, data.opt3.opt_level
    );

    hard_cases(out, &data.shipped);
    use_cases(out, data);
    drift(out, data);
    firmware(out, data);
    simulator(out, data);
    text
}

fn measurement_method(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let noise_relative = CONVERTER_NOISE_PF / NOMINAL_SENSOR_PF;
    let left_out: Vec<String> = data
        .leave_one_out
        .iter()
        .find_map(|(_, loo)| loo.as_ref())
        .map(|loo| {
            loo.per_point
                .iter()
                .map(|(pressure, _)| format!("{pressure}"))
                .collect()
        })
        .unwrap_or_default();
    let _ = writeln!(out, "## How it is measured\n");
    let _ = writeln!(
        out,
        "- **On the M4**: `m4-bench/` is a `no_std` binary that runs model-core built for \
         `thumbv7em-none-eabihf` as the firmware is built (opt-level \"{}\", fat LTO, one codegen \
         unit; and again at opt-level {}) on QEMU's `mps2-an386` (Cortex-M4 with FPU): \
         `qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -icount shift=0 \
         -semihosting-config enable=on,target=native -nographic -kernel m4-bench`. With \
         `-icount shift=0` virtual time advances 1 ns per executed instruction and SysTick \
         counts the 25 MHz processor clock, so one tick is exactly 40 instructions: a count is \
         (ticks around N calls - ticks around the same loop with the call replaced by \
         `black_box` of its inputs) x 40 / N. Counts are deterministic (the same binary gives \
         the same figures on any host).\n\
         - **Temperature-corrected inversion** (numerics.md's taxel conversion): \
         `Baseline::relative_change(SplitCapacitance, inverse_permittivity_ratio)` (dC/C0 from \
         the split capacitance, the baseline and the sample's temperature factor) followed by the \
         tier's inverse, called directly as in a build fixed to one tier (`mean` in m4-bench's \
         output), and through `TaxelInverses::pressure_kpa` with the tier chosen at run time \
         (`dispatched`). Over the grid's capacitance readings, {} passes. Its parts are counted \
         alone too: dC/C0 (`Baseline::relative_change`) and the inverse (called directly on the \
         grid's dC/C0 values).\n\
         - **Full model step**: `TaxelModel::convert(tier, ReadingValue, Some(&Baseline), \
         inverse_permittivity_ratio, &FaultThresholds)`: fault classification of the reading and \
         of dC/C0, the temperature-corrected dC/C0, the tier's inverse dispatched on a run-time \
         `Tier`, and the output record with its flags. Mean over the grid ({} passes); min–max \
         over single inputs (whole kPa at 25 °C, {} repetitions each).\n\
         - **`PadModel::process`**: one sample set of four taxels (the grid reading on each), \
         as the firmware calls it: the raw-code decode (`TaxelReading::value`), the temperature \
         resolution (`TemperatureTracker::resolve`, once per set), every taxel's `convert`, the \
         tare and tracking bookkeeping and the output. Counted block by block of one grid \
         temperature, the pad first brought to it in 1 °C steps (uncounted), so that every \
         counted set is the steady state and not the slew after an implausible jump; {} passes \
         over each block. Per taxel = per set / 4.\n\
         - **Grid**: 0–50 kPa in 0.5 kPa steps x 5–55 °C in 5 °C steps ({} readings) of a taxel \
         with C0 = 4.5 pF and 6 pF parasitic, C = Cp + C0 (1 + f(P)) eps(T)/eps(25 °C) from the \
         f64 forward model, quantised to raw FDC1004 codes at CAPDAC 3, tared at 25 °C through \
         `PadModel`.\n\
         - **References** (computed on the host by m4-bench's build script, written to a binary \
         file the target includes): independent f64 implementations of each tier's model from \
         the same calibration points, applied to the f64 dC/C0 of the quantised reading (see \
         m4-bench/build/reference.rs; the reference curve is `reference_curves::ForwardCubic`). \
         **(a) Numerical error** = |M4 - the tier's own reference|; **distance from the default \
         model** = |M4 - the f64 monotone cubic|.\n\
         - **(b) Model-form error**: leave-one-out on the article's Table 1, with model-core on \
         the host: each interior point ({} kPa) is left out, the tier rebuilt from the others \
         predicts it.\n\
         - **(c) Pressure noise**: {:.1} fF rms converter noise on C0 = {} pF is {:.1e} in \
         dC/C0; times the tier's own dP/d(dC/C0) at the pressure (central difference over +-1 \
         sigma, model-core on the host).\n\
         - **Host**: criterion (`model-core/benches/tiers.rs`), the same grid, one thread, \
         converted as a host tool converts a recording (readings from memory, results to \
         memory, model and tier opaque to the compiler once per pass); time per conversion = \
         thread CPU time per pass over the grid / {}. The tier is fixed for a pass, so the \
         compiler may hoist its dispatch out of the loop; the M4 count dispatches per call.\n\
         - **Cycles** are estimated, not measured (QEMU models no pipeline, and reads DWT \
         CYCCNT as 0). The dynamic instruction mix comes from a QEMU trace of the shipped build \
         (`-d in_asm,exec,nochain` with an address filter on the benchmark loops and what they \
         call; see `xtask/src/mix.rs`); the Cortex-M4 timing tables then bound the cycles \
         (VDIV/VSQRT 14, VMLA/VFMA 3, loads 1–2, taken branches 2–4, LDM/STM 1 + N, +1 when an \
         FP result is used at once). Flash wait states are not modelled; on the STM32F411 the \
         ART accelerator's prefetch and instruction cache hide them in a hot loop.\n",
        run.opt_level,
        data.opt3.opt_level,
        run.grid_repetitions,
        run.grid_repetitions,
        run.single_repetitions,
        run.grid_repetitions,
        run.grid_points,
        left_out.join(", "),
        CONVERTER_NOISE_PF * 1000.0,
        NOMINAL_SENSOR_PF,
        noise_relative,
        run.grid_points,
    );
}

fn cost_table(out: &mut String, data: &ReportData) {
    let (z, three) = (&data.shipped.opt_level, &data.opt3.opt_level);
    let _ = writeln!(out, "## Cost per taxel on the M4\n");
    let _ = writeln!(
        out,
        "Instructions; \"{z}\" is the shipped build, {three} the comparison. Corrected inversion: \
         the inverse called directly (through the run-time dispatch). `convert`: grid mean \
         (min–max over single inputs). `process`: `PadModel::process` per taxel (per sample set \
         of four).\n"
    );
    let _ = writeln!(
        out,
        "| tier | corrected inversion, \"{z}\" | {three} | `convert`, \"{z}\" | {three} | `process` per taxel (per set), \"{z}\" | {three} | est. cycles, `convert`, \"{z}\" |\n|---|---|---|---|---|---|---|---|"
    );
    let corrected = |run: &BenchRun, tier: Tier| {
        optional(run.corrected_count(tier).ok(), |count| {
            format!("{:.1} ({:.1})", count.direct, count.dispatched)
        })
    };
    let convert = |run: &BenchRun, tier: Tier| {
        optional(run.convert_count(tier).ok(), |count| {
            format!("{:.1} ({:.1}–{:.1})", count.mean, count.min, count.max)
        })
    };
    let process = |run: &BenchRun, tier: Tier| {
        optional(run.pad_count(tier).ok(), |count| {
            format!("{:.1} ({:.1})", count.per_taxel, count.per_set)
        })
    };
    for tier in Tier::ALL {
        let cycles = data.mix.as_ref().ok().and_then(|mix| {
            lookup(&mix.per_tier, tier)
                .map(|mix| format!("{:.0}–{:.0}", mix.cycles_lower(), mix.cycles_upper()))
        });
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            tier.name(),
            corrected(&data.shipped, tier),
            corrected(&data.opt3, tier),
            convert(&data.shipped, tier),
            convert(&data.opt3, tier),
            process(&data.shipped, tier),
            process(&data.opt3, tier),
            cycles.unwrap_or_else(|| "n/a".to_string()),
        );
    }
    let _ = writeln!(
        out,
        "\ndC/C0 alone (`Baseline::relative_change`) costs {} instructions at \"{z}\", {} at \
         {three}: the floor under every corrected inversion.\n",
        one_decimal(data.shipped.functions.get("relative-change").copied()),
        one_decimal(data.opt3.functions.get("relative-change").copied()),
    );
}

fn host_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Time per conversion on the host\n");
    let _ = writeln!(
        out,
        "| tier | `convert`, ns of CPU time (95 % CI) | M conversions/s | ns, wall clock | inverse alone (`TaxelInverses::pressure_kpa`), ns |\n|---|---|---|---|---|"
    );
    for figure in figures(data) {
        let wall = lookup(&data.host_convert_wall, figure.tier);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            figure.tier.name(),
            optional(figure.host, |host| format!(
                "{:.2} ({:.2}–{:.2})",
                host.nanoseconds, host.lower_nanoseconds, host.upper_nanoseconds
            )),
            optional(figure.host, |host| format!(
                "{:.0}",
                host.per_second() / 1e6
            )),
            optional(wall, |host| format!("{:.2}", host.nanoseconds)),
            optional(lookup(&data.host_inverse, figure.tier), |host| format!(
                "{:.2}",
                host.nanoseconds
            )),
        );
    }
    let _ = writeln!(
        out,
        "\nCriterion means of the benchmarking thread's CPU time, so that time slices given to \
         other processes do not count; the wall-clock column is the same benchmark timed by the \
         clock. They depend on the machine and on what else runs on it (load average {} when \
         criterion started, on {} logical CPUs); the M4 counts do not.\n",
        data.machine.load_average, data.machine.cpus
    );
}

fn error_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Error\n");
    let _ = writeln!(
        out,
        "| tier | (a) numerical, M4: max | rms | worst at | tolerance | from the default model, M4: max | rms | (b) leave-one-out: max | rms | (c) noise at {} kPa |\n|---|---|---|---|---|---|---|---|---|---|",
        NOISE_PRESSURES_KPA.map(|pressure| pressure.to_string()).join(" / ")
    );
    for tier in Tier::ALL {
        let grid = data.shipped.grid_result(tier).ok();
        let loo = data
            .leave_one_out
            .iter()
            .find(|(candidate, _)| *candidate == tier)
            .and_then(|(_, value)| value.as_ref());
        let noise = lookup(&data.noise_kpa, tier);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            tier.name(),
            optional(grid, |grid| kpa(grid.max_error_kpa)),
            optional(grid, |grid| kpa(grid.rms_error_kpa)),
            optional(grid, |grid| format!(
                "{} kPa, {} °C",
                grid.worst_at_kpa, grid.worst_at_c
            )),
            optional(grid, |grid| kpa(grid.tolerance_kpa)),
            optional(grid, |grid| kpa(grid.max_from_reference_curve_kpa)),
            optional(grid, |grid| kpa(grid.rms_from_reference_curve_kpa)),
            optional(loo, |loo| kpa(loo.max_kpa)),
            optional(loo, |loo| kpa(loo.rms_kpa)),
            optional(noise, |[low, middle, high]| format!(
                "{} / {} / {}",
                kpa(low),
                kpa(middle),
                kpa(high)
            )),
        );
    }
    let _ = writeln!(
        out,
        "\nAll figures in kPa. (a) and the distance from the default model are over the {}-point \
         grid on the M4 in the shipped build, opt-level \"{}\" (opt-level {} gives {}). \
         Leave-one-out errors per left-out point ({} kPa):\n",
        data.shipped.grid_points,
        data.shipped.opt_level,
        data.opt3.opt_level,
        same_results_text(data),
        data.leave_one_out
            .iter()
            .find_map(|(_, loo)| loo.as_ref())
            .map(|loo| loo
                .per_point
                .iter()
                .map(|(pressure, _)| format!("{pressure}"))
                .collect::<Vec<_>>()
                .join(" / "))
            .unwrap_or_default()
    );
    for (tier, loo) in &data.leave_one_out {
        let detail = match loo {
            Some(loo) => loo
                .per_point
                .iter()
                .map(|(_, error)| kpa(*error))
                .collect::<Vec<_>>()
                .join(" / "),
            None => "not available (a reduced curve does not support the tier)".to_string(),
        };
        let _ = writeln!(out, "- {}: {}", tier.name(), detail);
    }
    let _ = writeln!(out);
}

fn same_results_text(data: &ReportData) -> String {
    let differences: Vec<String> = Tier::ALL
        .into_iter()
        .filter_map(|tier| {
            let shipped = data.shipped.grid_result(tier).ok()?;
            let three = data.opt3.grid_result(tier).ok()?;
            (shipped.max_error_kpa != three.max_error_kpa).then(|| {
                format!(
                    "{} {} vs {}",
                    tier.name(),
                    kpa(shipped.max_error_kpa),
                    kpa(three.max_error_kpa)
                )
            })
        })
        .collect();
    if differences.is_empty() {
        "the same maxima for every tier".to_string()
    } else {
        format!("maxima differ: {}", differences.join("; "))
    }
}

fn context_table(out: &mut String, data: &ReportData) {
    let (z, three) = (&data.shipped.opt_level, &data.opt3.opt_level);
    let _ = writeln!(out, "## Where the instructions go\n");
    let _ = writeln!(
        out,
        "The parts of a taxel's conversion counted alone (grid means), and functions for \
         comparison.\n"
    );
    let _ = writeln!(
        out,
        "| subject | M4 instructions, \"{z}\" | {three} | host ns |\n|---|---|---|---|"
    );
    let function_row = |out: &mut String, what: &str, key: &str| {
        let _ = writeln!(
            out,
            "| {what} | {} | {} | |",
            one_decimal(data.shipped.functions.get(key).copied()),
            one_decimal(data.opt3.functions.get(key).copied()),
        );
    };
    function_row(
        out,
        "`TaxelReading::value` (raw-code decode and range checks, per taxel)",
        "reading-value",
    );
    function_row(
        out,
        "`TemperatureTracker::resolve` (once per sample set, steady temperature)",
        "temperature-resolve",
    );
    function_row(
        out,
        "`Baseline::relative_change` (dC/C0 alone)",
        "relative-change",
    );
    function_row(
        out,
        "`PadModel::select_tier_for` (the SetUseCase command: every tier's error on four taxels, gripper use case; once, not per sample)",
        "select-use-case",
    );
    for tier in Tier::ALL {
        let _ = writeln!(
            out,
            "| {} inverse alone, called directly (through `TaxelInverses::pressure_kpa`) | {} | {} | {} |",
            tier.name(),
            optional(data.shipped.inverse_count(tier).ok(), |count| format!(
                "{:.1} ({:.1})",
                count.direct, count.dispatched
            )),
            optional(data.opt3.inverse_count(tier).ok(), |count| format!(
                "{:.1} ({:.1})",
                count.direct, count.dispatched
            )),
            optional(lookup(&data.host_inverse, tier), |host| format!(
                "{:.2}",
                host.nanoseconds
            )),
        );
    }
    let fminf_traced = data
        .mix
        .as_ref()
        .ok()
        .map(|mix| mix.traced_functions.iter().any(|name| name == "fminf"));
    let fminf_note = match fminf_traced {
        Some(true) => "; the traced conversions call it",
        Some(false) => "; not called by the traced conversions",
        None => "",
    };
    function_row(
        out,
        "`TableInverse::pressure_kpa` called directly, a second loop",
        "table-direct",
    );
    function_row(
        out,
        &format!(
            "`f32::min`, for comparison (a call to `fminf`: FPv4-SP has no VMINNM{fminf_note})"
        ),
        "f32-min",
    );
    function_row(out, "libm `logf`, x in [1, 8]", "libm-logf");
    function_row(out, "libm `expf`, x in [-5, 0]", "libm-expf");
    function_row(out, "micromath `ln`, x in [1, 8]", "micromath-ln");
    let _ = writeln!(out);
}

fn mix_row(name: &str, counts: &Mix, systick: String) -> String {
    format!(
        "| {name} | {:.1} | {systick} | {:.2} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} / {:.1} | {:.0}–{:.0} |",
        counts.instructions,
        counts.fp_divide,
        counts.fp_multiply_accumulate,
        counts.fp_arithmetic,
        counts.single_loads,
        counts.multiple_words,
        counts.unconditional_branches,
        counts.conditional_branches,
        counts.cycles_lower(),
        counts.cycles_upper(),
    )
}

const MIX_HEADER: &str = "| subject | traced instructions | SysTick | VDIV/VSQRT | VMLA/VFMA | other FP arithmetic | LDR/VLDR | words in LDM/STM/PUSH/POP | branches always / conditional | est. cycles (lower–upper) |\n|---|---|---|---|---|---|---|---|---|---|";

fn mix_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(
        out,
        "## Instruction mix and cycle estimate (opt-level \"{}\", shipped)\n",
        data.shipped.opt_level
    );
    let mix = match &data.mix {
        Ok(mix) => mix,
        Err(reason) => {
            let _ = writeln!(out, "Not available: {reason}\n");
            return;
        }
    };
    let largest_difference = mix
        .per_tier
        .iter()
        .filter_map(|(tier, counts)| {
            let count = data.shipped.convert_count(*tier).ok()?;
            Some((counts.instructions - count.single_mean).abs())
        })
        .fold(0.0, f64::max);
    let _ = writeln!(
        out,
        "Per call, traced in the `instruction-mix` build (the shipped code generation) over the \
         {} single inputs (whole kPa at 25 °C). That build holds the same code as the tested one \
         (the probe is chosen at run time). For the full step the SysTick column is the tested build's count over the same \
         inputs; the two agree within {:.1} instructions, the loops' own overhead being spread \
         differently: the trace runs each loop once over all {} inputs, the SysTick count \
         repeats each input {} times in an outer loop.\n",
        mix.inputs_per_tier, largest_difference, mix.inputs_per_tier, data.shipped.single_repetitions
    );
    let _ = writeln!(
        out,
        "**Full model step** (`TaxelModel::convert`):\n\n{MIX_HEADER}"
    );
    for (tier, counts) in &mix.per_tier {
        let systick = optional(data.shipped.convert_count(*tier).ok(), |count| {
            format!("{:.1}", count.single_mean)
        });
        let _ = writeln!(out, "{}", mix_row(tier.name(), counts, systick));
    }
    let _ = writeln!(
        out,
        "\n**Temperature-corrected inversion** (dC/C0, then the inverse called directly), over \
         the {} capacitance readings among the same inputs; the SysTick column is the grid mean \
         (other inputs, so only roughly comparable):\n\n{MIX_HEADER}",
        mix.corrected_inputs
    );
    let _ = writeln!(
        out,
        "{}",
        mix_row(
            "dC/C0 alone (`Baseline::relative_change`)",
            &mix.relative_change,
            one_decimal(data.shipped.functions.get("relative-change").copied())
        )
    );
    for (tier, counts) in &mix.corrected {
        let systick = one_decimal(
            data.shipped
                .corrected_count(*tier)
                .ok()
                .map(|count| count.direct),
        );
        let _ = writeln!(out, "{}", mix_row(tier.name(), counts, systick));
    }
    let _ = writeln!(
        out,
        "\nFunctions inside the trace filter: {}.\n",
        mix.traced_functions
            .iter()
            .map(|name| format!("`{name}`"))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// The polynomial fit by degree: the lowest degree within the fast-tier distance, if any.
fn lowest_close_degree(data: &ReportData) -> Option<(usize, f64)> {
    data.polynomial_degrees
        .iter()
        .filter_map(|(degree, distance)| Some((*degree, (*distance)?)))
        .filter(|(_, distance)| *distance <= FAST_TIER_DISTANCE_KPA)
        .min_by_key(|(degree, _)| *degree)
}

fn polynomial_degree_table(out: &mut String, data: &ReportData) {
    if data.polynomial_degrees.is_empty() {
        return;
    }
    let _ = writeln!(out, "## The polynomial fit by degree (host)\n");
    let _ = writeln!(
        out,
        "model-core's least-squares fit of the inverse (`PolynomialInverse::with_degree`, no \
         constant term) on the article's curve, evaluated as the polynomial tier evaluates it \
         and clamped, against model-core's monotone cubic at {} values of dC/C0 from 0 to the \
         top point; the tier itself uses degree {POLYNOMIAL_DEGREE}. The M4 grid samples the \
         curve more coarsely (0.5 kPa steps), where the tier's distance is {} kPa.\n",
        crate::host::POLYNOMIAL_SWEEP_POINTS,
        optional(
            data.shipped
                .grid_result(Tier::Polynomial)
                .ok()
                .map(|grid| grid.max_from_reference_curve_kpa),
            kpa
        )
    );
    let _ = writeln!(
        out,
        "| degree | max distance from the default model, kPa | within {FAST_TIER_DISTANCE_KPA} kPa |\n|---|---|---|"
    );
    for (degree, distance) in &data.polynomial_degrees {
        let _ = writeln!(
            out,
            "| {degree} | {} | {} |",
            optional(*distance, kpa),
            match distance {
                Some(distance) if *distance <= FAST_TIER_DISTANCE_KPA => "yes",
                Some(_) => "no",
                None => "fit refused (not monotone)",
            }
        );
    }
    let _ = writeln!(out);
}

/// Differences of one traced mix from another, by class.
struct MixDifference {
    instructions: f64,
    loads: f64,
    words: f64,
    multiply_accumulates: f64,
    arithmetic: f64,
    branches: f64,
    divides: f64,
}

impl MixDifference {
    fn between(more: &Mix, less: &Mix) -> Self {
        Self {
            instructions: more.instructions - less.instructions,
            loads: more.single_loads - less.single_loads,
            words: more.multiple_words - less.multiple_words,
            multiply_accumulates: more.fp_multiply_accumulate - less.fp_multiply_accumulate,
            arithmetic: more.fp_arithmetic - less.fp_arithmetic,
            branches: (more.unconditional_branches + more.conditional_branches)
                - (less.unconditional_branches + less.conditional_branches),
            divides: more.fp_divide - less.fp_divide,
        }
    }

    /// Everything but single loads, multiply-accumulates, other FP arithmetic, branches and
    /// divisions: stores, load/store-multiple instructions, compares, moves, FPSCR transfers.
    fn others(&self) -> f64 {
        self.instructions
            - self.loads
            - self.multiply_accumulates
            - self.arithmetic
            - self.branches
            - self.divides
    }

    /// Words read from memory, counting load-multiple words with the single loads.
    fn fetched(&self) -> f64 {
        self.loads + self.words
    }
}

fn fast_corrected_gap(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let Some((tier, count, distance)) =
        fastest_close(data, &data.shipped, Measure::CorrectedInversion)
    else {
        return;
    };
    let relative_change = run.functions.get("relative-change").copied();
    let linear = Measure::CorrectedInversion.count(run, Tier::Linear);
    let mix = data.mix.as_ref().ok();
    let traced = |tier: Tier| mix.and_then(|mix| lookup(&mix.corrected, tier));
    let target = FAST_TIER_MAX_INSTRUCTIONS;

    if let (Some(relative_change), Some(linear)) = (relative_change, linear) {
        let room = if linear < target {
            format!(
                "{:.1} instructions are left under the target for everything a curve needs \
                 beyond a straight line",
                target - linear
            )
        } else {
            format!(
                "the floor alone is {:.1} above the target, so no tier can meet it with this \
                 dC/C0 and clamp",
                linear - target
            )
        };
        let floor_mix = traced(Tier::Linear)
            .zip(mix.map(|mix| mix.relative_change))
            .map(|(linear_mix, relative_mix)| {
                let difference = MixDifference::between(&linear_mix, &relative_mix);
                format!(
                    " In the trace dC/C0 executes {:.1} instructions ({:.1} loads: the \
                     baseline's fields and the inputs, {:.1} multiply-adds, {:.1} other FP \
                     arithmetic) and the linear inverse adds {:.1}: {:.1} loads (its constants, \
                     and its own address, which the benchmark's `black_box` hides), {:.1} FP \
                     arithmetic (the multiply), {:.1} branches and {:.1} others (the compares, \
                     FPSCR transfers and conditional moves of the clamp).",
                    relative_mix.instructions,
                    relative_mix.single_loads,
                    relative_mix.fp_multiply_accumulate,
                    relative_mix.fp_arithmetic,
                    difference.instructions,
                    difference.loads,
                    difference.arithmetic + difference.multiply_accumulates,
                    difference.branches,
                    difference.others() + difference.divides,
                )
            })
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "- **The floor under every tier** (temperature-corrected inversion). dC/C0 alone \
             (`Baseline::relative_change`: the split-capacitance difference, the temperature \
             factor and their multiply-adds) costs {relative_change:.1} instructions. The linear \
             tier, whose inverse is one multiply and the clamp to 0..top, costs {linear:.1}: \
             {:.1} on top of dC/C0.{floor_mix} No inverse is cheaper than a multiply and the \
             clamp, so {linear:.1} is the floor with this dC/C0 and clamp: {room}. (Every count \
             here includes the round trip through the stack that `black_box` forces on each \
             input; a loop over real readings would not have it.)",
            linear - relative_change,
        );
    }

    let Some(linear) = linear else {
        return;
    };
    let difference = traced(tier)
        .zip(traced(Tier::Linear))
        .map(|(tier_mix, linear_mix)| MixDifference::between(&tier_mix, &linear_mix));
    let trace_text = difference
        .as_ref()
        .map(|difference| {
            format!(
                " In the trace it executes {:+.1} instructions against the linear tier: {:+.1} \
                 single loads and {:+.1} words of load/store-multiple instructions, {:+.1} \
                 multiply-accumulates, {:+.1} other FP arithmetic, {:+.1} divisions, {:+.1} \
                 branches, {:+.1} others.",
                difference.instructions,
                difference.loads,
                difference.words,
                difference.multiply_accumulates,
                difference.arithmetic,
                difference.divides,
                difference.branches,
                difference.others(),
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "- **{}**, the cheapest tier within {FAST_TIER_DISTANCE_KPA} kPa of the default model \
         ({} kPa from it), costs {count:.1}, {:.1} more than the linear tier.{trace_text}",
        tier.name(),
        kpa(distance),
        count - linear,
    );
    if tier != Tier::Polynomial {
        return;
    }
    let Some(difference) = difference else {
        return;
    };
    let degree = POLYNOMIAL_DEGREE as f64;
    let fetched_per_coefficient = difference.fetched() / degree;
    let per_coefficient = (difference.fetched() + difference.multiply_accumulates) / degree;
    // Horner's rule on u (c1 + u (c2 + ... u cD)) needs D - 1 multiply-adds.
    let horner_extra = mix
        .zip(traced(Tier::Polynomial))
        .map(|(mix, polynomial)| {
            polynomial.fp_multiply_accumulate - mix.relative_change.fp_multiply_accumulate
        })
        .map(|horner| (horner, horner - (degree - 1.0)))
        .filter(|(_, extra)| *extra > 0.5);
    let horner_text = horner_extra
        .map(|(horner, _)| {
            format!(
                " Its Horner loop executes {horner:.1} multiply-adds (the trace's minus dC/C0's) \
                 where a degree-{POLYNOMIAL_DEGREE} polynomial without constant term needs {}: it \
                 starts from 0.0, and the compiler must keep the first 0 x u, which is not 0 for \
                 an infinite or NaN u.",
                POLYNOMIAL_DEGREE - 1
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "  Over its {POLYNOMIAL_DEGREE} coefficients that is {per_coefficient:.1} instructions \
         per coefficient: {fetched_per_coefficient:.1} loaded word (the coefficient) and a \
         multiply-add.{horner_text}"
    );

    let _ = writeln!(
        out,
        "- **What would close the gap** (estimates from the figures above, not measured; the \
         choice is model-core's):"
    );
    let verdict = |estimate: f64| {
        if estimate <= target {
            format!("{:.1} under the target", target - estimate)
        } else {
            format!("still {:.1} over the target", estimate - target)
        }
    };
    let fewer = lowest_close_degree(data).map(|(lowest_degree, lowest_distance)| {
        let saved = per_coefficient * (degree - lowest_degree as f64);
        (lowest_degree, lowest_distance, count - saved)
    });
    if let Some((lowest_degree, lowest_distance, estimate)) = fewer {
        let _ = writeln!(
            out,
            "  - *Fewer coefficients, larger error*: the lowest degree whose fit stays within \
             {FAST_TIER_DISTANCE_KPA} kPa of the default model on the article's curve is \
             {lowest_degree} ({} kPa; table \"The polynomial fit by degree\"). At \
             {per_coefficient:.1} instructions per coefficient that is about {estimate:.1} \
             instructions, {}.",
            kpa(lowest_distance),
            verdict(estimate)
        );
    }
    let in_registers = count - difference.fetched();
    let _ = writeln!(
        out,
        "  - *Per-taxel constants kept in registers across the four taxels*: the {:.1} words the \
         polynomial loads more than the linear tier are its constants (coefficients and scale). \
         If the four taxels of a sample set shared one curve, a loop over them could keep these \
         in FP registers (the FPU has {FP_REGISTERS} single-precision registers) and load only \
         the baselines: about {in_registers:.1} instructions per taxel, {}. Each taxel has its \
         own calibration today, so this needs one curve per pad.",
        difference.fetched(),
        verdict(in_registers)
    );
    if let Some((_, extra)) = horner_extra {
        let _ = writeln!(
            out,
            "  - *Horner's rule from the last coefficient* instead of from 0.0: {extra:.1} \
             multiply-add fewer, {}.",
            verdict(count - extra)
        );
    }
    if let Some((lowest_degree, _, estimate)) = fewer {
        let all = estimate
            - fetched_per_coefficient * lowest_degree as f64
            - horner_extra.map_or(0.0, |(_, extra)| extra);
        let _ = writeln!(
            out,
            "  - *All of these*: degree {lowest_degree}, its coefficients in registers{}: about \
             {all:.1} instructions, {}. Below that lies the linear tier's {linear:.1}, which \
             only a cheaper dC/C0 or clamp would lower.",
            if horner_extra.is_some() {
                ", Horner's rule from the last coefficient"
            } else {
                ""
            },
            verdict(all)
        );
    }
}

/// Functions of the trace that LLVM's machine outliner made.
fn outlined_functions(mix: &MixReport) -> usize {
    mix.traced_functions
        .iter()
        .filter(|name| name.starts_with("OUTLINED_FUNCTION"))
        .count()
}

fn default_corrected_gap(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let default = Tier::default();
    let Some(count) = Measure::CorrectedInversion.count(run, default) else {
        return;
    };
    let relative_change = run.functions.get("relative-change").copied();
    let inverse = run.inverse_count(default).ok();
    let parts = relative_change
        .zip(inverse)
        .map(|(relative_change, inverse)| {
            format!(
                " Its parts counted alone: dC/C0 (`Baseline::relative_change`) {relative_change:.1}, \
                 the inverse called directly {:.1} (sum {:.1}; the rest, {:+.1}, is what \
                 inlining the two into one loop saves or adds). The inverse alone is {} the \
                 target{}.",
                inverse.direct,
                relative_change + inverse.direct,
                count - relative_change - inverse.direct,
                if inverse.direct > DEFAULT_TIER_MAX_INSTRUCTIONS {
                    "over"
                } else {
                    "within"
                },
                if inverse.direct > DEFAULT_TIER_MAX_INSTRUCTIONS {
                    format!(
                        " by {:.1}: no cheaper dC/C0 closes the gap",
                        inverse.direct - DEFAULT_TIER_MAX_INSTRUCTIONS
                    )
                } else {
                    format!(
                        ", with {:.1} left for dC/C0 where it takes {relative_change:.1}",
                        DEFAULT_TIER_MAX_INSTRUCTIONS - inverse.direct
                    )
                }
            )
        })
        .unwrap_or_default();
    let traced = data
        .mix
        .as_ref()
        .ok()
        .and_then(|mix| lookup(&mix.corrected, default))
        .map(|mix| {
            format!(
                " In the trace: {:.2} VDIV (14 cycles each), {:.1} multiply-adds, {:.1} other FP \
                 arithmetic, {:.1} loads, {:.1} words of load/store-multiple, {:.1} / {:.1} \
                 branches (always / conditional): a search for the segment, Newton steps on the \
                 cubic (each with a division) and the clamp.",
                mix.fp_divide,
                mix.fp_multiply_accumulate,
                mix.fp_arithmetic,
                mix.single_loads,
                mix.multiple_words,
                mix.unconditional_branches,
                mix.conditional_branches
            )
        })
        .unwrap_or_default();
    let outlined = data
        .mix
        .as_ref()
        .ok()
        .map(outlined_functions)
        .filter(|count| *count > 0)
        .map(|count| {
            format!(
                " The traced code passes through {count} functions made by LLVM's machine \
                 outliner (`OUTLINED_FUNCTION_*`: instruction sequences shared to save flash at \
                 opt-level \"{}\", each reached by a call and left by a return, often with \
                 registers pushed and popped).",
                run.opt_level
            )
        })
        .unwrap_or_default();
    let opt3 = Measure::CorrectedInversion
        .count(&data.opt3, default)
        .map(|three| {
            format!(
                " At opt-level {} the same source costs {three:.1} (inverse alone {}): {:.1} of \
                 the shipped count is the price of optimising for size.",
                data.opt3.opt_level,
                optional(data.opt3.inverse_count(default).ok(), |count| format!(
                    "{:.1}",
                    count.direct
                )),
                count - three
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "- **The default tier's corrected inversion** ({}) costs {count:.1}, {:.1} over the \
         {DEFAULT_TIER_MAX_INSTRUCTIONS:.0}-instruction target.{parts}{traced}{outlined}{opt3}",
        default.name(),
        count - DEFAULT_TIER_MAX_INSTRUCTIONS,
    );
}

fn process_gap(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let default = Tier::default();
    let (Ok(pad), Ok(convert), Ok(corrected), Ok(inverse)) = (
        run.pad_count(default),
        run.convert_count(default),
        run.corrected_count(default),
        run.inverse_count(default),
    ) else {
        return;
    };
    let (Some(decode), Some(temperature), Some(relative_change)) = (
        run.functions.get("reading-value").copied(),
        run.functions.get("temperature-resolve").copied(),
        run.functions.get("relative-change").copied(),
    ) else {
        return;
    };
    let target = PROCESS_MAX_INSTRUCTIONS_PER_TAXEL;
    let dispatch = corrected.dispatched - corrected.direct;
    let classification = convert.mean - corrected.dispatched;
    let rest = pad.per_taxel - convert.mean - decode - temperature / 4.0;
    let non_inverse = pad.per_taxel - inverse.direct;
    let linear = run.pad_count(Tier::Linear).ok();
    let _ = writeln!(
        out,
        "- **`PadModel::process`** with the default tier costs {:.1} per taxel ({:.1} per set of \
         four), {:.1} over the {target:.0}-instruction target. Its measured parts, per taxel:\n\
         \x20 - raw-code decode (`TaxelReading::value`): {decode:.1};\n\
         \x20 - temperature resolution (`TemperatureTracker::resolve`, once per set): \
         {temperature:.1} per set, {:.1} per taxel;\n\
         \x20 - dC/C0 (`Baseline::relative_change`): {relative_change:.1};\n\
         \x20 - the inverse alone, called directly: {:.1};\n\
         \x20 - the run-time tier dispatch (corrected inversion dispatched minus direct): \
         {dispatch:.1};\n\
         \x20 - classification (reading, short/open, dead band, over-range) and the output record \
         inside `convert` (its count minus the dispatched corrected inversion): \
         {classification:.1};\n\
         \x20 - the rest of `process` (flag merging, tare and tracking bookkeeping, the four \
         outputs and the temperature copied out; per taxel minus `convert`, decode and a \
         quarter of the temperature): {rest:.1}.\n\
         \x20 \n\
         \x20 Everything but the inverse costs {non_inverse:.1} per taxel, so with this inverse \
         the target needs {:.1} instructions removed{}.{}",
        pad.per_taxel,
        pad.per_set,
        pad.per_taxel - target,
        temperature / 4.0,
        inverse.direct,
        pad.per_taxel - target,
        if non_inverse > target {
            format!(
                "; even with a free inverse the rest is {:.1} over",
                non_inverse - target
            )
        } else {
            String::new()
        },
        linear
            .map(|linear| format!(
                " The linear tier's `process` (an inverse of a multiply and a clamp) costs \
                 {:.1} per taxel.",
                linear.per_taxel
            ))
            .unwrap_or_default(),
    );
    if let Ok(three) = data.opt3.pad_count(default) {
        let _ = writeln!(
            out,
            "  At opt-level {} it costs {:.1} per taxel.",
            data.opt3.opt_level, three.per_taxel
        );
    }
}

fn gaps(out: &mut String, data: &ReportData) {
    let missed: Vec<TargetKind> = targets(data)
        .into_iter()
        .filter(|target| !target.met)
        .map(|target| target.kind)
        .collect();
    if missed.is_empty() {
        let _ = writeln!(out, "Every target is met.\n");
        return;
    }
    let _ = writeln!(out, "### Why the missed targets are missed\n");
    let _ = writeln!(
        out,
        "From the measured parts of the cost (SysTick counts in the shipped build, grid means; \
         instruction classes from the trace of the same build). How to remove them is \
         model-core's choice; estimates below are marked as such.\n"
    );
    if missed.contains(&TargetKind::DefaultCorrected) {
        default_corrected_gap(out, data);
    }
    if missed.contains(&TargetKind::FastCorrected) {
        fast_corrected_gap(out, data);
    }
    if missed.contains(&TargetKind::DefaultProcess) {
        process_gap(out, data);
    }
    if missed.contains(&TargetKind::DefaultError) {
        let _ = writeln!(
            out,
            "- **The default tier's numerical error** is above {DEFAULT_TIER_MAX_ERROR_KPA} kPa \
             on the M4: see the error table for where, and the hard cases for which inputs."
        );
    }
    if missed.contains(&TargetKind::Host) {
        let fastest = data
            .host_convert
            .iter()
            .min_by(|a, b| a.1.nanoseconds.total_cmp(&b.1.nanoseconds));
        let _ = writeln!(
            out,
            "- **Host**: the fastest conversion measured here takes {} ns of CPU time \
             ({} M/s); {:.0} M/s needs {:.0} ns. The inverse alone takes {} ns for that tier. \
             The machine matters: the load average was {} on {} logical CPUs when criterion \
             ran. Converting the four taxels of a sample set together (one temperature factor, \
             one dispatch, vectorisable arithmetic) is where the rest would have to come from; \
             it was not tried here.",
            optional(fastest, |(_, host)| format!("{:.2}", host.nanoseconds)),
            optional(fastest, |(_, host)| format!(
                "{:.0}",
                host.per_second() / 1e6
            )),
            HOST_MIN_CONVERSIONS_PER_SECOND / 1e6,
            1e9 / HOST_MIN_CONVERSIONS_PER_SECOND,
            optional(
                fastest.and_then(|(tier, _)| lookup(&data.host_inverse, *tier)),
                |host| format!("{:.2}", host.nanoseconds)
            ),
            data.machine.load_average,
            data.machine.cpus,
        );
    }
    let _ = writeln!(out);
}

fn hard_cases(out: &mut String, run: &BenchRun) {
    let _ = writeln!(
        out,
        "## Hard cases on the M4 (opt-level \"{}\", shipped)\n",
        run.opt_level
    );
    let _ = writeln!(
        out,
        "Each case is a fresh pad, tared with one unloaded sample set (and, where a warm-up is \
         given, brought to that temperature in 1 °C steps of unloaded sample sets, as a real pad \
         warms), then the reading through `PadModel::process` with every tier, each from the same \
         state. A case passes when the flags are exactly the \
         expected ones and the pressure is within tolerance of the tier's f64 reference (or \
         absent when a fault is expected). Cells: pressure in kPa, or `fault`.\n"
    );
    let mut header = "| case | reading | temperature | expected flags |".to_string();
    let mut rule = "|---|---|---|---|".to_string();
    for tier in Tier::ALL {
        header.push_str(&format!(" {} |", tier.name()));
        rule.push_str("---|");
    }
    let _ = writeln!(out, "{header}\n{rule}");
    for case in &run.cases {
        let temperature = if case.warm_up == "None" {
            format!("`{}`", case.temperature)
        } else {
            format!(
                "`{}` after a warm-up to `{}`",
                case.temperature, case.warm_up
            )
        };
        let mut row = format!(
            "| `{}`: {} | `{}` | {temperature} | {} |",
            case.name,
            case.description,
            case.reading,
            flag_names(case.expected_flags)
        );
        for tier in Tier::ALL {
            let result = run
                .hard
                .iter()
                .find(|result| result.case == case.name && result.tier == tier);
            let cell = match result {
                None => "missing".to_string(),
                Some(result) => {
                    let value = optional(result.pressure_kpa, |pressure| {
                        if pressure != 0.0 && pressure.abs() < 0.01 {
                            format!("{pressure:.2e}")
                        } else {
                            format!("{pressure:.3}")
                        }
                    })
                    .replace("n/a", "fault");
                    if result.pass {
                        value
                    } else {
                        format!("**FAIL** {value} ({})", flag_names(result.flags))
                    }
                }
            };
            row.push_str(&format!(" {cell} |"));
        }
        let _ = writeln!(out, "{row}");
    }
    let passed = run.hard.iter().filter(|result| result.pass).count();
    let _ = writeln!(
        out,
        "\n{passed} of {} case x tier results pass.\n",
        run.hard.len()
    );
}

fn use_cases(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Which tier each use case selects\n");
    let _ = writeln!(
        out,
        "`model_core::select_tier_for_taxels` on the article's curve picks the cheapest tier \
         (by `MEASURED_INSTRUCTIONS`) whose error over the use case's pressure and temperature \
         range fits the budget. The error is the sum of four parts (model-core's `use_case` \
         module): numerical (the tier against the reference curve), model form (for the \
         interpolating forms, leave-one-out over the calibration points in the range, scaled to \
         the calibration's spacing by the form's order, the table and polynomial carrying the \
         cubic's; for the fitted forms, their error at the calibration points), converter noise where the curve is flattest (C0 at the range's warmest \
         temperature), and the temperature sensor's 0.1 °C through the steepest part of the \
         permittivity law in the range.\n"
    );
    for selection in &data.use_cases {
        let use_case = selection.use_case;
        let parts = |choice: &TierChoice| {
            format!(
                "{} kPa numerical + {} kPa model form + {} kPa noise + {} kPa temperature = {} kPa",
                kpa(f64::from(choice.numerical_error_kpa)),
                kpa(f64::from(choice.model_form_error_kpa)),
                kpa(f64::from(choice.noise_kpa)),
                kpa(f64::from(choice.temperature_error_kpa)),
                kpa(f64::from(choice.total_error_kpa())),
            )
        };
        let verdict = match &selection.selected {
            Ok(choice) => format!(
                "**{}**: {} within {} kPa, {} instructions",
                choice.tier.name(),
                parts(choice),
                use_case.error_budget_kpa,
                choice.instructions
            ),
            Err(SelectionError::NoTierWithinBudget { best }) => format!(
                "**no tier fits**: the most accurate, {}, has {}, over the {} kPa budget",
                best.tier.name(),
                parts(best),
                use_case.error_budget_kpa
            ),
            Err(error) => format!("no tier: {error:?}"),
        };
        let _ = writeln!(
            out,
            "### {} (0–{} kPa, {}–{} °C, budget {} kPa)\n\n{verdict}.\n",
            selection.name,
            use_case.pressure_max_kpa,
            use_case.temperature_min_c,
            use_case.temperature_max_c,
            use_case.error_budget_kpa
        );
        let mut evaluated = selection.evaluated.clone();
        evaluated.sort_by_key(|choice| choice.instructions);
        let _ = writeln!(
            out,
            "| tier | instructions | numerical | model form | noise | temperature | total | fits |\n\
             |---|---|---|---|---|---|---|---|"
        );
        for choice in evaluated {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                choice.tier.name(),
                choice.instructions,
                kpa(f64::from(choice.numerical_error_kpa)),
                kpa(f64::from(choice.model_form_error_kpa)),
                kpa(f64::from(choice.noise_kpa)),
                kpa(f64::from(choice.temperature_error_kpa)),
                kpa(f64::from(choice.total_error_kpa())),
                if choice.total_error_kpa() <= use_case.error_budget_kpa {
                    "yes"
                } else {
                    "no"
                }
            );
        }
        let _ = writeln!(out);
    }
}

fn drift(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## `MEASURED_INSTRUCTIONS`\n");
    let tolerance = crate::measured::drift_tolerance(&MEASURED_INSTRUCTIONS);
    let _ = writeln!(
        out,
        "The constants in `model-core/src/use_case.rs` that `select_tier` ranks tiers by: \
         `TaxelModel::convert`, grid mean, in the shipped build (opt-level \"{}\"). `cargo xtask \
         report` rewrites them from its own run before it writes this page (and `cargo xtask \
         m4-test --write` does the same), so they are never typed in. `cargo xtask m4-test` fails \
         when the measured order of the tiers differs from theirs (counts within {:.0} \
         instructions are tied), or when a count is further than {tolerance:.1} instructions \
         from its constant: half the smallest gap between neighbouring tiers, within which no two \
         tiers can trade places.\n",
        data.shipped.opt_level,
        crate::measured::TIE_INSTRUCTIONS,
    );
    let _ = writeln!(
        out,
        "| tier | constant | measured, \"{}\" | difference | opt-level {} |\n|---|---|---|---|---|",
        data.shipped.opt_level, data.opt3.opt_level
    );
    let mut constants = MEASURED_INSTRUCTIONS.to_vec();
    constants.sort_by_key(|(_, constant)| *constant);
    for (tier, constant) in constants {
        let measured = data
            .shipped
            .convert_count(tier)
            .ok()
            .map(|count| count.mean);
        let _ = writeln!(
            out,
            "| {} | {constant} | {} | {} | {} |",
            tier.name(),
            optional(measured, |value| format!("{value:.1}")),
            optional(measured, |value| format!(
                "{:+.1}",
                value - f64::from(constant)
            )),
            one_decimal(data.opt3.convert_count(tier).ok().map(|count| count.mean)),
        );
    }
    let order = |run: &BenchRun| {
        let values: Vec<(Tier, f64)> = Tier::ALL
            .into_iter()
            .filter_map(|tier| Some((tier, run.convert_count(tier).ok()?.mean)))
            .collect();
        crate::measured::order_text(&values)
    };
    let _ = writeln!(
        out,
        "\nOrder, cheapest first (`=`: within {:.0} instructions): \"{}\": {}; opt-level {}: {}.\n",
        crate::measured::TIE_INSTRUCTIONS,
        data.shipped.opt_level,
        order(&data.shipped),
        data.opt3.opt_level,
        order(&data.opt3),
    );
}

fn hard_calibrations(out: &mut String, run: &BenchRun) {
    let _ = writeln!(
        out,
        "## Hard calibrations on the M4 (opt-level \"{}\", shipped)\n",
        run.opt_level
    );
    let Some(summary) = run.calibration_summary else {
        let _ = writeln!(
            out,
            "Not available: the run printed no hard-calibration result.\n"
        );
        return;
    };
    let _ = writeln!(
        out,
        "{} valid but ill-conditioned calibration curves (`reference_curves::hard_calibration`, \
         seeds 0–{}: 2 to 16 points, unequal spacing, nearly equal neighbours, a nearly flat \
         top, a steep start), each built on the target into a `CalibrationCurve` and \
         `TaxelInverses`, and the default tier's inverse (`monotone_cubic().pressure_kpa`) asked \
         at **{} dC/C0 probes** in all: spread in pressure over every interval, every \
         interval's midpoint in dC/C0, every point and a few ulps either side. An answer passes \
         when it is finite, within 0 ..= top and within the interval the f64 reference \
         (`reference_curves::ForwardCubic`, Fritsch–Carlson inverted by bisection) accepts: \
         model-core's host rule, within 0.01 kPa of a pressure whose reference dC/C0 is within \
         8 f32 ulps of the probe, written by the build script as the reference pressures at \
         dC/C0 -+ 8 ulps widened by 0.01 kPa. Result: {} misses on {} of {} curves.\n",
        summary.curves,
        summary.curves.saturating_sub(1),
        summary.probes,
        summary.misses,
        summary.failed_curves,
        summary.curves,
    );
    let mut shapes: Vec<String> = run
        .calibrations
        .iter()
        .map(|result| result.shape.clone())
        .collect();
    shapes.sort();
    shapes.dedup();
    let _ = writeln!(
        out,
        "| shape | curves | probes | points | smallest margin inside the interval, kPa | largest distance from the reference pressure, kPa | pass |\n|---|---|---|---|---|---|---|"
    );
    for shape in shapes {
        let results: Vec<_> = run
            .calibrations
            .iter()
            .filter(|result| result.shape == shape)
            .collect();
        let (fewest, most) = results.iter().fold((u32::MAX, 0), |(low, high), result| {
            (low.min(result.points), high.max(result.points))
        });
        let _ = writeln!(
            out,
            "| {shape} | {} | {} | {fewest}–{most} | {} | {} | {} of {} |",
            results.len(),
            results.iter().map(|result| result.probes).sum::<u32>(),
            kpa(results
                .iter()
                .map(|result| result.min_margin_kpa)
                .fold(f64::INFINITY, f64::min)),
            kpa(results
                .iter()
                .map(|result| result.max_from_reference_kpa)
                .fold(0.0, f64::max)),
            results.iter().filter(|result| result.pass).count(),
            results.len(),
        );
    }
    let _ = writeln!(
        out,
        "\nThe margin is how far the worst answer lies inside its accepted interval: an answer \
         equal to the reference pressure has 0.01 kPa plus the pressure that 8 ulps of dC/C0 \
         span there; a margin below 0.01 kPa is an answer that far beyond the rounding \
         allowance. The distance from the reference pressure includes what the f32 rounding of \
         dC/C0 explains, large where the curve is nearly flat.\n"
    );
}

fn firmware(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Firmware flash and RAM\n");
    let footprint = match &data.firmware {
        Ok(footprint) => footprint,
        Err(reason) => {
            let _ = writeln!(
                out,
                "Not available: the firmware did not build ({reason}).\n"
            );
            return;
        }
    };
    let percent = |used: u64, budget: u64| 100.0 * used as f64 / budget as f64;
    let _ = writeln!(
        out,
        "Built by `cargo fw-build` (profile `firmware`, opt-level {} from `[profile.firmware]` \
         in Cargo.toml; ELF `{}` in the target directory), measured as `.ci/firmware-size` \
         measures it.\n",
        footprint.opt_level, footprint.path
    );
    let _ = writeln!(
        out,
        "| | bytes | budget | used | within |\n|---|---|---|---|---|\n\
         | flash (vector table, code, constants, .data initialisers) | {} | {} ({} KiB) | {:.1} % | {} |\n\
         | static RAM (.data, .bss, .uninit; the stack comes on top) | {} | {} ({} KiB) | {:.1} % | {} |\n",
        footprint.flash_bytes,
        FLASH_BUDGET_BYTES,
        FLASH_BUDGET_BYTES / 1024,
        percent(footprint.flash_bytes, FLASH_BUDGET_BYTES),
        if footprint.flash_bytes <= FLASH_BUDGET_BYTES {
            "yes"
        } else {
            "**no**"
        },
        footprint.ram_bytes,
        STATIC_RAM_BUDGET_BYTES,
        STATIC_RAM_BUDGET_BYTES / 1024,
        percent(footprint.ram_bytes, STATIC_RAM_BUDGET_BYTES),
        if footprint.ram_bytes <= STATIC_RAM_BUDGET_BYTES {
            "yes"
        } else {
            "**no**"
        },
    );
    let _ = writeln!(
        out,
        "| section | address | bytes | counted in |\n|---|---|---|---|"
    );
    for section in &footprint.sections {
        let counted = match (section.writable, section.no_bits) {
            (false, _) => "flash",
            (true, false) => "flash (initial values) and RAM",
            (true, true) => "RAM",
        };
        let _ = writeln!(
            out,
            "| `{}` | {:#010x} | {} | {counted} |",
            section.name, section.address, section.size
        );
    }
    let _ = writeln!(
        out,
        "\nWithin both budgets: {}.\n",
        if footprint.within_budget() {
            "yes"
        } else {
            "**no**"
        }
    );
}

fn microseconds(nanoseconds: f64) -> String {
    format!("{:.2}", nanoseconds / 1000.0)
}

fn latency_row(what: &str, latency: &Latency) -> String {
    format!(
        "| {what} | {} | {} | {} | {} | {} |",
        latency.count,
        microseconds(latency.mean_ns),
        microseconds(latency.p50_ns),
        microseconds(latency.p99_ns),
        microseconds(latency.max_ns),
    )
}

fn simulator(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Simulator throughput and latency\n");
    let figures = match &data.simulator {
        Ok(figures) => figures,
        Err(reason) => {
            let _ = writeln!(out, "Not available: {reason}\n");
            return;
        }
    };
    let _ = writeln!(
        out,
        "The simulated device (`sim_device::SimulatedDevice`: the firmware's acquisition loop, \
         model, device application and protocol code on the simulated FDC1004 and TMP117, \
         default scene, seed {}) stepped as fast as the host computes, single-threaded, release \
         build (`cargo xtask sim-bench`, `xtask/src/simulator.rs`). The host port says a host is \
         connected and encodes every outgoing frame with `device::encode_outgoing`, as the \
         firmware's USB task does. {} steps after {} unmeasured ones (boot, converter \
         initialisation, start-up tare).\n",
        crate::simulator::SEED,
        figures.steps,
        crate::simulator::WARM_UP_STEPS,
    );
    let _ = writeln!(
        out,
        "| throughput | |\n|---|---|\n\
         | sample sets per second, wall clock | {:.0} ({:.3} s for {} sets) |\n\
         | sample sets per second, thread CPU time | {:.0} ({:.3} s) |\n\
         | simulated time covered | {:.2} s ({:.0}x real time, wall clock) |\n\
         | frames encoded | {} ({} sample frames, the rest counters and events), {} bytes |\n\
         | simulated I2C transactions per sample set | {:.1} |\n",
        figures.sets_per_second_wall(),
        figures.wall_seconds,
        figures.steps,
        figures.sets_per_second_cpu(),
        figures.cpu_seconds,
        figures.simulated_seconds,
        figures.simulated_seconds / figures.wall_seconds,
        figures.frames,
        figures.sample_frames,
        figures.bytes,
        figures.transactions_per_step,
    );
    let _ = writeln!(
        out,
        "| latency, µs (wall clock) | sets | mean | p50 | p99 | max |\n|---|---|---|---|---|---|\n{}\n{}\n",
        latency_row(
            "converter cycle to encoded frame (live): from the device's last host-side call \
             before the cycle (`HostPort::try_receive`) to the end of `encode_outgoing` of the \
             step's sample frame",
            &figures.cycle_to_frame
        ),
        latency_row(
            "converter results to encoded frame (replay): `PadModel::process` of the step's \
             readings, `device::sample_frame` and `encode_outgoing`",
            &figures.model_to_frame
        ),
    );
    let _ = writeln!(
        out,
        "The live interval contains the whole converter cycle on the simulated bus: the \
         simulated converter and temperature sensor compute their answers on the host, and no \
         time passes on a real bus. The replay interval is the part after the readings are in: \
         before each step a copy of the pad model is taken, and after it the step's readings go \
         through the copy again, then into a frame and its encoding; {} of {} replayed frames \
         differed from the step's own, byte for byte. On the firmware the latency from a \
         converter sample to its frame is dominated by the I2C transfers (the converter's \
         results and the temperature: {:.1} transactions per sample set here), which this \
         measurement does not compute; only the computation after them is comparable, and the \
         M4's instruction counts above are the better guide to it. The maxima include whatever \
         the host's scheduler did meanwhile (wall clock on {} logical CPUs, load average {} \
         before criterion ran).\n",
        figures.replay_mismatches,
        figures.model_to_frame.count,
        figures.transactions_per_step,
        data.machine.cpus,
        data.machine.load_average,
    );
}
