//! Parsing of m4-bench's semihosting output: one `kind key=value ...` line per result (a
//! `description=` field takes the rest of its line).

use std::collections::BTreeMap;

use anyhow::{anyhow, bail, Context, Result};
use model_core::Tier;

/// One output line: its first word and its fields.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// First word (`grid`, `hard`, `case`, `count`, `summary`, ...).
    pub kind: String,
    /// `key=value` fields.
    pub fields: BTreeMap<String, String>,
}

impl Line {
    /// Splits a line into its kind and fields.
    pub fn parse(text: &str) -> Option<Self> {
        let text = text.trim_end();
        let (kind, mut rest) = match text.split_once(' ') {
            Some((kind, rest)) => (kind, rest),
            None => (text, ""),
        };
        if kind.is_empty() || kind.contains('=') {
            return None;
        }
        let mut fields = BTreeMap::new();
        while !rest.is_empty() {
            rest = rest.trim_start();
            if let Some(description) = rest.strip_prefix("description=") {
                fields.insert("description".to_string(), description.to_string());
                break;
            }
            let (token, remainder) = rest.split_once(' ').unwrap_or((rest, ""));
            if let Some((key, value)) = token.split_once('=') {
                fields.insert(key.to_string(), value.to_string());
            }
            rest = remainder;
        }
        Some(Self {
            kind: kind.to_string(),
            fields,
        })
    }

    /// A field's text.
    pub fn text(&self, key: &str) -> Result<&str> {
        self.fields
            .get(key)
            .map(String::as_str)
            .ok_or_else(|| anyhow!("`{}` line without `{key}`", self.kind))
    }

    /// A numeric field.
    pub fn number(&self, key: &str) -> Result<f64> {
        let text = self.text(key)?;
        text.parse()
            .with_context(|| format!("`{}` line: `{key}={text}` is not a number", self.kind))
    }

    /// A field that is a number or `none`.
    pub fn optional_number(&self, key: &str) -> Result<Option<f64>> {
        match self.text(key)? {
            "none" => Ok(None),
            _ => self.number(key).map(Some),
        }
    }

    /// A hexadecimal `0x....` field.
    pub fn hex(&self, key: &str) -> Result<u16> {
        let text = self.text(key)?;
        u16::from_str_radix(text.trim_start_matches("0x"), 16)
            .with_context(|| format!("`{}` line: `{key}={text}` is not hexadecimal", self.kind))
    }

    /// A tier-name field.
    pub fn tier(&self, key: &str) -> Result<Tier> {
        let name = self.text(key)?;
        Tier::from_name(name).ok_or_else(|| anyhow!("unknown tier `{name}`"))
    }

    /// `result=pass`.
    pub fn passed(&self) -> bool {
        self.fields.get("result").map(String::as_str) == Some("pass")
    }
}

/// A tier's result on the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct GridResult {
    /// The tier.
    pub tier: Tier,
    /// Grid points.
    pub points: u32,
    /// Points that came out as faults (should be none).
    pub faults: u32,
    /// Largest |M4 - f64 reference of the tier|, kPa.
    pub max_error_kpa: f64,
    /// rms of the same, kPa.
    pub rms_error_kpa: f64,
    /// Where the largest error occurred: pressure, kPa.
    pub worst_at_kpa: f64,
    /// Where the largest error occurred: temperature, °C.
    pub worst_at_c: f64,
    /// The accepted maximum, kPa.
    pub tolerance_kpa: f64,
    /// Largest |M4 - f64 reference curve (monotone cubic)|, kPa.
    pub max_from_reference_curve_kpa: f64,
    /// rms of the same, kPa.
    pub rms_from_reference_curve_kpa: f64,
    /// Within tolerance and no faults.
    pub pass: bool,
}

