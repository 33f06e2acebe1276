//! Correctness on the target: every grid reading, every hard case and every hard calibration
//! through model-core, compared with the f64 references of the golden file; results printed over
//! semihosting, one line each.

use cortex_m_semihosting::hprintln;
use model_core::calibration::MAX_CURVE_POINTS;
use model_core::{
    Baseline, Calibration, CalibrationCurve, CalibrationSpec, CurvePoint, InverseCurve, PadModel,
    SampleInput, TaxelCalibration, TaxelInverses, TaxelModel, TaxelReading, TemperatureTracker,
    Tier,
};

use crate::format::{
    field_text, GridRecord, HardCalibration, HardCase, Header, Setup, CALIBRATION_POINTS_MAX,
    TIER_COUNT,
};

/// Step of a warm-up, °C: well inside the model's plausible step between two sample sets.
pub const WARM_UP_STEP_C: f32 = 1.0;

/// A calibration with the article's curve on every taxel and the setup's parasitic capacitance.
pub fn calibration_for(setup: &Setup) -> Option<Calibration> {
    let mut spec = CalibrationSpec::default();
    for taxel in spec.taxels.iter_mut() {
        taxel.parasitic_pf = setup.parasitic_pf;
    }
    Calibration::new(&spec).ok()
}

/// A pad tared (one sample set, the firmware's path) with the setup's unloaded reading.
pub fn tared_pad(setup: &Setup) -> Option<PadModel> {
    let mut pad = PadModel::new(calibration_for(setup)?);
    pad.start_tare(1);
    pad.process(&SampleInput::new(
        [setup.tare_reading; 4],
        setup.tare_temperature_c,
    ));
    Some(pad)
}

/// Brings a tared pad's temperature to `target_c` as a real pad warms or cools: unloaded sample
/// sets (the tare reading) with the temperature moving [`WARM_UP_STEP_C`] per set.
pub fn warm_up(pad: &mut PadModel, setup: &Setup, target_c: f32) {
    let mut temperature_c = pad.last_valid_temperature_c().unwrap_or(target_c);
    // At most 200 sets: the characterised range is 50 °C wide.
    for _ in 0..200 {
        temperature_c = if (target_c - temperature_c).abs() <= WARM_UP_STEP_C {
            target_c
        } else {
            temperature_c + (target_c - temperature_c).clamp(-WARM_UP_STEP_C, WARM_UP_STEP_C)
        };
        pad.process(&SampleInput::new(
            [setup.tare_reading; 4],
            Some(temperature_c),
        ));
        if temperature_c == target_c {
            break;
        }
    }
}

/// The grid's taxel: its models, baseline and calibration.
pub struct GridTaxel {
    /// Taxel 0's model for each tier, in [`Tier::ALL`] order (`None` where its curve lacks the
    /// tier).
    pub models: [Option<TaxelModel>; TIER_COUNT],
    /// Every tier of taxel 0 at once (the inverse-alone counts).
    pub inverses: TaxelInverses,
    /// Its baseline, from the tare.
    pub baseline: Baseline,
    /// The calibration (temperature law, thresholds).
    pub calibration: Calibration,
}

impl GridTaxel {
    /// Tares a pad with the grid's setup and keeps taxel 0.
    pub fn new(setup: &Setup) -> Option<Self> {
        let pad = tared_pad(setup)?;
        let taxel_calibration = &pad.calibration().taxels()[0];
        Some(Self {
            models: Tier::ALL.map(|tier| TaxelModel::with_tier(taxel_calibration, tier)),
            inverses: TaxelInverses::new(taxel_calibration.curve()),
            baseline: pad.baselines()[0]?,
            calibration: pad.calibration().clone(),
        })
    }

    /// Taxel 0's calibration.
    pub fn taxel_calibration(&self) -> &TaxelCalibration {
        &self.calibration.taxels()[0]
    }

    /// Taxel 0's model for a tier.
    pub fn model(&self, tier: Tier) -> Option<&TaxelModel> {
        self.models.get(tier as usize)?.as_ref()
    }

    /// eps(25 °C) / eps(T) for a grid temperature, as the pad resolves it.
    pub fn inverse_permittivity_ratio(&self, temperature_c: f32) -> f32 {
        let used = TemperatureTracker::default().resolve(
            Some(temperature_c),
            Some(self.baseline.temperature_c()),
            self.calibration.temperature_law(),
        );
        1.0 / used.permittivity_ratio
    }
}

/// Reads grid record `index`.
pub fn grid_record(golden: &[u8], header: &Header, index: usize) -> Option<GridRecord> {
    GridRecord::decode(golden.get(header.grid_offset(index)..)?)
}

#[derive(Clone, Copy, Default)]
struct Statistics {
    count: u32,
    max: f64,
    sum_of_squares: f64,
    worst_pressure_kpa: f32,
    worst_temperature_c: f32,
}

impl Statistics {
    fn add(&mut self, error: f64, record: &GridRecord) {
        self.count += 1;
        self.sum_of_squares += error * error;
        // NaN compares false and would hide: count it as infinitely wrong.
        let error = if error.is_nan() { f64::INFINITY } else { error };
        if error > self.max || self.count == 1 {
            self.max = error;
            self.worst_pressure_kpa = record.pressure_kpa;
            self.worst_temperature_c = record.temperature_c;
        }
    }

