//! Calibration data and its validation: the curve dC/C0 = f(P) per taxel, the parasitic
//! capacitance, the permittivity-against-temperature law, and the fault thresholds.
//!
//! [`CalibrationSpec`] is plain data (files, flash, wire); [`Calibration`] is the validated form
//! the model accepts. Validation is the only way from one to the other, so the model never sees a
//! curve it cannot invert.

use heapless::Vec;

use crate::reading::MAX_MEASURABLE_PF;

/// Number of taxels on the pad (C11, C12, C21, C22, in that order).
pub const TAXEL_COUNT: usize = 4;

/// Most points a calibration curve may hold.
pub const MAX_CURVE_POINTS: usize = 16;

/// Most points a temperature law may hold.
pub const MAX_TEMPERATURE_POINTS: usize = 8;

/// Names of the taxels in pad order, as in the article (row, column).
pub const TAXEL_NAMES: [&str; TAXEL_COUNT] = ["c11", "c12", "c21", "c22"];

/// The article's Table 1: cumulative dC/C0 at 0, 10, ... 50 kPa (means of the four taxels).
pub const ARTICLE_TABLE_1: [CurvePoint; 6] = [
    CurvePoint::new(0.0, 0.0),
    CurvePoint::new(10.0, 0.0829),
    CurvePoint::new(20.0, 0.1475),
    CurvePoint::new(30.0, 0.1981),
    CurvePoint::new(40.0, 0.2317),
    CurvePoint::new(50.0, 0.2563),
];

/// One calibration point: the relative capacitance change measured at a pressure.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CurvePoint {
    /// Applied normal pressure in kPa.
    pub pressure_kpa: f32,
    /// dC/C0 at that pressure, at the reference temperature.
    pub relative_change: f32,
}

impl CurvePoint {
    /// A point from its pressure and relative change.
    pub const fn new(pressure_kpa: f32, relative_change: f32) -> Self {
        Self {
            pressure_kpa,
            relative_change,
        }
    }
}

/// One point of the permittivity law: eps_r(T) / eps_r(reference).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PermittivityPoint {
    /// Pad temperature in °C.
    pub temperature_c: f32,
    /// Relative permittivity at that temperature divided by its value at the reference.
    pub permittivity_ratio: f32,
}

