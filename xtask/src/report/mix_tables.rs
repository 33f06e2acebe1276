//! Instruction-mix tables and the polynomial degree table.

use super::*;

pub(super) fn mix_row(name: &str, counts: &Mix, systick: String) -> String {
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

pub(super) const MIX_HEADER: &str = "| subject | traced instructions | SysTick | VDIV/VSQRT | VMLA/VFMA | other FP arithmetic | LDR/VLDR | words in LDM/STM/PUSH/POP | branches always / conditional | est. cycles (lower–upper) |\n|---|---|---|---|---|---|---|---|---|---|";

pub(super) fn mix_table(out: &mut String, data: &ReportData) {
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
pub(super) fn lowest_close_degree(data: &ReportData) -> Option<(usize, f64)> {
    data.polynomial_degrees
        .iter()
        .filter_map(|(degree, distance)| Some((*degree, (*distance)?)))
        .filter(|(_, distance)| *distance <= FAST_TIER_DISTANCE_KPA)
        .min_by_key(|(degree, _)| *degree)
}

pub(super) fn polynomial_degree_table(out: &mut String, data: &ReportData) {
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