/// What a hard case feeds the model.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseInfo {
    /// Identifier.
    pub name: String,
    /// The reading (`raw:code@capdac`, `pf:value`, `unavailable`).
    pub reading: String,
    /// The temperature as printed (`Some(25.0)`, `None`, `Some(NaN)`...).
    pub temperature: String,
    /// The temperature the pad was brought to before the reading, as printed (`None`: none).
    pub warm_up: String,
    /// Expected flags.
    pub expected_flags: u16,
    /// What the case exercises.
    pub description: String,
}

/// One hard case through one tier.
#[derive(Debug, Clone, PartialEq)]
pub struct HardResult {
    /// Case identifier.
    pub case: String,
    /// The tier.
    pub tier: Tier,
    /// Flags the M4 produced.
    pub flags: u16,
    /// Flags expected.
    pub expected_flags: u16,
    /// Pressure the M4 produced (None for a fault).
    pub pressure_kpa: Option<f64>,
    /// f64 reference (None when a fault is expected).
    pub reference_kpa: Option<f64>,
    /// Accepted |difference|, kPa.
    pub tolerance_kpa: f64,
    /// Flags equal and pressure within tolerance.
    pub pass: bool,
}

/// Instructions per `TaxelModel::convert` call for a tier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConvertCount {
    /// The tier.
    pub tier: Tier,
    /// Mean over the whole grid.
    pub mean: f64,
    /// Fewest, over single inputs (whole kPa at 25 °C).
    pub min: f64,
    /// Most, over the same single inputs.
    pub max: f64,
    /// Mean over the same single inputs.
    pub single_mean: f64,
}

/// Instructions per `PadModel::process` for a tier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadCount {
    /// The tier.
    pub tier: Tier,
    /// Per sample set (four taxels, one temperature resolution).
    pub per_set: f64,
    /// Per taxel: a quarter of the set's.
    pub per_taxel: f64,
}

/// Instructions per tier's inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseCount {
    /// The tier.
    pub tier: Tier,
    /// Through `TaxelInverses::pressure_kpa` (tier chosen at run time).
    pub dispatched: f64,
    /// The inverse alone, called directly.
    pub direct: f64,
}

/// One hard calibration's result on the target.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationResult {
    /// Generator seed.
    pub seed: u64,
    /// The generator's shape name.
    pub shape: String,
    /// Calibration points.
    pub points: u32,
    /// Probes checked.
    pub probes: u32,
    /// Smallest distance of an answer inside its accepted interval, kPa (negative: outside).
    pub min_margin_kpa: f64,
    /// Largest |answer - f64 reference pressure|, kPa.
    pub max_from_reference_kpa: f64,
    /// Every probe within its interval and the curve accepted.
    pub pass: bool,
}

/// The hard calibrations' summary line.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CalibrationSummary {
    /// Curves in the golden file.
    pub curves: u32,
    /// Probes checked in all.
    pub probes: u32,
    /// Curves with at least one miss.
    pub failed_curves: u32,
    /// Probes outside their interval (and curves refused).
    pub misses: u32,
}

/// Instructions per temperature-corrected inversion (`Baseline::relative_change`, then the tier's
/// inverse) for a tier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectedCount {
    /// The tier.
    pub tier: Tier,
    /// With the inverse called directly (a build fixed to one tier).
    pub direct: f64,
    /// Through `TaxelInverses::pressure_kpa` (tier chosen at run time).
    pub dispatched: f64,
}

