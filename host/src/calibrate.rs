//! `taxel calibrate`: fits a calibration from reference loads, reports each inversion tier's
//! error with leave-one-out cross-validation, writes the versioned calibration file, and
//! optionally uploads it to a device.
//!
//! Input: a CSV with `pressure_kpa`, `c11_pf..c22_pf` and optionally `temp_c`; several rows
//! (repeats) per load allowed. The rows at 0 kPa give C0 per taxel. Every row's capacitance is
//! brought to the reference temperature with the article's permittivity law (when it has a
//! temperature) before `dC/C0 = (C - Cp) / (k (C0 - Cp)) - 1` is formed; repeats are averaged
//! per pressure level, and the averaged levels are the curve points.

use std::collections::BTreeMap;
use std::io::Read;

use anyhow::Context;
use model_core::calibration::MAX_CURVE_POINTS;
use model_core::{
    leave_one_out_errors_kpa, Calibration, CalibrationCurve, CalibrationError, CalibrationSpec,
    CurvePoint, TaxelInverses, TemperatureLaw, Tier, TAXEL_COUNT, TAXEL_NAMES,
};

use crate::calibration_file::describe_calibration_error;
use crate::csv_format::{
    find_column, find_columns, parse_optional_number, CAPACITANCE_COLUMNS, TEMPERATURE_COLUMN,
};

/// The pressure column of a reference-load file.
pub const PRESSURE_COLUMN: &str = "pressure_kpa";

/// Why a data set cannot be turned into a calibration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrateError {
    /// The file has rows that cannot be read.
    #[error("{count} row(s) could not be read:\n{details}")]
    BadRows {
        /// How many.
        count: usize,
        /// One line per row: line number and reason.
        details: String,
    },
    /// No row is at 0 kPa, so C0 is unknown.
    #[error("no rows at pressure 0: C0 of each taxel comes from the unloaded rows")]
    NoUnloadedRows,
    /// A pressure is negative.
    #[error("line {line}: negative pressure {pressure_kpa} kPa")]
    NegativePressure {
        /// Line number.
        line: u64,
        /// The pressure.
        pressure_kpa: f64,
    },
    /// Fewer than two pressure levels.
    #[error("only {levels} pressure level(s): a curve needs 0 kPa and at least one load")]
    TooFewLevels {
        /// Distinct pressures found.
        levels: usize,
    },
    /// More levels than a calibration holds.
    #[error("{levels} pressure levels, but a calibration curve holds at most {MAX_CURVE_POINTS}")]
    TooManyLevels {
        /// Distinct pressures found.
        levels: usize,
    },
    /// C0 minus the parasitic capacitance is not positive.
    #[error(
        "taxel {taxel}: C0 minus the parasitic capacitance is {sensor_pf} pF (must be positive)"
    )]
    NoSensorCapacitance {
        /// Taxel name.
        taxel: &'static str,
        /// C0 - Cp at the reference temperature.
        sensor_pf: f64,
    },
    /// The averaged curve does not increase strictly.
    #[error(
        "taxel {taxel} is not monotone: mean dC/C0 at {pressure_kpa} kPa is {relative_change:.6}, \
         not above {previous_relative_change:.6} at {previous_pressure_kpa} kPa \
         (a calibration curve must increase strictly; check the data set)"
    )]
    NotMonotone {
        /// Taxel name.
        taxel: &'static str,
        /// The level that fails.
        pressure_kpa: f64,
        /// Its mean dC/C0.
        relative_change: f64,
        /// The level before it.
        previous_pressure_kpa: f64,
        /// Its mean dC/C0.
        previous_relative_change: f64,
    },
    /// Any other refusal by `Calibration::new`.
    #[error("invalid calibration: {0}")]
    Invalid(String),
}

/// One reference-load row.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadRow {
    /// 1-based line number in the file.
    pub line: u64,
    /// Applied pressure, kPa.
    pub pressure_kpa: f64,
    /// Measured capacitances in pad order, pF.
    pub capacitances_pf: [f64; TAXEL_COUNT],
    /// Pad temperature, °C, if given.
    pub temperature_c: Option<f64>,
}

