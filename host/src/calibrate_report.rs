//! The report `taxel calibrate` prints after writing the calibration: the averaged levels, each
//! tier's error with leave-one-out cross-validation, and the conditioning of every interval.

use std::fmt::Write as _;

use model_core::{Calibration, TaxelInverses, TAXEL_COUNT, TAXEL_NAMES};

use crate::calibrate::{cross_validate, curve_points, ReferenceData, TierFitError};

fn cell(value: Option<f64>) -> String {
    value.map_or_else(|| "n/a".to_owned(), |value| format!("{value:.4}"))
}

/// The cross-validation table, one line per taxel and tier:
/// `taxel tier fit_max_kpa loo_max_kpa loo_rms_kpa folds`.
pub fn cross_validation_table(results: &[Vec<TierFitError>; TAXEL_COUNT]) -> String {
    let mut table = String::new();
    let _ = writeln!(
        table,
        "{:<6} {:<21} {:>12} {:>12} {:>12} {:>6}",
        "taxel", "tier", "fit_max_kpa", "loo_max_kpa", "loo_rms_kpa", "folds"
    );
    for (taxel, tiers) in results.iter().enumerate() {
        for tier in tiers {
            let folds = format!(
                "{}/{}",
                tier.leave_one_out_kpa.iter().flatten().count(),
                tier.leave_one_out_kpa.len()
            );
            let _ = writeln!(
                table,
                "{:<6} {:<21} {:>12} {:>12} {:>12} {:>6}",
                TAXEL_NAMES[taxel],
                tier.tier.name(),
                cell(tier.fit_max_kpa),
                cell(tier.leave_one_out_max_kpa()),
                cell(tier.leave_one_out_rms_kpa()),
                folds
            );
        }
    }
    table
}

/// The averaged levels, one line per level: pressure, repeats and mean dC/C0 per taxel.
pub fn levels_table(data: &ReferenceData) -> String {
    let mut table = String::new();
    let _ = writeln!(
        table,
        "{:>12} {:>7} {:>10} {:>10} {:>10} {:>10}",
        "pressure_kpa", "repeats", "c11", "c12", "c21", "c22"
    );
    for level in &data.levels {
        let _ = writeln!(
            table,
            "{:>12} {:>7} {:>10.6} {:>10.6} {:>10.6} {:>10.6}",
            level.pressure_kpa,
            level.repeats,
            level.mean_relative_change[0],
            level.mean_relative_change[1],
            level.mean_relative_change[2],
            level.mean_relative_change[3]
        );
    }
    table
}

/// Per taxel and calibration interval, the rms pressure noise that the converter's 0.5 fF causes
/// there (on the taxel's measured C0 - Cp), and one warning per interval above `budget_kpa`.
pub fn conditioning_report(
    calibration: &Calibration,
    unloaded_sensor_pf: &[f64; TAXEL_COUNT],
    budget_kpa: f32,
) -> (String, Vec<String>) {
    let mut table = String::new();
    let mut warnings = Vec::new();
    let _ = writeln!(
        table,
        "{:>6} {:>18} {:>14}",
        "taxel", "interval_kpa", "noise_kpa"
    );
    for (taxel, (name, taxel_calibration)) in
        TAXEL_NAMES.iter().zip(calibration.taxels()).enumerate()
    {
        let inverses = TaxelInverses::new(taxel_calibration.curve());
        let sensor_pf = unloaded_sensor_pf.get(taxel).copied().unwrap_or(f64::NAN) as f32;
        for interval in model_core::conditioning::interval_noise(
            inverses.monotone_cubic().forward(),
            sensor_pf,
            model_core::conditioning::CONVERTER_NOISE_PF,
        ) {
            let span = format!(
                "{}..{}",
                interval.pressure_low_kpa, interval.pressure_high_kpa
            );
            let _ = writeln!(table, "{name:>6} {span:>18} {:>14.4}", interval.noise_kpa);
            if !(interval.noise_kpa <= budget_kpa) {
                warnings.push(format!(
                    "warning: taxel {name}, {span} kPa: 0.5 fF of converter noise moves the \
                     pressure by {:.3} kPa rms, over the {budget_kpa} kPa budget (neighbouring \
                     levels nearly equal in dC/C0: pressure is poorly determined there)",
                    interval.noise_kpa
                ));
            }
        }
    }
    (table, warnings)
}

/// The fit's report for people (levels, the tiers' cross-validated errors, conditioning) and
/// its conditioning warnings, each starting "warning: ", for the caller to show (the CLI on
/// stderr, Python through `warnings`).
pub fn fit_report(
    data: &ReferenceData,
    calibration: &Calibration,
    budget_kpa: f32,
) -> (String, Vec<String>) {
    let mut text = format!(
        "{} rows, {} levels; C0 - Cp per taxel (pF, at 25 °C): {}\n",
        data.rows.len(),
        data.levels.len(),
        data.unloaded_sensor_pf
            .iter()
            .map(|pf| format!("{pf:.6}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    text.push_str("\nMean dC/C0 per level (the curve points):\n");
    text.push_str(&levels_table(data));
    let results: [Vec<TierFitError>; TAXEL_COUNT] =
        std::array::from_fn(|taxel| cross_validate(&curve_points(data, taxel)));
    text.push_str(
        "\nPressure error per tier, kPa (predicted - applied): fit_max at the points with \
         the full curve; loo = leave-one-out over the interior levels (folds = levels where \
         the tier was available):\n",
    );
    text.push_str(&cross_validation_table(&results));
    let (conditioning, warnings) =
        conditioning_report(calibration, &data.unloaded_sensor_pf, budget_kpa);
    text.push_str(
        "\nConditioning: rms pressure noise from 0.5 fF of converter noise, worst point of \
         each interval:\n",
    );
    text.push_str(&conditioning);
    (text, warnings)
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::{Calibration, CalibrationSpec, CurvePoint};

    #[test]
    fn conditioning_names_the_flat_interval_and_warns_over_budget() {
        let mut spec = CalibrationSpec::default();
        spec.taxels[1].points = heapless::Vec::from_slice(&[
            CurvePoint::new(0.0, 0.0),
            CurvePoint::new(10.0, 0.1),
            CurvePoint::new(20.0, 0.10001),
            CurvePoint::new(30.0, 0.15),
        ])
        .unwrap();
        let calibration = Calibration::new(&spec).unwrap();
        let (table, warnings) = conditioning_report(&calibration, &[4.5; 4], 0.5);
        // The article's curve on c11: its first interval by hand, 0.5 fF / 4.5 pF over the
        // Fritsch-Carlson slope there (at least the 0.00738 /kPa end tangent): under 0.016 kPa.
        let first = table.lines().nth(1).unwrap();
        assert!(first.contains("c11") && first.contains("0..10"), "{first}");
        let noise: f32 = first.split_whitespace().last().unwrap().parse().unwrap();
        assert!(noise > 0.011 && noise < 0.016, "{noise}");
        // The 10..20 kPa interval of c12 rises by 1e-5: about 1.1e-4 / 1e-6 = 111 kPa or worse.
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("c12") && w.contains("10..20")),
            "{warnings:?}"
        );
        assert!(warnings.iter().all(|w| w.contains("c12")), "{warnings:?}");
    }
}