/// Why a calibration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationError {
    /// A curve has fewer than two points.
    TooFewPoints {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// A curve does not start at (0 kPa, 0).
    DoesNotStartAtOrigin {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// A value is NaN or infinite.
    NotFinite {
        /// Taxel index, 0..4 (or 255 for the temperature law and thresholds).
        taxel: u8,
    },
    /// Pressure or relative change does not strictly increase from one point to the next.
    NotStrictlyIncreasing {
        /// Taxel index, 0..4.
        taxel: u8,
        /// Index of the first point that fails.
        point: u8,
    },
    /// The parasitic capacitance is negative or above the converter's reach (100 pF).
    ParasiticOutOfRange {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// The calibrated unloaded capacitance is not a positive capacitance the converter can read.
    UnloadedOutOfRange {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// The temperature law is empty, not increasing in temperature, or has a ratio outside 0.5..2.
    InvalidTemperatureLaw,
    /// A fault threshold is out of its documented range.
    InvalidThresholds,
}

/// The first `N` items of `items` in a bounded vector. Every caller copies between vectors of
/// the same capacity (or a constant that fits), so nothing is dropped; unlike heapless'
/// `collect`, a longer input could not panic.
pub(crate) fn bounded_copy<T: Copy, const N: usize>(items: &[T]) -> Vec<T, N> {
    let mut copy = Vec::new();
    for item in items.iter().take(N) {
        let _ = copy.push(*item);
    }
    copy
}

/// Index used in [`CalibrationError`] for errors that belong to no taxel.
pub const NO_TAXEL: u8 = u8::MAX;

/// The validated calibration curve of one taxel.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationCurve {
    points: Vec<CurvePoint, MAX_CURVE_POINTS>,
}

impl CalibrationCurve {
    /// Validates points as a curve: at least two, finite, starting at (0, 0), strictly increasing
    /// in both pressure and relative change.
    pub fn new(points: &[CurvePoint], taxel: u8) -> Result<Self, CalibrationError> {
        if points.len() < 2 {
            return Err(CalibrationError::TooFewPoints { taxel });
        }
        let mut validated = Vec::new();
        for (index, point) in points.iter().enumerate() {
            if !point.pressure_kpa.is_finite() || !point.relative_change.is_finite() {
                return Err(CalibrationError::NotFinite { taxel });
            }
            if index == 0 && (point.pressure_kpa != 0.0 || point.relative_change != 0.0) {
                return Err(CalibrationError::DoesNotStartAtOrigin { taxel });
            }
            if let Some(previous) = validated.last() {
                let previous: &CurvePoint = previous;
                if point.pressure_kpa <= previous.pressure_kpa
                    || point.relative_change <= previous.relative_change
                {
                    return Err(CalibrationError::NotStrictlyIncreasing {
                        taxel,
                        point: index as u8,
                    });
                }
            }
            validated
                .push(*point)
                .map_err(|_| CalibrationError::NotStrictlyIncreasing {
                    taxel,
                    point: index as u8,
                })?;
        }
        Ok(Self { points: validated })
    }

    /// The article's Table 1.
    pub fn article_default() -> Self {
        Self {
            points: bounded_copy(&ARTICLE_TABLE_1),
        }
    }

    /// The points, in increasing order.
    pub fn points(&self) -> &[CurvePoint] {
        &self.points
    }

    /// The highest calibrated point (pressure and relative change).
    pub fn top(&self) -> CurvePoint {
        self.points
            .last()
            .copied()
            .unwrap_or(CurvePoint::new(0.0, 0.0))
    }

    /// One coordinate of every point, widened to f64.
    fn widened(&self, coordinate: impl Fn(&CurvePoint) -> f32) -> Vec<f64, MAX_CURVE_POINTS> {
        let mut values = Vec::new();
        for point in &self.points {
            // Same capacity as the points: a push cannot fail.
            let _ = values.push(f64::from(coordinate(point)));
        }
        values
    }

    /// Pressures as f64, for construction-time fits.
    pub(crate) fn pressures_kpa(&self) -> Vec<f64, MAX_CURVE_POINTS> {
        self.widened(|point| point.pressure_kpa)
    }

    /// Relative changes as f64, for construction-time fits.
    pub(crate) fn relative_changes(&self) -> Vec<f64, MAX_CURVE_POINTS> {
        self.widened(|point| point.relative_change)
    }
}

/// The validated permittivity law: piecewise linear through its points, flat outside them, and
/// the range of temperatures that was characterised.
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureLaw {
    points: Vec<PermittivityPoint, MAX_TEMPERATURE_POINTS>,
    characterised_min_c: f32,
    characterised_max_c: f32,
}

impl TemperatureLaw {
    /// The article's law (Fig. 13): flat at or below 25 °C, linear down to -3.24 % at 55 °C,
    /// characterised from 5 to 55 °C. Between 25 and 55 °C the article gives no numbers, so
    /// linear is the least-assumption reading.
    pub fn article_default() -> Self {
        Self {
            points: bounded_copy(&[
                PermittivityPoint {
                    temperature_c: 25.0,
                    permittivity_ratio: 1.0,
                },
                PermittivityPoint {
                    temperature_c: 55.0,
                    permittivity_ratio: 1.0 - 0.0324,
                },
            ]),
            characterised_min_c: 5.0,
            characterised_max_c: 55.0,
        }
    }

    /// Validates a law: 1 ..= [`MAX_TEMPERATURE_POINTS`] points, finite, strictly increasing in
    /// temperature, ratios within 0.5 ..= 2, and a characterised range `min < max`.
    pub fn new(
        points: &[PermittivityPoint],
        characterised_min_c: f32,
        characterised_max_c: f32,
    ) -> Result<Self, CalibrationError> {
        let invalid = CalibrationError::InvalidTemperatureLaw;
        if points.is_empty()
            || !characterised_min_c.is_finite()
            || !characterised_max_c.is_finite()
            || characterised_min_c >= characterised_max_c
        {
            return Err(invalid);
        }
        let mut validated: Vec<PermittivityPoint, MAX_TEMPERATURE_POINTS> = Vec::new();
        for point in points {
            let ratio_ok = (0.5..=2.0).contains(&point.permittivity_ratio);
            let increasing = validated
                .last()
                .is_none_or(|previous| point.temperature_c > previous.temperature_c);
            if !point.temperature_c.is_finite() || !ratio_ok || !increasing {
                return Err(invalid);
            }
            validated.push(*point).map_err(|_| invalid)?;
        }
        Ok(Self {
            points: validated,
            characterised_min_c,
            characterised_max_c,
        })
    }

    /// The law's points.
    pub fn points(&self) -> &[PermittivityPoint] {
        &self.points
    }

    /// Lowest characterised temperature, °C.
    pub fn characterised_min_c(&self) -> f32 {
        self.characterised_min_c
    }

    /// Highest characterised temperature, °C.
    pub fn characterised_max_c(&self) -> f32 {
        self.characterised_max_c
    }

    /// The steepest |d(eps_r ratio)/dT| of the law inside `low_c ..= high_c`, per °C (the law
    /// is flat outside its points).
    pub fn steepest_slope_per_c(&self, low_c: f32, high_c: f32) -> f32 {
        let mut steepest = 0.0f32;
        for pair in self.points.windows(2) {
            if let [low, high] = pair {
                let overlaps = low.temperature_c < high_c && high.temperature_c > low_c;
                let slope = (high.permittivity_ratio - low.permittivity_ratio)
                    / (high.temperature_c - low.temperature_c);
                if overlaps && slope.abs() > steepest {
                    steepest = slope.abs();
                }
            }
        }
        steepest
    }

    /// eps_r(T) / eps_r(reference) for a temperature already clamped to the characterised range.
    pub fn permittivity_ratio(&self, temperature_c: f32) -> f32 {
        let points = self.points.as_slice();
        let (Some(first), Some(last)) = (points.first(), points.last()) else {
            return 1.0;
        };
        if !(temperature_c > first.temperature_c) {
            return first.permittivity_ratio;
        }
        if temperature_c >= last.temperature_c {
            return last.permittivity_ratio;
        }
        for pair in points.windows(2) {
            let [low, high] = pair else {
                continue;
            };
            if temperature_c < high.temperature_c {
                let fraction =
                    (temperature_c - low.temperature_c) / (high.temperature_c - low.temperature_c);
                return low.permittivity_ratio
                    + fraction * (high.permittivity_ratio - low.permittivity_ratio);
            }
        }
        last.permittivity_ratio
    }
}

/// Thresholds that turn a reading into a fault or a warning.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultThresholds {
    /// A sensor capacitance (reading minus parasitic) below this is an open lead, pF.
    /// Default 1.0 pF: a taxel is about 4.5 pF, pure PDMS 2.8 pF.
    pub open_below_pf: f32,
    /// A relative change below minus this is a short (conduction) rather than drift. Default 0.15.
    pub shorted_below_relative: f32,
    /// Negative relative changes smaller than this are noise: 0 kPa, no flag. Default 0.003
    /// (about 13 fF on 4.5 pF, 27x the converter's 0.5 fF rms noise).
    pub dead_band_relative: f32,
}

impl Default for FaultThresholds {
    fn default() -> Self {
        Self {
            open_below_pf: 1.0,
            shorted_below_relative: 0.15,
            dead_band_relative: 0.003,
        }
    }
}

impl FaultThresholds {
    fn validate(&self) -> Result<(), CalibrationError> {
        let in_range = (0.0..=50.0).contains(&self.open_below_pf)
            && (0.0..=1.0).contains(&self.shorted_below_relative)
            && (0.0..=0.1).contains(&self.dead_band_relative)
            && self.dead_band_relative < self.shorted_below_relative;
        if in_range {
            Ok(())
        } else {
            Err(CalibrationError::InvalidThresholds)
        }
    }
}

/// The calibration of one taxel as plain data.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TaxelCalibrationSpec {
    /// dC/C0 against pressure, starting at (0, 0).
    pub points: Vec<CurvePoint, MAX_CURVE_POINTS>,
    /// Capacitance of the lead and converter input that is not part of C0 and does not follow the
    /// permittivity, pF.
    pub parasitic_pf: f32,
    /// The taxel's unloaded sensor capacitance C0 - Cp at 25 °C when it was calibrated, pF, if
    /// known (the built-in default has none). A tare far from it is flagged.
    #[cfg_attr(feature = "serde", serde(default))]
    pub unloaded_sensor_pf: Option<f32>,
}