/// Reads a reference-load CSV; any unreadable row refuses the whole file (a calibration should
/// not silently skip data).
pub fn read_loads<R: Read>(input: R) -> anyhow::Result<Vec<LoadRow>> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(input);
    let header = reader.headers().context("reading the header row")?.clone();
    let wanted = [
        PRESSURE_COLUMN,
        CAPACITANCE_COLUMNS[0],
        CAPACITANCE_COLUMNS[1],
        CAPACITANCE_COLUMNS[2],
        CAPACITANCE_COLUMNS[3],
    ];
    let columns = find_columns(&header, wanted).map_err(|missing| {
        anyhow::anyhow!("the header lacks the column(s) {}", missing.join(", "))
    })?;
    let temperature_column = find_column(&header, TEMPERATURE_COLUMN);
    let mut rows = Vec::new();
    let mut problems = Vec::new();
    for result in reader.records() {
        let record = match result {
            Ok(record) => record,
            Err(error) => {
                let line = error.position().map_or(0, |position| position.line());
                problems.push(format!("line {line}: {error}"));
                continue;
            }
        };
        let line = record.position().map_or(0, |position| position.line());
        let parsed = (|| -> Result<LoadRow, String> {
            if record.len() != header.len() {
                return Err(format!(
                    "expected {} fields, found {}",
                    header.len(),
                    record.len()
                ));
            }
            let number = |index: usize, name: &str| -> Result<f64, String> {
                match parse_optional_number(record.get(index).unwrap_or("")) {
                    Ok(Some(value)) if value.is_finite() => Ok(value),
                    Ok(Some(_)) => Err(format!("{name} is not finite")),
                    Ok(None) => Err(format!("{name} is empty")),
                    Err(error) => Err(format!("{name}: {error}")),
                }
            };
            let pressure_kpa = number(columns[0], PRESSURE_COLUMN)?;
            let mut capacitances_pf = [0.0; TAXEL_COUNT];
            for (taxel, capacitance_pf) in capacitances_pf.iter_mut().enumerate() {
                *capacitance_pf = number(columns[1 + taxel], CAPACITANCE_COLUMNS[taxel])?;
            }
            let temperature_c = match temperature_column {
                Some(index) => parse_optional_number(record.get(index).unwrap_or(""))
                    .map_err(|error| format!("{TEMPERATURE_COLUMN}: {error}"))?
                    .filter(|value| value.is_finite()),
                None => None,
            };
            Ok(LoadRow {
                line,
                pressure_kpa,
                capacitances_pf,
                temperature_c,
            })
        })();
        match parsed {
            Ok(row) => rows.push(row),
            Err(reason) => problems.push(format!("line {line}: {reason}")),
        }
    }
    if !problems.is_empty() {
        return Err(CalibrateError::BadRows {
            count: problems.len(),
            details: problems.join("\n"),
        }
        .into());
    }
    Ok(rows)
}

/// One pressure level: its repeats averaged.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// Applied pressure, kPa.
    pub pressure_kpa: f64,
    /// Rows at this pressure.
    pub repeats: usize,
    /// Mean dC/C0 per taxel.
    pub mean_relative_change: [f64; TAXEL_COUNT],
    /// Largest minus smallest dC/C0 among the repeats, per taxel.
    pub spread_relative_change: [f64; TAXEL_COUNT],
}

/// One row's dC/C0.
#[derive(Debug, Clone, PartialEq)]
pub struct RowChange {
    /// Line number.
    pub line: u64,
    /// Applied pressure, kPa.
    pub pressure_kpa: f64,
    /// dC/C0 per taxel at the reference temperature.
    pub relative_change: [f64; TAXEL_COUNT],
}

/// Reference loads reduced to dC/C0.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceData {
    /// C0 - Cp per taxel at the reference temperature (mean of the unloaded rows), pF.
    pub unloaded_sensor_pf: [f64; TAXEL_COUNT],
    /// Every row.
    pub rows: Vec<RowChange>,
    /// Levels in increasing pressure.
    pub levels: Vec<Level>,
    /// Rows whose temperature was outside the law's characterised range (clamped).
    pub rows_temperature_clamped: usize,
}