/// Everything one m4-bench run printed.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BenchRun {
    /// `z`, `3`, ...
    pub opt_level: String,
    /// Readings in the grid.
    pub grid_points: u32,
    /// Passes over the grid behind each grid mean.
    pub grid_repetitions: u32,
    /// Repetitions of each single input behind its own count.
    pub single_repetitions: u32,
    /// Per tier, on the grid.
    pub grid: Vec<GridResult>,
    /// The hard cases' inputs.
    pub cases: Vec<CaseInfo>,
    /// Hard case x tier results.
    pub hard: Vec<HardResult>,
    /// Hard calibrations (default tier's inverse against the f64 reference).
    pub calibrations: Vec<CalibrationResult>,
    /// Their summary line (None: missing, which fails the run).
    pub calibration_summary: Option<CalibrationSummary>,
    /// `TaxelModel::convert` counts per tier.
    pub convert: Vec<ConvertCount>,
    /// Inverse counts per tier.
    pub inverse: Vec<InverseCount>,
    /// Temperature-corrected inversion counts per tier.
    pub corrected: Vec<CorrectedCount>,
    /// `PadModel::process` per set and per taxel, per tier.
    pub pad: Vec<PadCount>,
    /// Other subjects (`relative-change`, `reading-value`, `temperature-resolve`,
    /// `table-direct`, `libm-logf`, `libm-expf`, `micromath-ln`, `f32-min`); one with a tier is
    /// filed as `subject/tier`.
    pub functions: BTreeMap<String, f64>,
    /// Lines starting `error:` and lines that are not `key=value` results (panics).
    pub problems: Vec<String>,
    /// The summary line was present and said pass.
    pub passed: bool,
    /// Misses the summary line counted.
    pub misses: u32,
}

impl BenchRun {
    /// Parses a whole run's output.
    pub fn parse(output: &str) -> Result<Self> {
        let mut run = BenchRun::default();
        let mut summary_seen = false;
        for text in output.lines().filter(|line| !line.trim().is_empty()) {
            if text.starts_with("error:") {
                run.problems.push(text.to_string());
                continue;
            }
            let Some(line) = Line::parse(text) else {
                run.problems.push(text.to_string());
                continue;
            };
            match line.kind.as_str() {
                "m4-bench" => {
                    run.opt_level = line.text("opt-level")?.to_string();
                    run.grid_points = line.number("grid_points")? as u32;
                    run.grid_repetitions = line.number("grid_repetitions")? as u32;
                    run.single_repetitions = line.number("single_repetitions")? as u32;
                }
                "grid" => run.grid.push(GridResult {
                    tier: line.tier("tier")?,
                    points: line.number("points")? as u32,
                    faults: line.number("faults")? as u32,
                    max_error_kpa: line.number("max_error_kpa")?,
                    rms_error_kpa: line.number("rms_error_kpa")?,
                    worst_at_kpa: line.number("worst_at_kpa")?,
                    worst_at_c: line.number("worst_at_c")?,
                    tolerance_kpa: line.number("tolerance_kpa")?,
                    max_from_reference_curve_kpa: line.number("max_from_reference_curve_kpa")?,
                    rms_from_reference_curve_kpa: line.number("rms_from_reference_curve_kpa")?,
                    pass: line.passed(),
                }),
                "case" => run.cases.push(CaseInfo {
                    name: line.text("name")?.to_string(),
                    reading: line.text("reading")?.to_string(),
                    temperature: line.text("temperature")?.to_string(),
                    warm_up: line
                        .fields
                        .get("warm_up")
                        .cloned()
                        .unwrap_or_else(|| "None".to_string()),
                    expected_flags: line.hex("expected_flags")?,
                    description: line.text("description")?.to_string(),
                }),
                "hard" if line.fields.contains_key("reason") => {
                    run.problems.push(text.to_string());
                }
                "hard" => run.hard.push(HardResult {
                    case: line.text("case")?.to_string(),
                    tier: line.tier("tier")?,
                    flags: line.hex("flags")?,
                    expected_flags: line.hex("expected_flags")?,
                    pressure_kpa: line.optional_number("pressure_kpa")?,
                    reference_kpa: line.optional_number("reference_kpa")?,
                    tolerance_kpa: line.number("tolerance_kpa")?,
                    pass: line.passed(),
                }),
                "calibration" => run.calibrations.push(CalibrationResult {
                    seed: line.number("seed")? as u64,
                    shape: line.text("shape")?.to_string(),
                    points: line.number("points")? as u32,
                    probes: line.number("probes")? as u32,
                    min_margin_kpa: line.number("min_margin_kpa").unwrap_or(f64::NEG_INFINITY),
                    max_from_reference_kpa: line
                        .number("max_from_reference_kpa")
                        .unwrap_or(f64::INFINITY),
                    pass: line.passed(),
                }),
                "calibrations" => {
                    run.calibration_summary = Some(CalibrationSummary {
                        curves: line.number("curves")? as u32,
                        probes: line.number("probes")? as u32,
                        failed_curves: line.number("failed_curves")? as u32,
                        misses: line.number("misses")? as u32,
                    });
                }
                "count" => match line.text("subject")? {
                    "convert" => run.convert.push(ConvertCount {
                        tier: line.tier("tier")?,
                        mean: line.number("mean")?,
                        min: line.number("min")?,
                        max: line.number("max")?,
                        single_mean: line.number("single_mean")?,
                    }),
                    "inverse" => run.inverse.push(InverseCount {
                        tier: line.tier("tier")?,
                        dispatched: line.number("mean")?,
                        direct: line.number("direct")?,
                    }),
                    "corrected-inversion" => run.corrected.push(CorrectedCount {
                        tier: line.tier("tier")?,
                        direct: line.number("mean")?,
                        dispatched: line.number("dispatched")?,
                    }),
                    "pad-process" => run.pad.push(PadCount {
                        tier: line.tier("tier")?,
                        per_set: line.number("per_set")?,
                        per_taxel: line.number("mean")?,
                    }),
                    subject => {
                        let key = match line.fields.get("tier") {
                            Some(tier) => format!("{subject}/{tier}"),
                            None => subject.to_string(),
                        };
                        run.functions.insert(key, line.number("mean")?);
                    }
                },
                "summary" => {
                    summary_seen = true;
                    run.misses = line.number("misses")? as u32;
                    run.passed = line.passed();
                }
                _ => run.problems.push(text.to_string()),
            }
        }
        if !summary_seen {
            run.passed = false;
            run.problems
                .push("no summary line: the run stopped early (panic or timeout)".to_string());
        }
        Ok(run)
    }