/// A whole pad's calibration as plain data: what files, flash records and the wire carry.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CalibrationSpec {
    /// Identifier chosen by whoever made the calibration (0 = the built-in default).
    pub id: u32,
    /// Per taxel, in pad order.
    pub taxels: [TaxelCalibrationSpec; TAXEL_COUNT],
    /// Permittivity law points.
    pub temperature_points: Vec<PermittivityPoint, MAX_TEMPERATURE_POINTS>,
    /// Lowest characterised temperature, °C.
    pub characterised_min_c: f32,
    /// Highest characterised temperature, °C.
    pub characterised_max_c: f32,
    /// Fault thresholds.
    pub thresholds: FaultThresholds,
}

impl Default for CalibrationSpec {
    fn default() -> Self {
        Calibration::default().to_spec()
    }
}

/// The validated calibration of one taxel.
#[derive(Debug, Clone, PartialEq)]
///
/// Only [`TaxelCalibration::new`] builds one, so every value held is a validated one.
pub struct TaxelCalibration {
    curve: CalibrationCurve,
    parasitic_pf: f32,
    unloaded_sensor_pf: Option<f32>,
}

impl TaxelCalibration {
    /// The curve.
    pub fn curve(&self) -> &CalibrationCurve {
        &self.curve
    }

    /// Parasitic capacitance, pF (0 ..= 100).
    pub fn parasitic_pf(&self) -> f32 {
        self.parasitic_pf
    }

