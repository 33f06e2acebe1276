//! `model_core::use_case::MEASURED_INSTRUCTIONS`: the per-tier cost `select_tier` ranks tiers by.
//!
//! - [`check_ranking`]: the order of the tiers by the measured count must be the order of the
//!   constants (counts within [`TIE_INSTRUCTIONS`] of each other are tied and may come in either
//!   order; tied constants need tied counts).
//! - [`check_drift`]: each count within [`drift_tolerance`] of its constant: half the smallest
//!   gap between neighbouring (untied) constants, so that no two tiers can trade places within
//!   it, and never below the tie width.
//! - [`rewrite`]: writes the constant block in model-core/src/use_case.rs from a run, so that the
//!   figures come from a command (`cargo xtask report`, `cargo xtask m4-test --write`).

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use model_core::Tier;

use crate::bench_output::BenchRun;

/// Counts closer than this are tied (instructions).
pub const TIE_INSTRUCTIONS: f64 = 2.0;

/// How far the difference of two constants can be from the difference of the counts they were
/// rounded from (half an instruction each).
const ROUNDING_INSTRUCTIONS: f64 = 1.0;

/// The file that holds the constant, relative to the workspace root.
pub const USE_CASE_FILE: &str = "model-core/src/use_case.rs";

const DECLARATION: &str = "pub const MEASURED_INSTRUCTIONS";

/// The count the constant holds for a tier: `TaxelModel::convert`, mean over the grid.
pub fn measured(run: &BenchRun, tier: Tier) -> Result<f64> {
    Ok(run.convert_count(tier)?.mean)
}

/// The constants a run gives: each tier's count rounded to a whole instruction.
pub fn from_run(run: &BenchRun) -> Result<Vec<(Tier, u32)>> {
    Tier::ALL
        .into_iter()
        .map(|tier| Ok((tier, measured(run, tier)?.round() as u32)))
        .collect()
}

fn constant_of(constants: &[(Tier, u32)], tier: Tier) -> Result<u32> {
    constants
        .iter()
        .find(|(candidate, _)| *candidate == tier)
        .map(|(_, value)| *value)
        .filter(|value| *value > 0)
        .ok_or_else(|| anyhow!("MEASURED_INSTRUCTIONS has no count for {}", tier.name()))
}

/// Tier names from cheapest to dearest by `value`, ties (within [`TIE_INSTRUCTIONS`] of the
/// previous) joined with `=`.
pub fn order_text(values: &[(Tier, f64)]) -> String {
    let mut sorted = values.to_vec();
    sorted.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut text = String::new();
    for (index, (tier, value)) in sorted.iter().enumerate() {
        if index > 0 {
            let tied = (value - sorted[index - 1].1).abs() <= TIE_INSTRUCTIONS;
            text.push_str(if tied { " = " } else { " < " });
        }
        text.push_str(tier.name());
    }
    text
}

/// Fails when the measured order of the tiers differs from the constants' order.
pub fn check_ranking(run: &BenchRun, constants: &[(Tier, u32)]) -> Result<()> {
    let mut pairs = Vec::new();
    let mut measured_values = Vec::new();
    let mut constant_values = Vec::new();
    for tier in Tier::ALL {
        measured_values.push((tier, measured(run, tier)?));
        constant_values.push((tier, f64::from(constant_of(constants, tier)?)));
    }
    for (index, (a, measured_a)) in measured_values.iter().enumerate() {
        for (b, measured_b) in &measured_values[index + 1..] {
            let constant_a = f64::from(constant_of(constants, *a)?);
            let constant_b = f64::from(constant_of(constants, *b)?);
            let measured_difference = measured_a - measured_b;
            if measured_difference.abs() <= TIE_INSTRUCTIONS {
                continue;
            }
            let constant_difference = constant_a - constant_b;
            // Constants are counts rounded to whole instructions, so tied constants may come
            // from counts up to one instruction further apart than the tie width.
            let mismatch = if constant_difference.abs() <= TIE_INSTRUCTIONS {
                measured_difference.abs() > TIE_INSTRUCTIONS + ROUNDING_INSTRUCTIONS
            } else {
                constant_difference.signum() != measured_difference.signum()
            };
            if mismatch {
                pairs.push(format!(
                    "{} {measured_a:.1} vs {} {measured_b:.1} measured, constants {constant_a} vs {constant_b}",
                    a.name(),
                    b.name()
                ));
            }
        }
    }
    if pairs.is_empty() {
        return Ok(());
    }
    bail!(
        "the measured order of the tiers differs from model_core::use_case::MEASURED_INSTRUCTIONS \
         (ties within {TIE_INSTRUCTIONS} instructions):\n  measured:  {}\n  constants: {}\n  {}\n\
         Regenerate the constant with `cargo xtask m4-test --write` (or `cargo xtask report`).",
        order_text(&measured_values),
        order_text(&constant_values),
        pairs.join("\n  ")
    )
}

