//! docs/PERFORMANCE.md and docs/speed-vs-error.svg from the measurements: every number in them
//! comes from a run of `cargo xtask report` (or is a target, a constant of model-core, or a
//! parameter of the method), none is typed in.

use std::fmt::Write;

use model_core::conditioning::{CONVERTER_NOISE_PF, NOMINAL_SENSOR_PF};
use model_core::inverse::POLYNOMIAL_DEGREE;
use model_core::use_case::MEASURED_INSTRUCTIONS;
use model_core::{SelectionError, TaxelFlags, Tier, TierChoice};
use plotters::style::RGBColor;

use crate::bench_output::BenchRun;
use crate::firmware::{Footprint, FLASH_BUDGET_BYTES, STATIC_RAM_BUDGET_BYTES};
use crate::host::{HostTime, LeaveOneOut, UseCaseSelection};
use crate::mix::{Mix, MixReport};
use crate::pad_rates::PadRate;
use crate::simulator::{Latency, SimulatorFigures};
use crate::speed_plot::{Guide, Link, Plot, Point};

mod cases;
mod gaps;
mod method;
mod mix_tables;
mod system;
mod targets;

use cases::*;
use gaps::*;
use method::*;
use mix_tables::*;
use system::*;
use targets::*;

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
    /// Host thread CPU time per taxel conversion of `PadModel::process_all` (the batch path),
    /// per tier.
    pub host_batch: Vec<(Tier, HostTime)>,
    /// Host thread CPU time per value of `ActiveInverse::pressures_kpa` (the batch path's
    /// inverse), per tier.
    pub host_batch_inverse: Vec<(Tier, HostTime)>,
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
    /// The sample-set rate per pad count and bus clock (or why it is missing).
    pub pad_rates: Result<Vec<PadRate>, String>,
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

/// The colour of a research tier in the speed-vs-error picture: a light grey, apart from the
/// tier colours (the linear tier's own is a darker grey).
const RESEARCH_COLOUR: RGBColor = RGBColor(0xaa, 0xaa, 0xaa);

/// The Pareto front of cost against error in the shipped build: the tiers no other tier beats
/// on both the temperature-corrected inversion's instruction count and the largest distance
/// from the default model, cheapest first, as (tier, instructions, distance in kPa).
fn pareto_front(data: &ReportData) -> Vec<(Tier, f64, f64)> {
    let measured: Vec<(Tier, f64, f64)> = figures(data)
        .iter()
        .filter_map(|figure| {
            let count = Measure::CorrectedInversion.count(&data.shipped, figure.tier)?;
            Some((figure.tier, count, figure.max_from_default_kpa?))
        })
        .collect();
    front_of(&measured)
}

/// The points of `measured` (tier, cost, error) that no other point beats on both, cheapest
/// first.
fn front_of(measured: &[(Tier, f64, f64)]) -> Vec<(Tier, f64, f64)> {
    let mut front: Vec<(Tier, f64, f64)> = measured
        .iter()
        .copied()
        .filter(|&(_, count, distance)| {
            !measured.iter().any(|&(_, other_count, other_distance)| {
                other_count <= count
                    && other_distance <= distance
                    && (other_count < count || other_distance < distance)
            })
        })
        .collect();
    front.sort_by(|a, b| a.1.total_cmp(&b.1));
    front
}

/// Tier names joined for prose: "`a`, `b` and `c`".
fn tier_names(tiers: impl IntoIterator<Item = Tier>) -> String {
    let names: Vec<String> = tiers
        .into_iter()
        .map(|tier| format!("`{}`", tier.name()))
        .collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        Some((last, _)) => last.clone(),
        None => "none".to_string(),
    }
}

/// Which tiers the device builds and which are research-only, against the measured front.
fn device_tiers(out: &mut String, data: &ReportData) {
    let front = pareto_front(data);
    let research = Tier::ALL.into_iter().filter(|tier| tier.is_research());
    let _ = writeln!(
        out,
        "**On the device:** {} (model-core without its feature `research-tiers`: the firmware \
         builds these inverses only). **Research only:** {}, built for the host tools, the \
         reports and this benchmark (`research-tiers`); the device refuses them (`SetModelTier` \
         answers NotSupported) and use-case selection never offers them. The device keeps the \
         Pareto front of cost against error of the shipped build (the black line), with \
         `linear` as the cheapest; measured here, the front is {}.",
        tier_names(Tier::ON_DEVICE),
        tier_names(research),
        tier_names(front.iter().map(|(tier, _, _)| *tier)),
    );
    let off_device: Vec<Tier> = front
        .iter()
        .map(|(tier, _, _)| *tier)
        .filter(|tier| !Tier::ON_DEVICE.contains(tier))
        .collect();
    if !off_device.is_empty() {
        let _ = writeln!(
            out,
            "\n**The measured front includes research tiers** ({}): the device's choice of tiers \
             (`Tier::ON_DEVICE`) should be reconsidered.",
            tier_names(off_device)
        );
    }
    let _ = writeln!(out);
}