    fn rms(&self) -> f64 {
        libm::sqrt(self.sum_of_squares / f64::from(self.count.max(1)))
    }
}

/// Checks every grid record with every tier; returns the number of misses.
pub fn grid(golden: &[u8], header: &Header, taxel: &GridTaxel) -> u32 {
    let mut numerical = [Statistics::default(); TIER_COUNT];
    let mut from_reference_curve = [Statistics::default(); TIER_COUNT];
    let mut faults = [0u32; TIER_COUNT];
    let thresholds = taxel.calibration.thresholds();
    for index in 0..header.grid_count as usize {
        let Some(record) = grid_record(golden, header, index) else {
            hprintln!("error: grid record {} unreadable", index);
            return 1;
        };
        let inverse_ratio = taxel.inverse_permittivity_ratio(record.temperature_c);
        let value = record.reading.value();
        for (slot, tier) in Tier::ALL.iter().enumerate() {
            let output = taxel.model(*tier).map(|model| {
                model.convert(
                    taxel.taxel_calibration(),
                    value,
                    Some(&taxel.baseline),
                    inverse_ratio,
                    thresholds,
                )
            });
            let pressure_kpa = match output.and_then(|output| output.pressure_kpa()) {
                Some(pressure_kpa) => f64::from(pressure_kpa),
                None => {
                    faults[slot] += 1;
                    f64::NAN
                }
            };
            numerical[slot].add(
                libm::fabs(pressure_kpa - record.reference_kpa[slot]),
                &record,
            );
            let reference_curve_kpa = record.reference_kpa[Tier::MonotoneCubic as usize];
            from_reference_curve[slot].add(libm::fabs(pressure_kpa - reference_curve_kpa), &record);
        }
    }
    let mut misses = 0;
    for (slot, tier) in Tier::ALL.iter().enumerate() {
        let statistics = &numerical[slot];
        let curve = &from_reference_curve[slot];
        let pass = statistics.max <= header.tolerance_kpa[slot] && faults[slot] == 0;
        misses += u32::from(!pass);
        hprintln!(
            "grid tier={} points={} faults={} max_error_kpa={:.3e} rms_error_kpa={:.3e} worst_at_kpa={} worst_at_c={} tolerance_kpa={:.1e} max_from_reference_curve_kpa={:.4e} rms_from_reference_curve_kpa={:.4e} result={}",
            tier.name(),
            statistics.count,
            faults[slot],
            statistics.max,
            statistics.rms(),
            statistics.worst_pressure_kpa,
            statistics.worst_temperature_c,
            header.tolerance_kpa[slot],
            curve.max,
            curve.rms(),
            if pass { "pass" } else { "fail" }
        );
    }
    misses
}

struct ReadingText(TaxelReading);

impl core::fmt::Display for ReadingText {
    fn fmt(&self, formatter: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            TaxelReading::Raw { code, capdac } => write!(formatter, "raw:{code}@{capdac}"),
            TaxelReading::CapacitancePf(pf) => write!(formatter, "pf:{pf:e}"),
            TaxelReading::Unavailable => write!(formatter, "unavailable"),
        }
    }
}

struct OptionalKpa(Option<f64>);

impl core::fmt::Display for OptionalKpa {
    fn fmt(&self, formatter: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Some(value) => write!(formatter, "{value:.6e}"),
            None => write!(formatter, "none"),
        }
    }
}

/// Runs one hard case with every tier; returns the number of misses.
fn hard_case(case: &HardCase) -> u32 {
    let name = field_text(&case.name);
    hprintln!(
        "case name={} reading={} temperature={:?} warm_up={:?} expected_flags={:#06x} description={}",
        name,
        ReadingText(case.reading),
        case.temperature_c,
        case.warm_up_c,
        case.expected_flags,
        field_text(&case.description)
    );
    let Some(mut prepared) = tared_pad(&case.setup) else {
        hprintln!("hard case={} result=fail reason=calibration-refused", name);
        return 1;
    };
    if let Some(target_c) = case.warm_up_c {
        warm_up(&mut prepared, &case.setup, target_c);
    }
    let mut misses = 0;
    for (slot, tier) in Tier::ALL.iter().enumerate() {
        // Each tier from the same state: a reading moves the pad's temperature state.
        let mut pad = prepared.clone();
        if pad.set_tier(*tier).is_err() {
            hprintln!(
                "hard case={} tier={} result=fail reason=tier-unavailable",
                name,
                tier.name()
            );
            misses += 1;
            continue;
        }
        let output = pad
            .process(&SampleInput::new([case.reading; 4], case.temperature_c))
            .taxels[0];
        let pressure_kpa = output.pressure_kpa().map(f64::from);
        let reference_kpa = case.reference_kpa[slot];
        let reference = (!reference_kpa.is_nan()).then_some(reference_kpa);
        let tolerance_kpa = case.tolerance_kpa[slot];
        let pressure_ok = match (pressure_kpa, reference) {
            (None, None) => true,
            (Some(got), Some(want)) => libm::fabs(got - want) <= tolerance_kpa,
            _ => false,
        };
        let pass = pressure_ok && output.flags().bits() == case.expected_flags;
        misses += u32::from(!pass);
        hprintln!(
            "hard case={} tier={} flags={:#06x} expected_flags={:#06x} pressure_kpa={} reference_kpa={} tolerance_kpa={:.1e} result={}",
            name,
            tier.name(),
            output.flags().bits(),
            case.expected_flags,
            OptionalKpa(pressure_kpa),
            OptionalKpa(reference),
            tolerance_kpa,
            if pass { "pass" } else { "fail" }
        );
    }
    misses
}