    /// Unloaded sensor capacitance C0 - Cp at 25 °C when calibrated, pF (finite, positive,
    /// within the converter's reach), if known.
    pub fn unloaded_sensor_pf(&self) -> Option<f32> {
        self.unloaded_sensor_pf
    }

    /// Validates one taxel's data.
    pub fn new(spec: &TaxelCalibrationSpec, taxel: u8) -> Result<Self, CalibrationError> {
        let curve = CalibrationCurve::new(&spec.points, taxel)?;
        if !spec.parasitic_pf.is_finite() {
            return Err(CalibrationError::NotFinite { taxel });
        }
        if !(0.0..=100.0).contains(&spec.parasitic_pf) {
            return Err(CalibrationError::ParasiticOutOfRange { taxel });
        }
        if let Some(unloaded_pf) = spec.unloaded_sensor_pf {
            if !(unloaded_pf > 0.0 && unloaded_pf <= MAX_MEASURABLE_PF) {
                return Err(CalibrationError::UnloadedOutOfRange { taxel });
            }
        }
        Ok(Self {
            curve,
            parasitic_pf: spec.parasitic_pf,
            unloaded_sensor_pf: spec.unloaded_sensor_pf,
        })
    }

    /// Back to plain data.
    pub fn to_spec(&self) -> TaxelCalibrationSpec {
        TaxelCalibrationSpec {
            points: bounded_copy(self.curve.points()),
            parasitic_pf: self.parasitic_pf,
            unloaded_sensor_pf: self.unloaded_sensor_pf,
        }
    }
}

/// A validated calibration for the whole pad.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    id: u32,
    taxels: [TaxelCalibration; TAXEL_COUNT],
    temperature_law: TemperatureLaw,
    thresholds: FaultThresholds,
}

impl Default for Calibration {
    /// The article's Table 1 on every taxel, no parasitic capacitance, the article's temperature
    /// law, default thresholds, id 0.
    fn default() -> Self {
        let taxel = TaxelCalibration {
            curve: CalibrationCurve::article_default(),
            parasitic_pf: 0.0,
            unloaded_sensor_pf: None,
        };
        Self {
            id: 0,
            taxels: [taxel.clone(), taxel.clone(), taxel.clone(), taxel],
            temperature_law: TemperatureLaw::article_default(),
            thresholds: FaultThresholds::default(),
        }
    }
}

impl Calibration {
    /// Validates plain calibration data.
    pub fn new(spec: &CalibrationSpec) -> Result<Self, CalibrationError> {
        let temperature_law = TemperatureLaw::new(
            &spec.temperature_points,
            spec.characterised_min_c,
            spec.characterised_max_c,
        )?;
        spec.thresholds.validate()?;
        let [a, b, c, d] = &spec.taxels;
        Ok(Self {
            id: spec.id,
            taxels: [
                TaxelCalibration::new(a, 0)?,
                TaxelCalibration::new(b, 1)?,
                TaxelCalibration::new(c, 2)?,
                TaxelCalibration::new(d, 3)?,
            ],
            temperature_law,
            thresholds: spec.thresholds,
        })
    }

    /// Back to plain data.
    pub fn to_spec(&self) -> CalibrationSpec {
        CalibrationSpec {
            id: self.id,
            taxels: [
                self.taxels[0].to_spec(),
                self.taxels[1].to_spec(),
                self.taxels[2].to_spec(),
                self.taxels[3].to_spec(),
            ],
            temperature_points: bounded_copy(self.temperature_law.points()),
            characterised_min_c: self.temperature_law.characterised_min_c(),
            characterised_max_c: self.temperature_law.characterised_max_c(),
            thresholds: self.thresholds,
        }
    }

