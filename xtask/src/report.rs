//! docs/PERFORMANCE.md and docs/speed-vs-error.svg from the measurements: every number in them
//! comes from a run of this command, none is typed in.

use std::fmt::Write;

use model_core::use_case::MEASURED_INSTRUCTIONS;
use model_core::{TaxelFlags, Tier};

use crate::bench_output::BenchRun;
use crate::host::{HostTime, LeaveOneOut, UseCaseSelection};
use crate::mix::MixReport;
use crate::svg::{Guide, Plot, Point};

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

/// The firmware's footprint, if an ELF was found.
#[derive(Debug, Clone, PartialEq)]
pub enum Firmware {
    /// No firmware ELF at the looked-up paths.
    NotBuilt {
        /// Paths looked at, relative to the workspace root.
        looked_at: Vec<String>,
    },
    /// Sizes from the ELF.
    Built {
        /// The ELF, relative to the workspace root.
        path: String,
        /// Flash bytes (code, constants, .data initialisers).
        flash_bytes: u64,
        /// Static RAM bytes (.data, .bss, .uninit), stack not included.
        ram_bytes: u64,
    },
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
    /// Where it ran.
    pub machine: Machine,
    /// Firmware footprint hook.
    pub firmware: Firmware,
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

/// A tier's figures gathered from every source.
struct TierFigures {
    tier: Tier,
    instructions: Option<f64>,
    instructions_s: Option<f64>,
    max_from_default_kpa: Option<f64>,
    host: Option<HostTime>,
}

fn figures(data: &ReportData) -> Vec<TierFigures> {
    Tier::ALL
        .into_iter()
        .map(|tier| TierFigures {
            tier,
            instructions: data.opt3.convert_count(tier).ok().map(|count| count.mean),
            instructions_s: data.opt_s.convert_count(tier).ok().map(|count| count.mean),
            max_from_default_kpa: data
                .opt3
                .grid_result(tier)
                .ok()
                .map(|result| result.max_from_reference_curve_kpa),
            host: lookup(&data.host_convert, tier),
        })
        .collect()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TargetKind {
    DefaultError,
    DefaultCost,
    FastCost,
    Host,
}

struct Target {
    kind: TargetKind,
    what: String,
    measured: String,
    met: bool,
    gap: String,
}

fn targets(data: &ReportData) -> Vec<Target> {
    let mut targets = Vec::new();
    let default = Tier::default();
    let figures = figures(data);
    if let Ok(grid) = data.opt3.grid_result(default) {
        targets.push(Target {
            kind: TargetKind::DefaultError,
            what: format!(
                "default tier ({}): max numerical error on the M4 <= {DEFAULT_TIER_MAX_ERROR_KPA} kPa",
                default.name()
            ),
            measured: format!("{} kPa", kpa(grid.max_error_kpa)),
            met: grid.max_error_kpa <= DEFAULT_TIER_MAX_ERROR_KPA,
            gap: format!(
                "{:.0}x margin",
                DEFAULT_TIER_MAX_ERROR_KPA / grid.max_error_kpa.max(1e-12)
            ),
        });
    }
    if let Ok(count) = data.opt3.convert_count(default) {
        let met = count.mean <= DEFAULT_TIER_MAX_INSTRUCTIONS;
        targets.push(Target {
            kind: TargetKind::DefaultCost,
            what: format!(
                "default tier: <= {DEFAULT_TIER_MAX_INSTRUCTIONS:.0} instructions per taxel conversion"
            ),
            measured: format!(
                "{:.1} (grid mean; {:.1}–{:.1} over single inputs)",
                count.mean, count.min, count.max
            ),
            met,
            gap: if met {
                format!("{:.1} to spare", DEFAULT_TIER_MAX_INSTRUCTIONS - count.mean)
            } else {
                format!(
                    "{:+.1} instructions ({:+.1} %)",
                    count.mean - DEFAULT_TIER_MAX_INSTRUCTIONS,
                    100.0 * (count.mean / DEFAULT_TIER_MAX_INSTRUCTIONS - 1.0)
                )
            },
        });
    }
    let fastest_close = figures
        .iter()
        .filter(|figure| {
            figure
                .max_from_default_kpa
                .is_some_and(|distance| distance <= FAST_TIER_DISTANCE_KPA)
        })
        .filter_map(|figure| {
            figure
                .instructions
                .map(|count| (figure.tier, count, figure))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    if let Some((tier, count, figure)) = fastest_close {
        let met = count <= FAST_TIER_MAX_INSTRUCTIONS;
        targets.push(Target {
            kind: TargetKind::FastCost,
            what: format!(
                "fastest tier within {FAST_TIER_DISTANCE_KPA} kPa of the default tier: <= {FAST_TIER_MAX_INSTRUCTIONS:.0} instructions"
            ),
            measured: format!(
                "{} ({} kPa from the default model): {count:.1}",
                tier.name(),
                optional(figure.max_from_default_kpa, kpa)
            ),
            met,
            gap: if met {
                format!("{:.1} to spare", FAST_TIER_MAX_INSTRUCTIONS - count)
            } else {
                format!(
                    "{:+.1} instructions ({:.1}x the target)",
                    count - FAST_TIER_MAX_INSTRUCTIONS,
                    count / FAST_TIER_MAX_INSTRUCTIONS
                )
            },
        });
    }
    let fastest_host = figures
        .iter()
        .filter_map(|figure| figure.host.map(|host| (figure.tier, host)))
        .min_by(|a, b| a.1.nanoseconds.total_cmp(&b.1.nanoseconds));
    if let Some((tier, host)) = fastest_host {
        let met = host.per_second() >= HOST_MIN_CONVERSIONS_PER_SECOND;
        targets.push(Target {
            kind: TargetKind::Host,
            what: "host: >= 100 M taxel conversions/s on one core, fastest tier".to_string(),
            measured: format!(
                "{}: {:.1} M/s ({:.2} ns per conversion){}",
                tier.name(),
                host.per_second() / 1e6,
                host.nanoseconds,
                fastest_close
                    .and_then(|(close, _, _)| {
                        let host = lookup(&data.host_convert, close)?;
                        (close != tier).then(|| {
                            format!(
                                "; {} (fastest within {FAST_TIER_DISTANCE_KPA} kPa of the default): {:.1} M/s",
                                close.name(),
                                host.per_second() / 1e6
                            )
                        })
                    })
                    .unwrap_or_default()
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
    const COLOURS: [&str; 6] = [
        "#7f7f7f", "#2ca02c", "#1f77b4", "#ff7f0e", "#d62728", "#9467bd",
    ];
    let mut points = Vec::new();
    for (figure, colour) in figures(data).into_iter().zip(COLOURS) {
        let Some(y) = figure.max_from_default_kpa else {
            continue;
        };
        if let Some(x) = figure.instructions {
            points.push(Point {
                label: Some(figure.tier.name().to_string()),
                x,
                y,
                filled: true,
                colour,
            });
        }
        if let Some(x) = figure.instructions_s {
            points.push(Point {
                label: None,
                x,
                y,
                filled: false,
                colour,
            });
        }
    }
    Plot {
        title: "model-core on the Cortex-M4F: cost against error, per tier".to_string(),
        x_label: "M4 instructions per taxel conversion (QEMU icount, mean over the grid)"
            .to_string(),
        y_label: "max |P - P_default| on the M4, kPa (log)".to_string(),
        notes: vec![
            "filled: opt-level 3; hollow: opt-level \"s\" (same error, different cost).".to_string(),
            "y: largest deviation from the f64 reference of the default model (monotone cubic) over 0-50 kPa x 5-55 °C;".to_string(),
            "for monotone-cubic itself that is its numerical error. Dashed: the targets.".to_string(),
        ],
        points,
        guides: vec![
            Guide::Horizontal(FAST_TIER_DISTANCE_KPA, "0.5 kPa from the default tier".to_string()),
            Guide::Horizontal(DEFAULT_TIER_MAX_ERROR_KPA, "0.05 kPa".to_string()),
            Guide::Vertical(FAST_TIER_MAX_INSTRUCTIONS, "30".to_string()),
            Guide::Vertical(DEFAULT_TIER_MAX_INSTRUCTIONS, "200".to_string()),
        ],
    }
}

/// docs/PERFORMANCE.md.
pub fn markdown(data: &ReportData) -> String {
    let mut text = String::new();
    let out = &mut text;
    let _ = writeln!(out, "# Performance of model-core\n");
    let _ = writeln!(
        out,
        "<!-- Generated by `cargo xtask report`: do not edit by hand, run it again. -->\n"
    );
    let _ = writeln!(
        out,
        "**Generated** by `cargo xtask report` (a few minutes, most of it criterion); never \
         edited by hand. Machine: {} ({} logical CPUs), {}, {}. The on-target part alone, with \
         its checks, is `cargo xtask m4-test` (CI runs it).\n",
        data.machine.cpu, data.machine.cpus, data.machine.rustc, data.machine.qemu
    );

    let _ = writeln!(out, "## Targets\n");
    let _ = writeln!(out, "| target | measured | met | gap |\n|---|---|---|---|");
    for target in targets(data) {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} |",
            target.what,
            target.measured,
            if target.met { "yes" } else { "**no**" },
            target.gap
        );
    }
    let _ = writeln!(out);
    gaps(out, data);

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
         - **Instructions per taxel conversion** are those of `TaxelModel::convert(tier, \
         ReadingValue, Some(&Baseline), inverse_permittivity_ratio, &FaultThresholds)`: fault \
         classification, the temperature-corrected dC/C0, the tier's inverse (dispatched on a \
         run-time `Tier`) and the output with its flags. The raw-code decode \
         (`TaxelReading::value`) and the per-sample temperature resolution are outside; the \
         whole `PadModel::process` per taxel is listed below for comparison. Mean over the \
         grid below; min–max over single inputs (whole kPa at 25 °C, 64 repetitions each).\n\
         - **Grid**: 0–50 kPa in 0.5 kPa steps x 5–55 °C in 5 °C steps (101 x 11 = 1111 \
         readings) of a taxel with C0 = 4.5 pF and 6 pF parasitic, C = Cp + C0 (1 + f(P)) \
         eps(T)/eps(25 °C) from the f64 forward model, quantised to raw FDC1004 codes at CAPDAC \
         3, tared at 25 °C through `PadModel`.\n\
         - **References** (computed on the host by m4-bench's build script, written to a binary \
         file the target includes): independent f64 implementations of each tier's model from \
         the same calibration points — the Fritsch–Carlson forward cubic in Hermite form \
         inverted by bisection, the secant and the secants between points, an f64 \
         least-squares fit of A (1 - exp(-P/B)) inverted in closed form, and a 64-interval \
         table of f64 samples of the cubic's inverse interpolated in f64 — applied to the \
         f64 dC/C0 of the quantised reading. **(a) Numerical error** = |M4 - the tier's own \
         reference|; **distance from the default model** = |M4 - the f64 monotone cubic|.\n\
         - **(b) Model-form error**: leave-one-out on the article's Table 1, with model-core on \
         the host: each interior point (10, 20, 30, 40 kPa) is left out, the tier rebuilt from \
         the other five predicts it.\n\
         - **(c) Pressure noise**: 0.5 fF rms converter noise on C0 = 4.5 pF is 1.1e-4 in \
         dC/C0; times the tier's own dP/d(dC/C0) at the pressure (central difference over +-1 \
         sigma, model-core on the host).\n\
         - **Host**: criterion 0.8 (`model-core/benches/tiers.rs`), the same grid, one thread, \
         converted as a host tool converts a recording (readings from memory, results to \
         memory, model and tier opaque to the compiler once per pass); time per conversion = \
         thread CPU time per pass over the grid / 1111. The tier is fixed for a pass, so the \
         compiler may hoist its dispatch out of the loop; the M4 count dispatches per call.\n\
         - **Cycles** are estimated, not measured (QEMU models no pipeline, and reads DWT \
         CYCCNT as 0). The dynamic instruction mix of each tier comes from a QEMU trace \
         (`-d in_asm,exec,nochain` with an address filter on the benchmark loop and what it \
         calls; see `xtask/src/mix.rs`); the Cortex-M4 timing tables then bound the cycles: \
         1 per instruction, VDIV/VSQRT 14, VMLA/VFMA 3, VSTR 2, LDM/STM/PUSH/POP and their FP \
         forms 1 + N, taken branches 1 + P (P = 1–3), SDIV/UDIV 2–12, LDR/VLDR 2 (1 when \
         pipelined), +1 when an FP result is used by the next instruction. The lower bound \
         takes the best case of each, the upper the worst. Flash wait states are not \
         modelled: on the STM32F411 at 100 MHz flash needs 3 wait states, which the ART \
         accelerator's prefetch and 1 KiB instruction cache hide in a hot loop like this one.\n"
    );

    cost_table(out, data);
    error_table(out, data);
    context_table(out, data);
    mix_table(out, data);

    let _ = writeln!(out, "## Speed against error\n");
    let _ = writeln!(
        out,
        "![M4 instructions per taxel conversion against the largest deviation from the default \
         model](speed-vs-error.svg)\n\n\
         Each tier at opt-level 3 (filled) and \"s\" (hollow). The y value is what choosing the \
         tier costs in accuracy on the M4, numerical error included; the default tier's own \
         point is its numerical error.\n"
    );

    hard_cases(out, &data.opt3);
    use_cases(out, data);
    drift(out, data);
    firmware(out, data);
    text
}

fn cost_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Cost per taxel conversion\n");
    let _ = writeln!(
        out,
        "| tier | M4 instructions, opt 3: grid mean (min–max) | opt \"s\": mean | s / 3 | est. cycles, opt 3 | host ns, CPU time | host M conversions/s | host ns, wall clock |\n|---|---|---|---|---|---|---|---|"
    );
    for figure in figures(data) {
        let count = data.opt3.convert_count(figure.tier).ok();
        let cycles = data.mix.as_ref().ok().and_then(|mix| {
            lookup(&mix.per_tier, figure.tier)
                .map(|mix| format!("{:.0}–{:.0}", mix.cycles_lower(), mix.cycles_upper()))
        });
        let wall = lookup(&data.host_convert_wall, figure.tier);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            figure.tier.name(),
            optional(count, |count| format!(
                "{:.1} ({:.1}–{:.1})",
                count.mean, count.min, count.max
            )),
            optional(figure.instructions_s, |value| format!("{value:.1}")),
            optional(
                figure.instructions.zip(figure.instructions_s),
                |(three, small)| format!("{:.2}", small / three)
            ),
            cycles.unwrap_or_else(|| "n/a".to_string()),
            optional(figure.host, |host| format!(
                "{:.2} ({:.2}–{:.2})",
                host.nanoseconds, host.lower_nanoseconds, host.upper_nanoseconds
            )),
            optional(figure.host, |host| format!(
                "{:.0}",
                host.per_second() / 1e6
            )),
            optional(wall, |host| format!("{:.2}", host.nanoseconds)),
        );
    }
    let _ = writeln!(
        out,
        "\nHost figures are criterion means (95 % confidence interval in brackets) of the \
         benchmarking thread's CPU time, so that time slices given to other processes do not \
         count; the wall-clock column is the same benchmark timed by the clock. They depend on \
         the machine and on what else runs on it (load average {} when criterion started, on {} \
         logical CPUs); the M4 counts do not.\n",
        data.machine.load_average, data.machine.cpus
    );
}

fn error_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Error\n");
    let _ = writeln!(
        out,
        "| tier | (a) numerical, M4: max | rms | worst at | tolerance | from the default model, M4: max | rms | (b) leave-one-out: max | rms | (c) noise at 5 / 25 / 45 kPa |\n|---|---|---|---|---|---|---|---|---|---|"
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
        "\nAll figures in kPa. (a) and the distance from the default model are over the 1111-point \
         grid on the M4 at opt-level 3 (opt-level \"s\" gives the same results: {}). \
         Leave-one-out errors per left-out point (10 / 20 / 30 / 40 kPa):\n",
        same_results_text(data)
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
    for tier in Tier::ALL {
        let _ = writeln!(
            out,
            "| `TaxelInverses::pressure_kpa`, {} (dispatch + inverse) | {} | {} | {} |",
            tier.name(),
            optional(lookup(&data.opt3.inverse, tier), |value| format!(
                "{value:.1}"
            )),
            optional(lookup(&data.opt_s.inverse, tier), |value| format!(
                "{value:.1}"
            )),
            optional(lookup(&data.host_inverse, tier), |host| format!(
                "{:.2}",
                host.nanoseconds
            )),
        );
    }
    let functions = [
        (
            "table-direct",
            "`TableInverse::pressure_kpa` called directly (no dispatch)",
        ),
        (
            "f32-min",
            "`f32::min` (a call to `fminf`: FPv4-SP has no VMINNM)",
        ),
        ("libm-logf", "libm `logf`, x in [1, 8]"),
        ("libm-expf", "libm `expf`, x in [-5, 0]"),
        ("micromath-ln", "micromath `ln`, x in [1, 8]"),
    ];
    for (key, what) in functions {
        let _ = writeln!(
            out,
            "| {what} | {} | {} | |",
            optional(data.opt3.functions.get(key), |value| format!("{value:.1}")),
            optional(data.opt_s.functions.get(key), |value| format!("{value:.1}")),
        );
    }
    for tier in Tier::ALL {
        let _ = writeln!(
            out,
            "| `PadModel::process` per taxel, {} (raw decode, temperature, tare and tracking checks) | {} | {} | |",
            tier.name(),
            optional(lookup(&data.opt3.pad, tier), |value| format!("{value:.1}")),
            optional(lookup(&data.opt_s.pad, tier), |value| format!("{value:.1}")),
        );
    }
    let _ = writeln!(out);
}

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
        "Per conversion, over the {} single inputs (whole kPa at 25 °C), traced in the \
         `instruction-mix` build. The SysTick column is the tested build's count over the same \
         inputs: the two methods agree within {:.1} instructions (the two builds inline a little \
         differently, and the loops' entry and exit are spread over 51 calls in the trace, 64 \
         in the SysTick count).\n",
        mix.inputs_per_tier, largest_difference
    );
    let _ = writeln!(
        out,
        "| tier | traced instructions | SysTick, same inputs | VDIV/VSQRT | VMLA/VFMA | other FP arithmetic | LDR/VLDR | words in LDM/STM/PUSH/POP | branches always / conditional | est. cycles (lower–upper) |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for (tier, counts) in &mix.per_tier {
        let _ = writeln!(
            out,
            "| {} | {:.1} | {} | {:.2} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} / {:.1} | {:.0}–{:.0} |",
            tier.name(),
            counts.instructions,
            optional(data.opt3.convert_count(*tier).ok(), |count| format!(
                "{:.1}",
                count.single_mean
            )),
            counts.fp_divide,
            counts.fp_multiply_accumulate,
            counts.fp_arithmetic,
            counts.single_loads,
            counts.multiple_words,
            counts.unconditional_branches,
            counts.conditional_branches,
            counts.cycles_lower(),
            counts.cycles_upper(),
        );
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

fn gaps(out: &mut String, data: &ReportData) {
    let run = &data.opt3;
    let number = |value: Option<f64>| optional(value, |value| format!("{value:.1}"));
    let overhead = |tier: Tier| -> Option<f64> {
        Some(run.convert_count(tier).ok()?.mean - lookup(&run.inverse, tier)?)
    };
    let default = Tier::default();
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
         and what would remove them.\n"
    );
    let m4_cost_missed =
        missed.contains(&TargetKind::DefaultCost) || missed.contains(&TargetKind::FastCost);
    if m4_cost_missed {
        let overheads: Vec<f64> = Tier::ALL.into_iter().filter_map(overhead).collect();
        let (overhead_min, overhead_max) = overheads
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), value| {
                (low.min(*value), high.max(*value))
            });
        let _ = writeln!(
            out,
            "- **The conversion around the inverse** costs {overhead_min:.0}–{overhead_max:.0} \
             instructions whatever the tier (`convert` minus `TaxelInverses::pressure_kpa`; {} \
             with the table tier): fault classification of the reading and of dC/C0, the \
             temperature-corrected dC/C0 formed part by part from the split capacitance, and the \
             output with its flags. The linear tier, whose inverse is one multiply and a clamp, \
             costs {} in total: no tier can get below that inside `TaxelModel::convert` as it \
             stands, so 30 instructions per conversion is out of reach without a leaner hot path \
             (e.g. dC/C0 and classification once per sample set for all four taxels, or a \
             convert specialised per tier).",
            number(overhead(Tier::Table)),
            number(run.convert_count(Tier::Linear).ok().map(|count| count.mean)),
        );
        let _ = writeln!(
            out,
            "- **`f32::min`** in `clamp_pressure` (every tier) is a call to `fminf` on the \
             Cortex-M4F, {} instructions where a compare and a conditional move would take \
             about 3.",
            number(run.functions.get("f32-min").copied())
        );
        let _ = writeln!(
            out,
            "- **Run-time tier dispatch**: `TaxelInverses::pressure_kpa` on the table tier costs \
             {}, the table called directly {}; choosing the tier once per sample set (or at \
             compile time) would save the difference.",
            number(lookup(&run.inverse, Tier::Table)),
            number(run.functions.get("table-direct").copied())
        );
    }
    if missed.contains(&TargetKind::DefaultCost) {
        let vdiv = data
            .mix
            .as_ref()
            .ok()
            .and_then(|mix| lookup(&mix.per_tier, default))
            .map(|mix| mix.fp_divide);
        let _ = writeln!(
            out,
            "- **The default tier's inverse** costs {} instructions, {} more than the linear \
             tier's: a linear search for the segment (up to five comparisons on Table 1), then \
             Newton steps from the secant guess, each a cubic, its slope and one VDIV ({} VDIV per \
             conversion in the trace, 14 cycles each), then the clamp. The target needs {} fewer \
             per conversion; the candidates are one Newton step fewer, or a per-segment \
             polynomial of the inverse fitted at construction (numerics.md: a degree-5 \
             polynomial is 10–12 instructions, 0.06 kPa), and the `fminf` call above. The first \
             two change the algorithm and its error; none was measured here; the choice is \
             model-core's.",
            number(lookup(&run.inverse, default)),
            number(
                lookup(&run.inverse, default)
                    .zip(lookup(&run.inverse, Tier::Linear))
                    .map(|(cubic, linear)| cubic - linear)
            ),
            number(vdiv),
            number(
                run.convert_count(default)
                    .ok()
                    .map(|count| count.mean - DEFAULT_TIER_MAX_INSTRUCTIONS)
            ),
        );
    }
    if missed.contains(&TargetKind::DefaultError) {
        let _ = writeln!(
            out,
            "- **The default tier's numerical error** is above 0.05 kPa on the M4: see the error \
             table for where, and the hard cases for which inputs."
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
             ({} M/s); 100 M/s needs 10 ns. The inverse alone takes {} ns for that tier, so \
             most of the time is the same conversion around the inverse as on the M4. The \
             machine matters: the load average was {} on {} logical CPUs when criterion ran, \
             and a shared core slows a thread even when its CPU time is what is counted. \
             Converting the four taxels of a sample set together (one temperature factor, one \
             dispatch, vectorisable arithmetic) is where the rest would have to come from; it \
             was not tried here.",
            optional(fastest, |(_, host)| format!("{:.2}", host.nanoseconds)),
            optional(fastest, |(_, host)| format!(
                "{:.0}",
                host.per_second() / 1e6
            )),
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
    let _ = writeln!(out, "## Firmware and simulator (hook)\n");
    let _ = writeln!(
        out,
        "<!-- Hook: filled by `firmware_section` and `simulator_section` in xtask/src/main.rs. -->\n"
    );
    match &data.firmware {
        Firmware::Built {
            path,
            flash_bytes,
            ram_bytes,
        } => {
            let _ = writeln!(
                out,
                "- Firmware `{path}`: {flash_bytes} bytes of flash (code, constants, .data \
                 initialisers), {ram_bytes} bytes of static RAM (.data, .bss, .uninit; stack not \
                 included)."
            );
        }
        Firmware::NotBuilt { looked_at } => {
            let _ = writeln!(
                out,
                "- Firmware flash/RAM: not built (no ELF at {}).",
                looked_at
                    .iter()
                    .map(|path| format!("`{path}`"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            );
        }
    }
    let _ = writeln!(
        out,
        "- Simulator throughput/latency: not measured yet (no simulator benchmark is wired in).\n"
    );
}