/// Forms dC/C0 for every row and averages the repeats per level.
pub fn reference_data(
    rows: &[LoadRow],
    parasitic_pf: [f64; TAXEL_COUNT],
    law: &TemperatureLaw,
) -> Result<ReferenceData, CalibrateError> {
    if let Some(row) = rows.iter().find(|row| row.pressure_kpa < 0.0) {
        return Err(CalibrateError::NegativePressure {
            line: row.line,
            pressure_kpa: row.pressure_kpa,
        });
    }
    let (minimum_c, maximum_c) = (
        f64::from(law.characterised_min_c()),
        f64::from(law.characterised_max_c()),
    );
    let mut rows_temperature_clamped = 0;
    let sensor_at_reference: Vec<[f64; TAXEL_COUNT]> = rows
        .iter()
        .map(|row| {
            let ratio = match row.temperature_c {
                Some(temperature_c) => {
                    let clamped = temperature_c.clamp(minimum_c, maximum_c);
                    if clamped != temperature_c {
                        rows_temperature_clamped += 1;
                    }
                    f64::from(law.permittivity_ratio(clamped as f32))
                }
                None => 1.0,
            };
            std::array::from_fn(|taxel| (row.capacitances_pf[taxel] - parasitic_pf[taxel]) / ratio)
        })
        .collect();
    let unloaded: Vec<&[f64; TAXEL_COUNT]> = rows
        .iter()
        .zip(&sensor_at_reference)
        .filter(|(row, _)| row.pressure_kpa == 0.0)
        .map(|(_, sensor)| sensor)
        .collect();
    if unloaded.is_empty() {
        return Err(CalibrateError::NoUnloadedRows);
    }
    let mut unloaded_sensor_pf = [0.0; TAXEL_COUNT];
    for (taxel, mean) in unloaded_sensor_pf.iter_mut().enumerate() {
        *mean = unloaded.iter().map(|sensor| sensor[taxel]).sum::<f64>() / unloaded.len() as f64;
        if !(*mean > 0.0) {
            return Err(CalibrateError::NoSensorCapacitance {
                taxel: TAXEL_NAMES[taxel],
                sensor_pf: *mean,
            });
        }
    }
    let row_changes: Vec<RowChange> = rows
        .iter()
        .zip(&sensor_at_reference)
        .map(|(row, sensor)| RowChange {
            line: row.line,
            pressure_kpa: row.pressure_kpa,
            relative_change: std::array::from_fn(|taxel| {
                sensor[taxel] / unloaded_sensor_pf[taxel] - 1.0
            }),
        })
        .collect();
    let mut grouped: BTreeMap<u64, Vec<&RowChange>> = BTreeMap::new();
    for row in &row_changes {
        // Non-negative finite f64 order like their bit patterns.
        grouped
            .entry(row.pressure_kpa.to_bits())
            .or_default()
            .push(row);
    }
    let levels: Vec<Level> = grouped
        .into_values()
        .map(|group| {
            let pressure_kpa = group[0].pressure_kpa;
            let column = |taxel: usize| group.iter().map(move |row| row.relative_change[taxel]);
            let mut mean_relative_change: [f64; TAXEL_COUNT] =
                std::array::from_fn(|taxel| column(taxel).sum::<f64>() / group.len() as f64);
            if pressure_kpa == 0.0 {
                // The unloaded mean is 0 by construction; rounding must not move the origin.
                mean_relative_change = [0.0; TAXEL_COUNT];
            }
            let spread_relative_change = std::array::from_fn(|taxel| {
                column(taxel).fold(f64::NEG_INFINITY, f64::max)
                    - column(taxel).fold(f64::INFINITY, f64::min)
            });
            Level {
                pressure_kpa,
                repeats: group.len(),
                mean_relative_change,
                spread_relative_change,
            }
        })
        .collect();
    if levels.len() < 2 {
        return Err(CalibrateError::TooFewLevels {
            levels: levels.len(),
        });
    }
    if levels.len() > MAX_CURVE_POINTS {
        return Err(CalibrateError::TooManyLevels {
            levels: levels.len(),
        });
    }
    Ok(ReferenceData {
        unloaded_sensor_pf,
        rows: row_changes,
        levels,
        rows_temperature_clamped,
    })
}

