//! Hard cases, use cases, temperature drift and hard calibrations.

use super::*;

pub(super) fn hard_cases(out: &mut String, run: &BenchRun) {
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

pub(super) fn use_cases(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Which tier each use case selects\n");
    let _ = writeln!(
        out,
        "`model_core::select_tier_for_taxels` on the article's curve picks, among the device's \
         tiers (the Pareto front: linear, table, monotone-cubic), the cheapest (by \
         `MEASURED_INSTRUCTIONS`) whose error over the use case's pressure and temperature range \
         fits the budget; the research tiers are evaluated below for comparison, never selected. \
         The error is the sum of four parts (model-core's `use_case` \
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

pub(super) fn drift(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## `MEASURED_INSTRUCTIONS`\n");
    let tolerance = crate::measured::drift_tolerance(&MEASURED_INSTRUCTIONS);
    let _ = writeln!(
        out,
        "The constants in the generated file `model-core/src/measured_instructions.rs` that `select_tier` ranks tiers by: \
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

pub(super) fn hard_calibrations(out: &mut String, run: &BenchRun) {
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