/// Half the smallest gap between neighbouring constants that are not tied, at least
/// [`TIE_INSTRUCTIONS`]: a drift within it cannot swap two tiers.
pub fn drift_tolerance(constants: &[(Tier, u32)]) -> f64 {
    let mut values: Vec<f64> = constants
        .iter()
        .map(|(_, value)| f64::from(*value))
        .collect();
    values.sort_by(f64::total_cmp);
    let smallest_gap = values
        .windows(2)
        .map(|pair| pair[1] - pair[0])
        .filter(|gap| *gap > TIE_INSTRUCTIONS)
        .fold(f64::INFINITY, f64::min);
    if smallest_gap.is_finite() {
        (smallest_gap / 2.0).max(TIE_INSTRUCTIONS)
    } else {
        TIE_INSTRUCTIONS
    }
}

/// Fails when a tier's count is further than [`drift_tolerance`] from its constant.
pub fn check_drift(run: &BenchRun, constants: &[(Tier, u32)]) -> Result<()> {
    let tolerance = drift_tolerance(constants);
    let mut drifted = Vec::new();
    for tier in Tier::ALL {
        let value = measured(run, tier)?;
        let constant = f64::from(constant_of(constants, tier)?);
        if (value - constant).abs() > tolerance {
            drifted.push(format!(
                "{}: measured {value:.1}, constant {constant} ({:+.1})",
                tier.name(),
                value - constant
            ));
        }
    }
    if drifted.is_empty() {
        return Ok(());
    }
    bail!(
        "instruction counts drifted more than {tolerance:.1} instructions (half the smallest gap \
         between neighbouring tiers) from model_core::use_case::MEASURED_INSTRUCTIONS:\n  {}\n\
         Regenerate the constant with `cargo xtask m4-test --write` (or `cargo xtask report`).",
        drifted.join("\n  ")
    )
}

/// The constant block (doc comment and declaration) for `constants` measured at `opt_level`.
pub fn block(constants: &[(Tier, u32)], opt_level: &str) -> String {
    let doc = [
        "Instructions per taxel conversion (temperature correction included) on the Cortex-M4F:"
            .to_string(),
        "`TaxelModel::convert`, mean over a 0–50 kPa x 5–55 °C grid, measured under QEMU in the"
            .to_string(),
        format!(
            "build the firmware ships (opt-level \"{opt_level}\", fat LTO, one codegen unit; see"
        ),
        "docs/PERFORMANCE.md). Written by `cargo xtask report` or `cargo xtask m4-test --write`,"
            .to_string(),
        "never by hand. `cargo xtask m4-test` fails when the measured order of the tiers differs"
            .to_string(),
        format!(
            "from this one (counts within {TIE_INSTRUCTIONS:.0} instructions are tied), or when a \
             count drifts"
        ),
        "further than half the smallest gap between neighbouring tiers.".to_string(),
    ];
    let mut text = String::new();
    for line in doc {
        text.push_str("/// ");
        text.push_str(&line);
        text.push('\n');
    }
    text.push_str(&format!(
        "{DECLARATION}: [(Tier, u32); {}] = [\n",
        constants.len()
    ));
    for (tier, value) in constants {
        text.push_str(&format!("    (Tier::{tier:?}, {value}),\n"));
    }
    text.push_str("];\n");
    text
}

