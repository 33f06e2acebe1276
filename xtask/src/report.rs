//! docs/PERFORMANCE.md and docs/speed-vs-error.svg from the measurements: every number in them
//! comes from a run of `cargo xtask report` (or is a target, a constant of model-core, or a
//! parameter of the method), none is typed in.

use std::fmt::Write;

use model_core::inverse::POLYNOMIAL_DEGREE;
use model_core::use_case::{CONVERTER_NOISE_PF, MEASURED_INSTRUCTIONS, NOMINAL_SENSOR_PF};
use model_core::{TaxelFlags, Tier};

use crate::bench_output::BenchRun;
use crate::firmware::{Footprint, FLASH_BUDGET_BYTES, STATIC_RAM_BUDGET_BYTES};
use crate::host::{HostTime, LeaveOneOut, UseCaseSelection};
use crate::mix::{Mix, MixReport};
use crate::simulator::{Latency, SimulatorFigures};
use crate::svg::{Guide, Link, Plot, Point};

/// Targets of the performance work.
pub const DEFAULT_TIER_MAX_ERROR_KPA: f64 = 0.05;
/// See [`DEFAULT_TIER_MAX_ERROR_KPA`].
pub const DEFAULT_TIER_MAX_INSTRUCTIONS: f64 = 200.0;
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
    /// m4-bench at opt-level 3.
    pub opt3: BenchRun,
    /// m4-bench at opt-level "s".
    pub opt_s: BenchRun,
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

/// The two ways of counting a taxel conversion that the instruction targets are held against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Measure {
    /// `Baseline::relative_change` then the tier's inverse called directly: numerics.md's unit.
    CorrectedInversion,
    /// `TaxelModel::convert`: classification, dC/C0, dispatched inverse, output record.
    FullStep,
}

impl Measure {
    const BOTH: [Measure; 2] = [Measure::CorrectedInversion, Measure::FullStep];

    fn label(self) -> &'static str {
        match self {
            Measure::CorrectedInversion => {
                "taxel conversion as numerics.md counts it (temperature-corrected inversion)"
            }
            Measure::FullStep => {
                "full per-taxel model step (`TaxelModel::convert`, with fault classification and output)"
            }
        }
    }

    fn count(self, run: &BenchRun, tier: Tier) -> Option<f64> {
        match self {
            Measure::CorrectedInversion => run.corrected_count(tier).ok().map(|count| count.direct),
            Measure::FullStep => run.convert_count(tier).ok().map(|count| count.mean),
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
                .opt3
                .grid_result(tier)
                .ok()
                .map(|result| result.max_from_reference_curve_kpa),
            host: lookup(&data.host_convert, tier),
        })
        .collect()
}