    /// The convert count of a tier.
    pub fn convert_count(&self, tier: Tier) -> Result<ConvertCount> {
        self.convert
            .iter()
            .find(|count| count.tier == tier)
            .copied()
            .ok_or_else(|| anyhow!("no instruction count for tier {}", tier.name()))
    }

    /// The corrected-inversion count of a tier.
    pub fn corrected_count(&self, tier: Tier) -> Result<CorrectedCount> {
        self.corrected
            .iter()
            .find(|count| count.tier == tier)
            .copied()
            .ok_or_else(|| anyhow!("no corrected-inversion count for tier {}", tier.name()))
    }

    /// The inverse counts of a tier.
    pub fn inverse_count(&self, tier: Tier) -> Result<InverseCount> {
        self.inverse
            .iter()
            .find(|count| count.tier == tier)
            .copied()
            .ok_or_else(|| anyhow!("no inverse count for tier {}", tier.name()))
    }

    /// The `PadModel::process` counts of a tier.
    pub fn pad_count(&self, tier: Tier) -> Result<PadCount> {
        self.pad
            .iter()
            .find(|count| count.tier == tier)
            .copied()
            .ok_or_else(|| anyhow!("no PadModel::process count for tier {}", tier.name()))
    }

    /// The grid result of a tier.
    pub fn grid_result(&self, tier: Tier) -> Result<&GridResult> {
        self.grid
            .iter()
            .find(|result| result.tier == tier)
            .ok_or_else(|| anyhow!("no grid result for tier {}", tier.name()))
    }