/// The curve points of one taxel from the averaged levels.
pub fn curve_points(data: &ReferenceData, taxel: usize) -> Vec<CurvePoint> {
    data.levels
        .iter()
        .map(|level| {
            CurvePoint::new(
                level.pressure_kpa as f32,
                level.mean_relative_change[taxel] as f32,
            )
        })
        .collect()
}

/// Builds and validates the calibration: the averaged levels as curve points, the parasitic
/// capacitance, each taxel's measured C0 - Cp at 25 °C (so that the model flags a later tare far
/// from it), the article's temperature law and the default thresholds.
pub fn fit_calibration(
    data: &ReferenceData,
    id: u32,
    parasitic_pf: f32,
) -> Result<Calibration, CalibrateError> {
    let mut spec = CalibrationSpec {
        id,
        ..CalibrationSpec::default()
    };
    for (taxel, taxel_spec) in spec.taxels.iter_mut().enumerate() {
        taxel_spec.points = curve_points(data, taxel).into_iter().collect();
        taxel_spec.parasitic_pf = parasitic_pf;
        taxel_spec.unloaded_sensor_pf = data
            .unloaded_sensor_pf
            .get(taxel)
            .map(|&unloaded_pf| unloaded_pf as f32);
    }
    Calibration::new(&spec).map_err(|error| match error {
        CalibrationError::NotStrictlyIncreasing { taxel, point } => {
            let (taxel, point) = (usize::from(taxel), usize::from(point));
            match (
                data.levels.get(point),
                point
                    .checked_sub(1)
                    .and_then(|previous| data.levels.get(previous)),
            ) {
                (Some(level), Some(previous)) if taxel < TAXEL_COUNT => {
                    CalibrateError::NotMonotone {
                        taxel: TAXEL_NAMES[taxel],
                        pressure_kpa: level.pressure_kpa,
                        relative_change: level.mean_relative_change[taxel],
                        previous_pressure_kpa: previous.pressure_kpa,
                        previous_relative_change: previous.mean_relative_change[taxel],
                    }
                }
                _ => CalibrateError::Invalid(describe_calibration_error(&error)),
            }
        }
        other => CalibrateError::Invalid(describe_calibration_error(&other)),
    })
}

/// One tier's error on one taxel, kPa (predicted minus applied pressure).
#[derive(Debug, Clone, PartialEq)]
pub struct TierFitError {
    /// The tier.
    pub tier: Tier,
    /// Largest |error| at the calibration points with the full curve (`None` if the tier is not
    /// available for the curve).
    pub fit_max_kpa: Option<f64>,
    /// Leave-one-out error per interior level, in level order (`None` where the tier is not
    /// available for the reduced curve).
    pub leave_one_out_kpa: Vec<Option<f64>>,
}

impl TierFitError {
    fn evaluated(&self) -> impl Iterator<Item = f64> + '_ {
        self.leave_one_out_kpa.iter().flatten().copied()
    }

    /// Largest leave-one-out |error|, kPa (`None` if no fold could use the tier).
    pub fn leave_one_out_max_kpa(&self) -> Option<f64> {
        self.evaluated().map(f64::abs).reduce(f64::max)
    }

    /// Root mean square of the leave-one-out errors, kPa.
    pub fn leave_one_out_rms_kpa(&self) -> Option<f64> {
        let count = self.evaluated().count();
        (count > 0).then(|| {
            (self.evaluated().map(|error| error * error).sum::<f64>() / count as f64).sqrt()
        })
    }
}

/// Predicts the pressure of a relative change through a tier, as the model does for a reading
/// within the curve.
fn predict_kpa(inverses: &TaxelInverses, tier: Tier, relative_change: f32) -> f64 {
    f64::from(inverses.pressure_kpa(tier, relative_change))
}

