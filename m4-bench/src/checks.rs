//! Correctness on the target: every grid reading and every hard case through model-core, compared
//! with the f64 references of the golden file; results printed over semihosting, one line each.

use cortex_m_semihosting::hprintln;
use model_core::{
    Baseline, Calibration, CalibrationSpec, PadModel, SampleInput, TaxelModel, TaxelReading,
    TemperatureTracker, Tier,
};

use crate::format::{field_text, GridRecord, HardCase, Header, Setup, TIER_COUNT};

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

/// The grid's taxel: its model, baseline and calibration.
pub struct GridTaxel {
    /// Taxel 0's model.
    pub model: TaxelModel,
    /// Its baseline, from the tare.
    pub baseline: Baseline,
    /// The calibration (temperature law, thresholds).
    pub calibration: Calibration,
}

impl GridTaxel {
    /// Tares a pad with the grid's setup and keeps taxel 0.
    pub fn new(setup: &Setup) -> Option<Self> {
        let pad = tared_pad(setup)?;
        Some(Self {
            model: pad.taxels()[0].clone(),
            baseline: pad.baselines()[0]?,
            calibration: pad.calibration().clone(),
        })
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
            let output = taxel.model.convert(
                *tier,
                value,
                Some(&taxel.baseline),
                inverse_ratio,
                thresholds,
            );
            let pressure_kpa = match output.pressure_kpa() {
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
        "case name={} reading={} temperature={:?} expected_flags={:#06x} description={}",
        name,
        ReadingText(case.reading),
        case.temperature_c,
        case.expected_flags,
        field_text(&case.description)
    );
    let Some(mut pad) = tared_pad(&case.setup) else {
        hprintln!("hard case={} result=fail reason=calibration-refused", name);
        return 1;
    };
    let mut misses = 0;
    for (slot, tier) in Tier::ALL.iter().enumerate() {
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