    /// The calibration's identifier.
    pub fn id(&self) -> u32 {
        self.id
    }

    /// Per-taxel calibrations in pad order.
    pub fn taxels(&self) -> &[TaxelCalibration; TAXEL_COUNT] {
        &self.taxels
    }

    /// The permittivity law.
    pub fn temperature_law(&self) -> &TemperatureLaw {
        &self.temperature_law
    }

    /// The fault thresholds.
    pub fn thresholds(&self) -> &FaultThresholds {
        &self.thresholds
    }

    /// Replaces one taxel's calibration (validated); `taxel` outside 0..4 is refused.
    pub fn with_taxel(
        mut self,
        taxel: usize,
        spec: &TaxelCalibrationSpec,
        id: u32,
    ) -> Result<Self, CalibrationError> {
        let validated = TaxelCalibration::new(spec, taxel.min(NO_TAXEL as usize) as u8)?;
        let slot = self
            .taxels
            .get_mut(taxel)
            .ok_or(CalibrationError::TooFewPoints { taxel: NO_TAXEL })?;
        *slot = validated;
        self.id = id;
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec_with_points(points: &[CurvePoint]) -> CalibrationSpec {
        let mut spec = CalibrationSpec::default();
        spec.taxels[2].points = Vec::from_iter(points.iter().copied());
        spec
    }

    #[test]
    fn default_round_trips_through_plain_data() {
        let spec = CalibrationSpec::default();
        assert_eq!(Calibration::new(&spec), Ok(Calibration::default()));
    }

    #[test]
    fn refuses_bad_curves_with_typed_errors() {
        let one = [CurvePoint::new(0.0, 0.0)];
        assert_eq!(
            Calibration::new(&spec_with_points(&one)),
            Err(CalibrationError::TooFewPoints { taxel: 2 })
        );
        let offset = [CurvePoint::new(1.0, 0.0), CurvePoint::new(10.0, 0.1)];
        assert_eq!(
            Calibration::new(&spec_with_points(&offset)),
            Err(CalibrationError::DoesNotStartAtOrigin { taxel: 2 })
        );
        let nan = [CurvePoint::new(0.0, 0.0), CurvePoint::new(10.0, f32::NAN)];
        assert_eq!(
            Calibration::new(&spec_with_points(&nan)),
            Err(CalibrationError::NotFinite { taxel: 2 })
        );
        let flat = [
            CurvePoint::new(0.0, 0.0),
            CurvePoint::new(10.0, 0.1),
            CurvePoint::new(20.0, 0.1),
        ];
        assert_eq!(
            Calibration::new(&spec_with_points(&flat)),
            Err(CalibrationError::NotStrictlyIncreasing { taxel: 2, point: 2 })
        );
        let backwards = [
            CurvePoint::new(0.0, 0.0),
            CurvePoint::new(10.0, 0.1),
            CurvePoint::new(5.0, 0.2),
        ];
        assert_eq!(
            Calibration::new(&spec_with_points(&backwards)),
            Err(CalibrationError::NotStrictlyIncreasing { taxel: 2, point: 2 })
        );
    }

    #[test]
    fn refuses_bad_parasitic_law_and_thresholds() {
        let mut spec = CalibrationSpec::default();
        spec.taxels[1].parasitic_pf = -0.1;
        assert_eq!(
            Calibration::new(&spec),
            Err(CalibrationError::ParasiticOutOfRange { taxel: 1 })
        );
        let mut spec = CalibrationSpec::default();
        spec.temperature_points.clear();
        assert_eq!(
            Calibration::new(&spec),
            Err(CalibrationError::InvalidTemperatureLaw)
        );
        let mut spec = CalibrationSpec::default();
        spec.thresholds.dead_band_relative = f32::NAN;
        assert_eq!(
            Calibration::new(&spec),
            Err(CalibrationError::InvalidThresholds)
        );
    }

    #[test]
    fn article_law_is_flat_below_25_and_linear_to_55() {
        let law = TemperatureLaw::article_default();
        assert_eq!(law.permittivity_ratio(5.0), 1.0);
        assert_eq!(law.permittivity_ratio(25.0), 1.0);
        assert!((law.permittivity_ratio(40.0) - (1.0 - 0.0162)).abs() < 1e-6);
        assert!((law.permittivity_ratio(55.0) - 0.9676).abs() < 1e-6);
        assert!((law.permittivity_ratio(80.0) - 0.9676).abs() < 1e-6);
    }
}