/// Leave-one-out cross-validation of every tier on one taxel's curve: each interior point is
/// predicted from the curve rebuilt without it.
pub fn cross_validate(points: &[CurvePoint]) -> Vec<TierFitError> {
    let full = CalibrationCurve::new(points, 0)
        .ok()
        .map(|curve| TaxelInverses::new(&curve));
    Tier::ALL
        .iter()
        .map(|&tier| {
            let fit_max_kpa = full
                .as_ref()
                .filter(|inverses| inverses.supports(tier))
                .map(|inverses| {
                    points
                        .iter()
                        .map(|point| {
                            (predict_kpa(inverses, tier, point.relative_change)
                                - f64::from(point.pressure_kpa))
                            .abs()
                        })
                        .fold(0.0, f64::max)
                });
            let leave_one_out_kpa = leave_one_out_errors_kpa(points, tier)
                .iter()
                .map(|error| error.map(f64::from))
                .collect();
            TierFitError {
                tier,
                fit_max_kpa,
                leave_one_out_kpa,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(line: u64, pressure_kpa: f64, capacitance_pf: f64) -> LoadRow {
        LoadRow {
            line,
            pressure_kpa,
            capacitances_pf: [capacitance_pf; TAXEL_COUNT],
            temperature_c: None,
        }
    }

    #[test]
    fn repeats_are_averaged_and_the_origin_is_exact() {
        let rows = [
            row(2, 0.0, 4.4),
            row(3, 0.0, 4.6),
            row(4, 10.0, 4.9),
            row(5, 10.0, 5.1),
        ];
        let data = reference_data(&rows, [0.0; 4], &TemperatureLaw::article_default()).unwrap();
        assert_eq!(data.levels.len(), 2);
        assert_eq!(data.levels[0].mean_relative_change, [0.0; 4]);
        assert!((data.levels[1].mean_relative_change[0] - (5.0 / 4.5 - 1.0)).abs() < 1e-12);
        assert_eq!(data.levels[1].repeats, 2);
    }

    #[test]
    fn the_measured_c0_goes_into_the_calibration_and_its_wire_records() {
        let rows = [
            LoadRow {
                capacitances_pf: [5.3, 5.1, 5.5, 5.2],
                ..row(2, 0.0, 0.0)
            },
            LoadRow {
                capacitances_pf: [5.7, 5.5, 5.9, 5.6],
                ..row(3, 10.0, 0.0)
            },
        ];
        let data = reference_data(&rows, [0.8; 4], &TemperatureLaw::article_default()).unwrap();
        let calibration = fit_calibration(&data, 3, 0.8).unwrap();
        for (taxel, expected_pf) in [4.5f32, 4.3, 4.7, 4.4].into_iter().enumerate() {
            let unloaded_pf = calibration.taxels()[taxel].unloaded_sensor_pf().unwrap();
            assert!((unloaded_pf - expected_pf).abs() < 1e-5, "{unloaded_pf}");
            let record =
                device::calibration_record(&calibration, wire::PadIndex::default(), taxel as u8)
                    .unwrap();
            assert_eq!(record.calibration.unloaded_sensor_pf, Some(unloaded_pf));
            assert_eq!(record.check(), Ok(()));
        }
    }

    #[test]
    fn piecewise_linear_leave_one_out_is_the_chord_error() {
        let points = model_core::ARTICLE_TABLE_1;
        let results = cross_validate(&points);
        let piecewise = results
            .iter()
            .find(|result| result.tier == Tier::PiecewiseLinear)
            .unwrap();
        assert_eq!(piecewise.leave_one_out_kpa.len(), 4);
        // Leaving out 10 kPa: the chord from (0, 0) to (20, 0.1475) gives 0.0829 at
        // 20 * 0.0829 / 0.1475 kPa.
        let expected = 20.0 * 0.0829 / 0.1475 - 10.0;
        let error = piecewise.leave_one_out_kpa[0].unwrap();
        assert!((error - expected).abs() < 1e-3, "{error} vs {expected}");
        assert_eq!(piecewise.fit_max_kpa.map(|error| error < 1e-3), Some(true));
    }
}