/// `source` with its constant block (the `///` lines right above the declaration, the
/// declaration, down to the line `];`) replaced by `block`.
pub fn replace_block(source: &str, block: &str) -> Result<String> {
    let lines: Vec<&str> = source.lines().collect();
    let declaration = lines
        .iter()
        .position(|line| line.starts_with(DECLARATION))
        .ok_or_else(|| anyhow!("no `{DECLARATION}` line"))?;
    let mut first = declaration;
    while first > 0 && lines[first - 1].trim_start().starts_with("///") {
        first -= 1;
    }
    let last = lines[declaration..]
        .iter()
        .position(|line| line.trim_end() == "];")
        .map(|offset| declaration + offset)
        .ok_or_else(|| anyhow!("`{DECLARATION}` has no closing `];` line"))?;
    let mut text = String::new();
    for line in &lines[..first] {
        text.push_str(line);
        text.push('\n');
    }
    text.push_str(block);
    for line in &lines[last + 1..] {
        text.push_str(line);
        text.push('\n');
    }
    if !source.ends_with('\n') {
        text.pop();
    }
    Ok(text)
}

/// Writes the constants from `run` into model-core/src/use_case.rs; returns whether the file
/// changed.
pub fn rewrite(root: &Path, run: &BenchRun) -> Result<bool> {
    let path = root.join(USE_CASE_FILE);
    let source =
        std::fs::read_to_string(&path).with_context(|| format!("reading {USE_CASE_FILE}"))?;
    let updated = replace_block(&source, &block(&from_run(run)?, &run.opt_level))
        .with_context(|| format!("finding MEASURED_INSTRUCTIONS in {USE_CASE_FILE}"))?;
    if updated == source {
        return Ok(false);
    }
    crate::write_whole_file(&path, &updated)?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_with_counts(counts: &[(Tier, f64)]) -> BenchRun {
        let mut text = String::from("m4-bench opt-level=z grid_points=1 hard_cases=0 hard_calibrations=0 grid_repetitions=1 single_repetitions=1\n");
        for (tier, mean) in counts {
            text.push_str(&format!(
                "count subject=convert tier={} mean={mean} min={mean} max={mean} single_mean={mean}\n",
                tier.name()
            ));
        }
        text.push_str("summary misses=0 result=pass\n");
        BenchRun::parse(&text).unwrap()
    }

    fn constants(values: [u32; 7]) -> Vec<(Tier, u32)> {
        Tier::ALL.into_iter().zip(values).collect()
    }

    fn counts(values: [f64; 7]) -> Vec<(Tier, f64)> {
        Tier::ALL.into_iter().zip(values).collect()
    }

    #[test]
    fn the_same_order_passes_and_a_swap_fails() {
        let constants = constants([100, 120, 180, 150, 140, 110, 105]);
        let same = run_with_counts(&counts([101.0, 119.0, 181.0, 151.0, 139.0, 110.4, 104.6]));
        assert!(check_ranking(&same, &constants).is_ok());
        // Table (110) and polynomial (105) trade places by more than the tie width.
        let swapped = run_with_counts(&counts([101.0, 119.0, 181.0, 151.0, 139.0, 104.0, 109.0]));
        let message = check_ranking(&swapped, &constants).unwrap_err().to_string();
        assert!(message.contains("table"), "{message}");
        assert!(message.contains("polynomial"), "{message}");
    }

    #[test]
    fn counts_within_two_instructions_are_tied() {
        let constants = constants([100, 120, 180, 150, 140, 110, 105]);
        // Table and polynomial now 1.5 apart in the other order: tied, accepted.
        let tied = run_with_counts(&counts([100.0, 120.0, 180.0, 150.0, 140.0, 107.0, 108.5]));
        assert!(check_ranking(&tied, &constants).is_ok());
        // Tied constants need tied counts.
        let tied_constants = self::constants([100, 120, 180, 150, 140, 106, 105]);
        let apart = run_with_counts(&counts([100.0, 120.0, 180.0, 150.0, 140.0, 110.0, 105.0]));
        assert!(check_ranking(&apart, &tied_constants).is_err());
    }

    #[test]
    fn constants_tied_by_rounding_accept_the_counts_they_were_rounded_from() {
        // Table 162.8 and saturating-micromath 165.0 are 2.2 apart, the constants written from
        // them (163, 165) are tied: the run that wrote them passes its own check.
        let measured = [114.7, 166.8, 278.9, 172.8, 165.0, 162.8, 179.8];
        let run = run_with_counts(&counts(measured));
        let written = from_run(&run).unwrap();
        assert!(check_ranking(&run, &written).is_ok());
        assert!(check_drift(&run, &written).is_ok());
    }

    #[test]
    fn the_drift_tolerance_is_half_the_smallest_untied_gap() {
        let constants = constants([100, 120, 180, 150, 140, 110, 106]);
        // Gaps: 100, 106, 110, 120, 140, 150, 180 -> 6, 4, 10, 20, 10, 30: half of 4.
        assert_eq!(drift_tolerance(&constants), 2.0);
        let wide = self::constants([100, 130, 200, 170, 160, 120, 110]);
        assert_eq!(drift_tolerance(&wide), 5.0);
        let at = run_with_counts(&counts([100.0, 130.0, 200.0, 170.0, 160.0, 120.0, 110.0]));
        assert!(check_drift(&at, &wide).is_ok());
        let drifted = run_with_counts(&counts([100.0, 130.0, 206.0, 170.0, 160.0, 120.0, 110.0]));
        let message = check_drift(&drifted, &wide).unwrap_err().to_string();
        assert!(message.contains("monotone-cubic"), "{message}");
    }

    #[test]
    fn a_missing_count_is_an_error() {
        let constants = constants([100, 120, 180, 150, 140, 110, 105]);
        let partial = run_with_counts(&[(Tier::Linear, 10.0)]);
        assert!(check_ranking(&partial, &constants).is_err());
        assert!(check_drift(&partial, &constants).is_err());
    }

    #[test]
    fn the_block_is_replaced_and_nothing_else() {
        let source = "//! Module.\n\nuse x;\n\n/// Old doc.\n/// More.\npub const MEASURED_INSTRUCTIONS: [(Tier, u32); 1] = [\n    (Tier::Linear, 1),\n];\n\n/// Next.\npub const OTHER: u32 = 2;\n";
        let constants = constants([100, 120, 180, 150, 140, 110, 105]);
        let updated = replace_block(source, &block(&constants, "z")).unwrap();
        assert!(updated.starts_with("//! Module.\n\nuse x;\n\n/// Instructions per taxel"));
        assert!(updated.ends_with("];\n\n/// Next.\npub const OTHER: u32 = 2;\n"));
        assert!(updated.contains("    (Tier::MonotoneCubic, 180),\n"));
        assert!(updated.contains("opt-level \"z\""));
        assert!(!updated.contains("Old doc"));
        // Idempotent.
        let again = replace_block(&updated, &block(&constants, "z")).unwrap();
        assert_eq!(again, updated);
        assert!(replace_block("no constant here", "x").is_err());
    }

    #[test]
    fn the_file_in_the_workspace_has_a_replaceable_block() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let source = std::fs::read_to_string(root.join(USE_CASE_FILE)).unwrap();
        let current = model_core::use_case::MEASURED_INSTRUCTIONS.to_vec();
        let updated = replace_block(&source, &block(&current, "z")).unwrap();
        // What precedes the constant's doc comment and what follows `];` are untouched.
        let head =
            |text: &str| text[..text.find("/// Instructions per taxel").unwrap()].to_string();
        let tail = |text: &str| {
            let start = text.find(DECLARATION).unwrap();
            text[start..].split_once("\n];\n").unwrap().1.to_string()
        };
        assert_eq!(head(&updated), head(&source));
        assert_eq!(tail(&updated), tail(&source));
        assert!(updated.contains(&block(&current, "z")));
    }

    #[test]
    fn the_order_text_joins_ties() {
        let values = counts([100.0, 120.0, 180.0, 150.0, 140.0, 110.0, 109.0]);
        assert_eq!(
            order_text(&values),
            "linear < polynomial = table < piecewise-linear < saturating-micromath < saturating < monotone-cubic"
        );
    }
}