    /// Fails with every miss listed unless the run passed completely.
    pub fn require_pass(&self) -> Result<()> {
        let mut misses: Vec<String> = self.problems.clone();
        misses.extend(
            self.grid
                .iter()
                .filter(|result| !result.pass)
                .map(|result| {
                    format!(
                        "grid, {}: max error {:.3e} kPa > {:.1e} kPa or {} faults",
                        result.tier.name(),
                        result.max_error_kpa,
                        result.tolerance_kpa,
                        result.faults
                    )
                }),
        );
        misses.extend(self.hard.iter().filter(|result| !result.pass).map(|result| {
            format!(
                "hard case {}, {}: flags {:#06x} (expected {:#06x}), pressure {:?} (reference {:?} +- {:.1e})",
                result.case,
                result.tier.name(),
                result.flags,
                result.expected_flags,
                result.pressure_kpa,
                result.reference_kpa,
                result.tolerance_kpa
            )
        }));
        misses.extend(
            self.calibrations
                .iter()
                .filter(|result| !result.pass)
                .map(|result| {
                    format!(
                        "hard calibration seed {} ({}, {} points): an answer {:.3e} kPa outside the accepted interval",
                        result.seed, result.shape, result.points, -result.min_margin_kpa
                    )
                }),
        );
        match self.calibration_summary {
            None => misses.push("no hard-calibration summary line".to_string()),
            Some(summary) if summary.misses > 0 => misses.push(format!(
                "hard calibrations: {} misses on {} of {} curves",
                summary.misses, summary.failed_curves, summary.curves
            )),
            Some(_) => {}
        }
        if self.passed && misses.is_empty() {
            return Ok(());
        }
        bail!(
            "the on-target test failed ({} misses counted on the target):\n  {}",
            self.misses,
            misses.join("\n  ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "m4-bench opt-level=z grid_points=1111 hard_cases=2 hard_calibrations=2 grid_repetitions=4 single_repetitions=64
grid tier=table points=1111 faults=0 max_error_kpa=3.870e-5 rms_error_kpa=8.350e-6 worst_at_kpa=48 worst_at_c=50 tolerance_kpa=5.0e-3 max_from_reference_curve_kpa=1.4604e-2 rms_from_reference_curve_kpa=4.0140e-3 result=pass
case name=temperature-nan reading=raw:1234@3 temperature=Some(NaN) warm_up=None expected_flags=0x0020 description=20 kPa at 25 C, temperature NaN: the tare's is used
hard case=temperature-nan tier=table flags=0x0020 expected_flags=0x0020 pressure_kpa=2.000000e1 reference_kpa=2.000001e1 tolerance_kpa=5.0e-3 result=pass
hard case=open-lead tier=table flags=0x0008 expected_flags=0x0008 pressure_kpa=none reference_kpa=none tolerance_kpa=5.0e-3 result=pass
count subject=convert tier=table mean=119.26 min=70.00 max=124.38 single_mean=120.00 calls=4444 single_inputs=51
calibration seed=0 shape=Saturating points=2 probes=7 min_margin_kpa=1.000e-2 max_from_reference_kpa=1.257e-7 misses=0 result=pass
calibration seed=1 shape=FlatTop points=6 probes=43 min_margin_kpa=9.926e-3 max_from_reference_kpa=7.563e-5 misses=0 result=pass
calibrations curves=2 probes=50 failed_curves=0 misses=0 result=pass
count subject=inverse tier=table mean=56.42 direct=49.00 calls=4444
count subject=corrected-inversion tier=table mean=45.92 dispatched=58.93 calls=4444
count subject=corrected-inversion tier=linear mean=28.00 dispatched=37.95 calls=4444
count subject=relative-change mean=14.00 calls=4444
count subject=future-subject tier=table mean=1.5 calls=4444
count subject=future-subject tier=linear mean=2.5 calls=4444
count subject=libm-logf mean=37.66 calls=256
count subject=pad-process tier=table per_set=1078.90 mean=269.73 calls=4444
summary misses=0 result=pass
";

    #[test]
    fn a_complete_run_parses_and_passes() {
        let run = BenchRun::parse(SAMPLE).unwrap();
        assert_eq!(run.opt_level, "z");
        assert!(run.problems.is_empty(), "{:?}", run.problems);
        assert!(run.require_pass().is_ok());
        let grid = run.grid_result(Tier::Table).unwrap();
        assert_eq!(grid.points, 1111);
        assert!((grid.max_from_reference_curve_kpa - 1.4604e-2).abs() < 1e-12);
        assert_eq!(
            run.cases[0].description,
            "20 kPa at 25 C, temperature NaN: the tare's is used"
        );
        assert_eq!(run.cases[0].expected_flags, 0x20);
        assert_eq!(run.hard[1].pressure_kpa, None);
        assert_eq!(run.hard[0].pressure_kpa, Some(20.0));
        let count = run.convert_count(Tier::Table).unwrap();
        assert_eq!((count.min, count.max), (70.0, 124.38));
        assert_eq!(run.functions.get("libm-logf"), Some(&37.66));
        assert_eq!(
            (
                run.grid_points,
                run.grid_repetitions,
                run.single_repetitions
            ),
            (1111, 4, 64)
        );
        let corrected = run.corrected_count(Tier::Table).unwrap();
        assert_eq!((corrected.direct, corrected.dispatched), (45.92, 58.93));
        assert_eq!(run.corrected_count(Tier::Linear).unwrap().direct, 28.0);
        assert!(run.corrected_count(Tier::Polynomial).is_err());
        assert_eq!(run.functions.get("relative-change"), Some(&14.0));
        assert_eq!(run.inverse_count(Tier::Table).unwrap().direct, 49.0);
        let pad = run.pad_count(Tier::Table).unwrap();
        assert_eq!((pad.per_set, pad.per_taxel), (1078.9, 269.73));
        assert_eq!(run.calibrations.len(), 2);
        assert_eq!(run.calibrations[1].shape, "FlatTop");
        assert_eq!(run.calibration_summary.unwrap().probes, 50);
        assert_eq!(run.cases[0].warm_up, "None");
        // An unknown subject per tier keeps one value per tier instead of overwriting.
        assert_eq!(run.functions.get("future-subject/table"), Some(&1.5));
        assert_eq!(run.functions.get("future-subject/linear"), Some(&2.5));
    }

    #[test]
    fn a_failed_check_or_a_missing_summary_fails_with_the_reason() {
        let failed = SAMPLE.replace(
            "pressure_kpa=2.000000e1 reference_kpa=2.000001e1 tolerance_kpa=5.0e-3 result=pass",
            "pressure_kpa=2.100000e1 reference_kpa=2.000001e1 tolerance_kpa=5.0e-3 result=fail",
        );
        let message = BenchRun::parse(&failed)
            .unwrap()
            .require_pass()
            .unwrap_err()
            .to_string();
        assert!(message.contains("temperature-nan"), "{message}");
        let truncated = SAMPLE.replace(
            "summary misses=0 result=pass\n",
            "panicked at src/main.rs\n",
        );
        let run = BenchRun::parse(&truncated).unwrap();
        assert!(!run.passed);
        let message = run.require_pass().unwrap_err().to_string();
        assert!(message.contains("panicked"), "{message}");
    }

    #[test]
    fn a_hard_calibration_miss_fails_the_run() {
        let missed = SAMPLE
            .replace(
                "calibrations curves=2 probes=50 failed_curves=0 misses=0 result=pass",
                "calibration-miss seed=1 relative_change=1e-1 pressure_kpa=3e0 reference_kpa=2e0 lower_kpa=1.9e0 upper_kpa=2.1e0\ncalibrations curves=2 probes=50 failed_curves=1 misses=1 result=fail",
            )
            .replace("summary misses=0 result=pass", "summary misses=1 result=fail");
        let message = BenchRun::parse(&missed)
            .unwrap()
            .require_pass()
            .unwrap_err()
            .to_string();
        assert!(message.contains("calibration-miss seed=1"), "{message}");
        let without_summary = SAMPLE.replace(
            "calibrations curves=2 probes=50 failed_curves=0 misses=0 result=pass\n",
            "",
        );
        assert!(BenchRun::parse(&without_summary)
            .unwrap()
            .require_pass()
            .is_err());
    }

    #[test]
    fn malformed_numbers_are_errors_not_zeros() {
        let broken = SAMPLE.replace("mean=119.26", "mean=lots");
        assert!(BenchRun::parse(&broken).is_err());
    }
}