/// The speed-vs-error picture.
pub fn plot(data: &ReportData) -> Plot {
    let mut points = Vec::new();
    let mut links = Vec::new();
    for figure in figures(data) {
        let research = figure.tier.is_research();
        let colour = if research {
            RESEARCH_COLOUR
        } else {
            taxel_plot_style::tier_colour(figure.tier)
        };
        let label = if research {
            format!("{} (research)", figure.tier.name())
        } else {
            figure.tier.name().to_string()
        };
        let Some(y) = figure.max_from_default_kpa else {
            continue;
        };
        let corrected = Measure::CorrectedInversion.count(&data.shipped, figure.tier);
        let full = Measure::FullStep.count(&data.shipped, figure.tier);
        if let Some(x) = corrected {
            points.push(Point {
                label: Some(label.clone()),
                x,
                y,
                filled: true,
                colour,
            });
        }
        if let Some(x) = full {
            points.push(Point {
                label: corrected.is_none().then_some(label),
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
            "Black line: the Pareto front of the filled points. Grey, \"(research)\": research tiers, not on the device".to_string(),
            "(built only with model-core's feature research-tiers, for host tools and this benchmark).".to_string(),
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
        front: pareto_front(data)
            .into_iter()
            .map(|(_, count, distance)| (count, distance))
            .collect(),
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
    let model_core = match &data.firmware {
        Ok(footprint) if footprint.model_core_opt_level != footprint.opt_level => format!(
            " with model-core itself at opt-level {} (`[profile.firmware.package.model-core]`: \
             the hot path built for speed, the rest of the firmware for size; `PadModel::process` \
             is never inlined into its size-optimised callers)",
            footprint.model_core_opt_level
        ),
        _ => String::new(),
    };
    let _ = writeln!(
        out,
        "M4 figures are from the build the firmware ships: opt-level \"{}\"{model_core}, fat LTO, \
         one codegen unit (m4-bench's `release` profile, which `cargo xtask m4-test` checks \
         against the root `[profile.firmware]`). The benchmark's own loops are built like the \
         firmware's callers of model-core, so parts counted alone (an inverse, \
         `TaxelModel::convert`) are inlined into size-optimised code; inside \
         `PadModel::process` they run as model-core is built. Everything at opt-level {} is the \
         second column wherever it is shown.\n",
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
    device_tiers(out, data);

    hard_cases(out, &data.shipped);
    use_cases(out, data);
    drift(out, data);
    firmware(out, data);
    several_pads(out, data);
    simulator(out, data);
    measured_elsewhere(out);
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_front_of_the_shipped_figures_is_the_device_tiers() {
        // The shipped build's figures the device's choice was made on (docs/PERFORMANCE.md):
        // instructions per temperature-corrected inversion, largest distance from the default.
        let measured = [
            (Tier::Linear, 34.0, 9.09),
            (Tier::PiecewiseLinear, 98.7, 0.494),
            (Tier::MonotoneCubic, 142.3, 3e-5),
            (Tier::Saturating, 107.8, 0.644),
            (Tier::SaturatingMicromath, 98.8, 0.646),
            (Tier::Table, 88.6, 0.015),
            (Tier::Polynomial, 107.0, 0.050),
        ];
        let front: Vec<Tier> = front_of(&measured)
            .into_iter()
            .map(|(tier, _, _)| tier)
            .collect();
        assert_eq!(front, [Tier::Linear, Tier::Table, Tier::MonotoneCubic]);
        let mut on_device = Tier::ON_DEVICE.to_vec();
        on_device.sort_by_key(|tier| front.iter().position(|front_tier| front_tier == tier));
        assert_eq!(front, on_device);
        // A tie on one axis is not a win; equal points both stay.
        let tied = [(Tier::Linear, 10.0, 1.0), (Tier::Table, 10.0, 1.0)];
        assert_eq!(front_of(&tied).len(), 2);
    }

    #[test]
    fn tier_names_read_as_prose() {
        assert_eq!(tier_names([]), "none");
        assert_eq!(tier_names([Tier::Table]), "`table`");
        assert_eq!(
            tier_names(Tier::ON_DEVICE),
            "`linear`, `monotone-cubic` and `table`"
        );
    }
}