/// Runs every hard case; returns the number of misses.
pub fn hard_cases(golden: &[u8], header: &Header) -> u32 {
    let mut misses = 0;
    for index in 0..header.hard_case_count as usize {
        let case = golden
            .get(header.hard_case_offset(index)..)
            .and_then(HardCase::decode);
        match case {
            Some(case) => misses += hard_case(&case),
            None => {
                hprintln!("error: hard case {} unreadable", index);
                misses += 1;
            }
        }
    }
    misses
}

/// Checks one hard calibration: the curve is accepted, and the default tier's inverse of every
/// probe is finite, within 0 ..= top and within the reference's accepted interval. Returns
/// (probes checked, misses).
fn hard_calibration(calibration: &HardCalibration) -> (u32, u32) {
    let shape = field_text(&calibration.shape);
    let mut points = [CurvePoint::new(0.0, 0.0); CALIBRATION_POINTS_MAX];
    let given = calibration.points();
    for (slot, (pressure_kpa, relative_change)) in points.iter_mut().zip(given) {
        *slot = CurvePoint::new(*pressure_kpa, *relative_change);
    }
    let count = given.len().min(MAX_CURVE_POINTS);
    let curve = match CalibrationCurve::new(&points[..count], 0) {
        Ok(curve) => curve,
        Err(error) => {
            hprintln!(
                "calibration seed={} shape={} points={} probes=0 result=fail reason={:?}",
                calibration.seed,
                shape,
                given.len(),
                error
            );
            return (0, 1);
        }
    };
    let inverses = TaxelInverses::new(&curve);
    let cubic = inverses.monotone_cubic();
    let top_kpa = f64::from(curve.top().pressure_kpa);
    let (mut misses, mut checked) = (0u32, 0u32);
    // Smallest distance of an answer from the nearer end of its accepted interval (negative:
    // outside), and the largest distance from the reference pressure itself.
    let (mut margin_kpa, mut deviation_kpa) = (f64::INFINITY, 0.0f64);
    for probe in calibration.probes() {
        checked += 1;
        let got_kpa = f64::from(cubic.pressure_kpa(probe.relative_change));
        let margin = (got_kpa - probe.lower_kpa).min(probe.upper_kpa - got_kpa);
        let pass = got_kpa.is_finite() && (0.0..=top_kpa).contains(&got_kpa) && margin >= 0.0;
        margin_kpa = margin_kpa.min(if got_kpa.is_finite() {
            margin
        } else {
            f64::NEG_INFINITY
        });
        deviation_kpa = deviation_kpa.max(libm::fabs(got_kpa - probe.reference_kpa));
        if !pass {
            misses += 1;
            hprintln!(
                "calibration-miss seed={} relative_change={:e} pressure_kpa={:e} reference_kpa={:e} lower_kpa={:e} upper_kpa={:e}",
                calibration.seed,
                probe.relative_change,
                got_kpa,
                probe.reference_kpa,
                probe.lower_kpa,
                probe.upper_kpa
            );
        }
    }
    hprintln!(
        "calibration seed={} shape={} points={} probes={} min_margin_kpa={:.3e} max_from_reference_kpa={:.3e} misses={} result={}",
        calibration.seed,
        shape,
        given.len(),
        checked,
        margin_kpa,
        deviation_kpa,
        misses,
        if misses == 0 { "pass" } else { "fail" }
    );
    (checked, misses)
}

/// Runs every hard calibration; returns the number of misses (probes outside their interval,
/// curves refused, records unreadable).
pub fn hard_calibrations(golden: &[u8], header: &Header) -> u32 {
    let (mut probes, mut misses, mut failed_curves) = (0u32, 0u32, 0u32);
    for index in 0..header.hard_calibration_count as usize {
        let calibration = golden
            .get(header.hard_calibration_offset(index)..)
            .and_then(HardCalibration::decode);
        let Some(calibration) = calibration else {
            hprintln!("error: hard calibration {} unreadable", index);
            misses += 1;
            failed_curves += 1;
            continue;
        };
        let (checked, missed) = hard_calibration(&calibration);
        probes += checked;
        misses += missed;
        failed_curves += u32::from(missed > 0);
    }
    hprintln!(
        "calibrations curves={} probes={} failed_curves={} misses={} result={}",
        header.hard_calibration_count,
        probes,
        failed_curves,
        misses,
        if misses == 0 { "pass" } else { "fail" }
    );
    misses
}