/// The cheapest tier by `measure` among those within [`FAST_TIER_DISTANCE_KPA`] of the default
/// model: (tier, instructions, distance).
fn fastest_close(data: &ReportData, measure: Measure) -> Option<(Tier, f64, f64)> {
    figures(data)
        .iter()
        .filter_map(|figure| {
            let distance = figure.max_from_default_kpa?;
            let count = measure.count(&data.opt3, figure.tier)?;
            (distance <= FAST_TIER_DISTANCE_KPA).then_some((figure.tier, count, distance))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TargetKind {
    DefaultError,
    DefaultCost(Measure),
    FastCost(Measure),
    Host,
}

struct Target {
    kind: TargetKind,
    what: String,
    measure: String,
    measured: String,
    met: bool,
    gap: String,
}

fn instruction_gap(count: f64, target: f64) -> (bool, String) {
    if count <= target {
        (true, format!("{:.1} to spare", target - count))
    } else {
        (
            false,
            format!(
                "{:+.1} instructions ({:.2}x the target)",
                count - target,
                count / target
            ),
        )
    }
}

fn targets(data: &ReportData) -> Vec<Target> {
    let mut targets = Vec::new();
    let default = Tier::default();
    if let Ok(grid) = data.opt3.grid_result(default) {
        targets.push(Target {
            kind: TargetKind::DefaultError,
            what: format!(
                "default tier ({}): max numerical error on the M4 <= {DEFAULT_TIER_MAX_ERROR_KPA} kPa",
                default.name()
            ),
            measure: format!(
                "largest difference from the f64 reference over the {}-point grid",
                data.opt3.grid_points
            ),
            measured: format!("{} kPa", kpa(grid.max_error_kpa)),
            met: grid.max_error_kpa <= DEFAULT_TIER_MAX_ERROR_KPA,
            gap: format!(
                "{:.0}x margin",
                DEFAULT_TIER_MAX_ERROR_KPA / grid.max_error_kpa.max(1e-12)
            ),
        });
    }
    for measure in Measure::BOTH {
        let Some(count) = measure.count(&data.opt3, default) else {
            continue;
        };
        let detail = match measure {
            Measure::CorrectedInversion => data
                .opt3
                .corrected_count(default)
                .ok()
                .map(|count| {
                    format!(
                        " (inverse called directly; {:.1} through the run-time dispatch)",
                        count.dispatched
                    )
                })
                .unwrap_or_default(),
            Measure::FullStep => data
                .opt3
                .convert_count(default)
                .ok()
                .map(|count| {
                    format!(
                        " (grid mean; {:.1}–{:.1} over single inputs)",
                        count.min, count.max
                    )
                })
                .unwrap_or_default(),
        };
        let (met, gap) = instruction_gap(count, DEFAULT_TIER_MAX_INSTRUCTIONS);
        targets.push(Target {
            kind: TargetKind::DefaultCost(measure),
            what: format!(
                "default tier: <= {DEFAULT_TIER_MAX_INSTRUCTIONS:.0} M4 instructions per taxel conversion"
            ),
            measure: measure.label().to_string(),
            measured: format!("{count:.1}{detail}"),
            met,
            gap,
        });
    }
    for measure in Measure::BOTH {
        let Some((tier, count, distance)) = fastest_close(data, measure) else {
            continue;
        };
        let (met, gap) = instruction_gap(count, FAST_TIER_MAX_INSTRUCTIONS);
        targets.push(Target {
            kind: TargetKind::FastCost(measure),
            what: format!(
                "fastest tier within {FAST_TIER_DISTANCE_KPA} kPa of the default tier: <= {FAST_TIER_MAX_INSTRUCTIONS:.0} M4 instructions"
            ),
            measure: measure.label().to_string(),
            measured: format!(
                "{}, {} kPa from the default model: {count:.1}",
                tier.name(),
                kpa(distance)
            ),
            met,
            gap,
        });
    }
    let fastest_host = figures(data)
        .iter()
        .filter_map(|figure| figure.host.map(|host| (figure.tier, host)))
        .min_by(|a, b| a.1.nanoseconds.total_cmp(&b.1.nanoseconds));
    if let Some((tier, host)) = fastest_host {
        let met = host.per_second() >= HOST_MIN_CONVERSIONS_PER_SECOND;
        let close = fastest_close(data, Measure::FullStep).and_then(|(close, _, _)| {
            let host = lookup(&data.host_convert, close)?;
            (close != tier).then(|| {
                format!(
                    "; {} (fastest within {FAST_TIER_DISTANCE_KPA} kPa of the default): {:.1} M/s",
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
        let corrected = Measure::CorrectedInversion.count(&data.opt3, figure.tier);
        let full = Measure::FullStep.count(&data.opt3, figure.tier);
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
        title: "model-core on the Cortex-M4F: cost against error, per tier (opt-level 3)"
            .to_string(),
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
                format!("{FAST_TIER_MAX_INSTRUCTIONS:.0}"),
            ),
            Guide::Vertical(
                DEFAULT_TIER_MAX_INSTRUCTIONS,
                format!("{DEFAULT_TIER_MAX_INSTRUCTIONS:.0}"),
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

    let _ = writeln!(out, "## Targets\n");
    let _ = writeln!(
        out,
        "| target | measured as | measured | met | gap |\n|---|---|---|---|---|"
    );
    for target in targets(data) {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            target.what,
            target.measure,
            target.measured,
            if target.met { "yes" } else { "**no**" },
            target.gap
        );
    }
    let _ = writeln!(
        out,
        "\nThe instruction targets are held against both measures: numerics.md counts a taxel \
         conversion as the temperature-corrected inversion (dC/C0 from the reading, the baseline \
         and the temperature factor, then the tier's inverse); the full model step \
         `TaxelModel::convert` adds the fault classification, the run-time tier dispatch and the \
         output record. \"Within {FAST_TIER_DISTANCE_KPA} kPa of the default tier\" is the \
         largest distance from the f64 default model over the grid on the M4 (error table).\n"
    );
    gaps(out, data);

    measurement_method(out, data);
    cost_table(out, data);
    host_table(out, data);
    error_table(out, data);
    context_table(out, data);
    mix_table(out, data);
    polynomial_degree_table(out, data);

    let _ = writeln!(out, "## Speed against error\n");
    let _ = writeln!(
        out,
        "![M4 instructions per taxel conversion against the largest deviation from the default \
         model](speed-vs-error.svg)\n\n\
         One row of points per tier, at opt-level 3: filled, the temperature-corrected inversion; \
         hollow, the full model step `TaxelModel::convert`; the line joins the two. x is the mean \
         M4 instruction count over the grid; y is the largest distance from the f64 default \
         model (monotone cubic) over the grid on the M4, so what choosing the tier costs in \
         accuracy, numerical error included; the default tier's own point is its numerical \
         error. The opt-level \"s\" counts are in the cost table.\n"
    );

    hard_cases(out, &data.opt3);
    use_cases(out, data);
    drift(out, data);
    firmware(out, data);
    simulator(out, data);
    text
}

fn measurement_method(out: &mut String, data: &ReportData) {
    let run = &data.opt3;
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
         `thumbv7em-none-eabihf` (opt-level 3, fat LTO, one codegen unit; and again at \
         opt-level \"s\") on QEMU's `mps2-an386` (Cortex-M4 with FPU): `qemu-system-arm -machine \
         mps2-an386 -cpu cortex-m4 -icount shift=0 -semihosting-config enable=on,target=native \
         -nographic -kernel m4-bench`. With `-icount shift=0` virtual time advances 1 ns per \
         executed instruction and SysTick counts the 25 MHz processor clock, so one tick is \
         exactly 40 instructions: a count is (ticks around N calls - ticks around the same loop \
         with the call replaced by `black_box` of its inputs) x 40 / N. Counts are \
         deterministic (the same binary gives the same figures on any host).\n\
         - **Temperature-corrected inversion** (numerics.md's taxel conversion): \
         `Baseline::relative_change(SplitCapacitance, inverse_permittivity_ratio)` (dC/C0 from \
         the split capacitance, the baseline and the sample's temperature factor) followed by the \
         tier's inverse, called directly as in a build fixed to one tier (`mean` in m4-bench's \
         output), and through `TaxelInverses::pressure_kpa` with the tier chosen at run time \
         (`dispatched`). Over the grid's capacitance readings, {} passes.\n\
         - **Full model step**: `TaxelModel::convert(tier, ReadingValue, Some(&Baseline), \
         inverse_permittivity_ratio, &FaultThresholds)`: fault classification of the reading and \
         of dC/C0, the temperature-corrected dC/C0, the tier's inverse dispatched on a run-time \
         `Tier`, and the output record with its flags. The raw-code decode \
         (`TaxelReading::value`) and the per-sample temperature resolution are outside; the \
         whole `PadModel::process` per taxel is listed below for comparison. Mean over the \
         grid ({} passes); min–max over single inputs (whole kPa at 25 °C, {} repetitions \
         each).\n\
         - **Grid**: 0–50 kPa in 0.5 kPa steps x 5–55 °C in 5 °C steps ({} readings) of a taxel \
         with C0 = 4.5 pF and 6 pF parasitic, C = Cp + C0 (1 + f(P)) eps(T)/eps(25 °C) from the \
         f64 forward model, quantised to raw FDC1004 codes at CAPDAC 3, tared at 25 °C through \
         `PadModel`.\n\
         - **References** (computed on the host by m4-bench's build script, written to a binary \
         file the target includes): independent f64 implementations of each tier's model from \
         the same calibration points, applied to the f64 dC/C0 of the quantised reading (see \
         m4-bench/build/reference.rs). **(a) Numerical error** = |M4 - the tier's own \
         reference|; **distance from the default model** = |M4 - the f64 monotone cubic|.\n\
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
         CYCCNT as 0). The dynamic instruction mix comes from a QEMU trace (`-d \
         in_asm,exec,nochain` with an address filter on the benchmark loops and what they \
         call; see `xtask/src/mix.rs`); the Cortex-M4 timing tables then bound the cycles \
         (VDIV/VSQRT 14, VMLA/VFMA 3, loads 1–2, taken branches 2–4, LDM/STM 1 + N, +1 when an \
         FP result is used at once). Flash wait states are not modelled; on the STM32F411 the \
         ART accelerator's prefetch and instruction cache hide them in a hot loop.\n",
        run.grid_repetitions,
        run.grid_repetitions,
        run.single_repetitions,
        run.grid_points,
        left_out.join(", "),
        CONVERTER_NOISE_PF * 1000.0,
        NOMINAL_SENSOR_PF,
        noise_relative,
        run.grid_points,
    );
}

fn cost_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Cost per taxel conversion on the M4\n");
    let _ = writeln!(
        out,
        "| tier | corrected inversion, opt 3: direct | dispatched | opt \"s\": direct | full step `convert`, opt 3: grid mean (min–max) | opt \"s\" | s / 3 | est. cycles, full step, opt 3 |\n|---|---|---|---|---|---|---|---|"
    );
    for tier in Tier::ALL {
        let corrected = data.opt3.corrected_count(tier).ok();
        let corrected_s = data.opt_s.corrected_count(tier).ok();
        let count = data.opt3.convert_count(tier).ok();
        let count_s = data.opt_s.convert_count(tier).ok();
        let cycles = data.mix.as_ref().ok().and_then(|mix| {
            lookup(&mix.per_tier, tier)
                .map(|mix| format!("{:.0}–{:.0}", mix.cycles_lower(), mix.cycles_upper()))
        });
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            tier.name(),
            one_decimal(corrected.map(|count| count.direct)),
            one_decimal(corrected.map(|count| count.dispatched)),
            one_decimal(corrected_s.map(|count| count.direct)),
            optional(count, |count| format!(
                "{:.1} ({:.1}–{:.1})",
                count.mean, count.min, count.max
            )),
            one_decimal(count_s.map(|count| count.mean)),
            optional(count.zip(count_s), |(three, small)| format!(
                "{:.2}",
                small.mean / three.mean
            )),
            cycles.unwrap_or_else(|| "n/a".to_string()),
        );
    }
    let _ = writeln!(
        out,
        "\ndC/C0 alone (`Baseline::relative_change`) costs {} instructions at opt-level 3, {} at \
         \"s\": the floor under every corrected inversion.\n",
        one_decimal(data.opt3.functions.get("relative-change").copied()),
        one_decimal(data.opt_s.functions.get("relative-change").copied()),
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
        let grid = data.opt3.grid_result(tier).ok();
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
         grid on the M4 at opt-level 3 (opt-level \"s\" gives the same results: {}). \
         Leave-one-out errors per left-out point ({} kPa):\n",
        data.opt3.grid_points,
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
            let three = data.opt3.grid_result(tier).ok()?;
            let small = data.opt_s.grid_result(tier).ok()?;
            (three.max_error_kpa != small.max_error_kpa).then(|| {
                format!(
                    "{} {} vs {}",
                    tier.name(),
                    kpa(three.max_error_kpa),
                    kpa(small.max_error_kpa)
                )
            })
        })
        .collect();
    if differences.is_empty() {
        "identical maxima for every tier".to_string()
    } else {
        format!("maxima differ: {}", differences.join("; "))
    }
}

fn context_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Where the instructions go\n");
    let _ = writeln!(
        out,
        "| subject | M4 instructions, opt 3 | opt \"s\" | host ns |\n|---|---|---|---|"
    );
    let _ = writeln!(
        out,
        "| `Baseline::relative_change` (dC/C0 alone) | {} | {} | |",
        one_decimal(data.opt3.functions.get("relative-change").copied()),
        one_decimal(data.opt_s.functions.get("relative-change").copied()),
    );
    for tier in Tier::ALL {
        let _ = writeln!(
            out,
            "| `TaxelInverses::pressure_kpa`, {} (dispatch + inverse) | {} | {} | {} |",
            tier.name(),
            one_decimal(lookup(&data.opt3.inverse, tier)),
            one_decimal(lookup(&data.opt_s.inverse, tier)),
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
    let functions = [
        (
            "table-direct",
            "`TableInverse::pressure_kpa` called directly (no dispatch)".to_string(),
        ),
        (
            "f32-min",
            format!(
                "`f32::min`, for comparison (a call to `fminf`: FPv4-SP has no VMINNM{fminf_note})"
            ),
        ),
        ("libm-logf", "libm `logf`, x in [1, 8]".to_string()),
        ("libm-expf", "libm `expf`, x in [-5, 0]".to_string()),
        ("micromath-ln", "micromath `ln`, x in [1, 8]".to_string()),
    ];
    for (key, what) in functions {
        let _ = writeln!(
            out,
            "| {what} | {} | {} | |",
            one_decimal(data.opt3.functions.get(key).copied()),
            one_decimal(data.opt_s.functions.get(key).copied()),
        );
    }
    for tier in Tier::ALL {
        let _ = writeln!(
            out,
            "| `PadModel::process` per taxel, {} (raw decode, temperature, tare and tracking checks) | {} | {} | |",
            tier.name(),
            one_decimal(lookup(&data.opt3.pad, tier)),
            one_decimal(lookup(&data.opt_s.pad, tier)),
        );
    }
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
    let _ = writeln!(out, "## Instruction mix and cycle estimate (opt-level 3)\n");
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
            let count = data.opt3.convert_count(*tier).ok()?;
            Some((counts.instructions - count.single_mean).abs())
        })
        .fold(0.0, f64::max);
    let _ = writeln!(
        out,
        "Per call, traced in the `instruction-mix` build over the {} single inputs (whole kPa at \
         25 °C). That build holds the same code as the tested one (the probe is chosen at run \
         time). For the full step the SysTick column is the tested build's count over the same \
         inputs; the two agree within {:.1} instructions, the loops' own overhead being spread \
         differently: the trace runs each loop once over all {} inputs, the SysTick count \
         repeats each input {} times in an outer loop.\n",
        mix.inputs_per_tier, largest_difference, mix.inputs_per_tier, data.opt3.single_repetitions
    );
    let _ = writeln!(
        out,
        "**Full model step** (`TaxelModel::convert`):\n\n{MIX_HEADER}"
    );
    for (tier, counts) in &mix.per_tier {
        let systick = optional(data.opt3.convert_count(*tier).ok(), |count| {
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
            one_decimal(data.opt3.functions.get("relative-change").copied())
        )
    );
    for (tier, counts) in &mix.corrected {
        let systick = one_decimal(
            data.opt3
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
            data.opt3
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
    let run = &data.opt3;
    let Some((tier, count, distance)) = fastest_close(data, Measure::CorrectedInversion) else {
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

fn fast_full_step_gap(out: &mut String, data: &ReportData) {
    let run = &data.opt3;
    let Some((tier, count, _)) = fastest_close(data, Measure::FullStep) else {
        return;
    };
    let rest: Vec<f64> = Tier::ALL
        .into_iter()
        .filter_map(|tier| {
            Some(run.convert_count(tier).ok()?.mean - run.corrected_count(tier).ok()?.dispatched)
        })
        .collect();
    let (rest_min, rest_max) = rest
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), value| {
            (low.min(*value), high.max(*value))
        });
    let corrected = run.corrected_count(tier).ok();
    let linear_full = Measure::FullStep.count(run, Tier::Linear);
    let _ = writeln!(
        out,
        "- **The full model step** of {} costs {count:.1}: its corrected inversion {} (inverse \
         called directly), {} through the run-time dispatch, and the rest of `convert` (reading \
         and dC/C0 classification, the output record with its flags) {} more. Across tiers that \
         rest is {} instructions. Even the linear tier's full step costs {}{}. Closer to the \
         target would come classification once per sample set for the four taxels, a convert \
         specialised per tier (the dispatch costs {} here), and a leaner output record; the \
         measure numerics.md uses is the row above.",
        tier.name(),
        one_decimal(corrected.map(|count| count.direct)),
        one_decimal(corrected.map(|count| count.dispatched)),
        one_decimal(corrected.map(|corrected| count - corrected.dispatched)),
        if rest.is_empty() {
            "n/a".to_string()
        } else {
            format!("{rest_min:.1}–{rest_max:.1}")
        },
        one_decimal(linear_full),
        linear_full
            .filter(|linear| *linear > FAST_TIER_MAX_INSTRUCTIONS)
            .map(|linear| format!(
                ", {:.1} over the target: {FAST_TIER_MAX_INSTRUCTIONS:.0} instructions per full \
                 step is out of reach as `TaxelModel::convert` is structured",
                linear - FAST_TIER_MAX_INSTRUCTIONS
            ))
            .unwrap_or_default(),
        one_decimal(corrected.map(|count| count.dispatched - count.direct)),
    );
}

fn default_cost_gap(out: &mut String, data: &ReportData, measure: Measure) {
    let run = &data.opt3;
    let default = Tier::default();
    let Some(count) = measure.count(run, default) else {
        return;
    };
    let vdiv = data
        .mix
        .as_ref()
        .ok()
        .and_then(|mix| lookup(&mix.corrected, default))
        .map(|mix| mix.fp_divide);
    let _ = writeln!(
        out,
        "- **The default tier** ({}) costs {count:.1} as a {}, {:.1} over the target. Its \
         corrected inversion costs {} against the linear tier's {}: a search for the segment, \
         Newton steps on the cubic (each with one VDIV: {} per conversion in the trace, 14 \
         cycles each) and the clamp. Fewer Newton steps or a polynomial of the inverse per \
         segment would change the algorithm and its error; the choice is model-core's.",
        default.name(),
        measure.label(),
        count - DEFAULT_TIER_MAX_INSTRUCTIONS,
        one_decimal(Measure::CorrectedInversion.count(run, default)),
        one_decimal(Measure::CorrectedInversion.count(run, Tier::Linear)),
        optional(vdiv, |vdiv| format!("{vdiv:.2}")),
    );
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
    let _ = writeln!(out, "### What the missed targets would take\n");
    let _ = writeln!(
        out,
        "model-core's algorithms are left as they are; these are the measured parts of the cost \
         (SysTick counts at opt-level 3, grid means; instruction classes from the trace) and \
         what would remove them.\n"
    );
    for measure in Measure::BOTH {
        if missed.contains(&TargetKind::DefaultCost(measure)) {
            default_cost_gap(out, data, measure);
        }
    }
    if missed.contains(&TargetKind::FastCost(Measure::CorrectedInversion)) {
        fast_corrected_gap(out, data);
    }
    if missed.contains(&TargetKind::FastCost(Measure::FullStep)) {
        fast_full_step_gap(out, data);
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
    let _ = writeln!(out, "## Hard cases on the M4 (opt-level 3)\n");
    let _ = writeln!(
        out,
        "Each case is a fresh pad, tared with one unloaded sample set, then the reading through \
         `PadModel::process` with every tier. A case passes when the flags are exactly the \
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
        let mut row = format!(
            "| `{}`: {} | `{}` | `{}` | {} |",
            case.name,
            case.description,
            case.reading,
            case.temperature,
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
        "`model_core::select_tier` on the article's curve picks the cheapest tier (by \
         `MEASURED_INSTRUCTIONS`) whose error over the use case's pressure range, measured \
         against the reference curve, plus the converter noise at the top of the range, fits \
         the budget.\n"
    );
    for selection in &data.use_cases {
        let use_case = selection.use_case;
        let verdict = match &selection.selected {
            Ok(choice) => format!(
                "**{}**: {} kPa model error + {} kPa noise = {} kPa within {} kPa, {} instructions",
                choice.tier.name(),
                kpa(f64::from(choice.model_error_kpa)),
                kpa(f64::from(choice.noise_kpa)),
                kpa(f64::from(choice.total_error_kpa())),
                use_case.error_budget_kpa,
                choice.instructions
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
            "| tier | instructions | model error | noise | total | fits |\n|---|---|---|---|---|---|"
        );
        for choice in evaluated {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} |",
                choice.tier.name(),
                choice.instructions,
                kpa(f64::from(choice.model_error_kpa)),
                kpa(f64::from(choice.noise_kpa)),
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
    let _ = writeln!(
        out,
        "The constants in `model-core/src/use_case.rs` that `select_tier` ranks tiers by, against \
         this run (grid mean, opt-level 3). `cargo xtask m4-test` fails when a tier drifts more \
         than {:.0} % from its constant.\n",
        crate::DRIFT_TOLERANCE * 100.0
    );
    let _ = writeln!(
        out,
        "| tier | constant | measured | drift |\n|---|---|---|---|"
    );
    for (tier, constant) in MEASURED_INSTRUCTIONS {
        let measured = data.opt3.convert_count(tier).ok().map(|count| count.mean);
        let _ = writeln!(
            out,
            "| {} | {constant} | {} | {} |",
            tier.name(),
            optional(measured, |value| format!("{value:.1}")),
            optional(measured.filter(|_| constant > 0), |value| format!(
                "{:+.1} %",
                100.0 * (value / f64::from(constant) - 1.0)
            ))
        );
    }
    let _ = writeln!(out);
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
