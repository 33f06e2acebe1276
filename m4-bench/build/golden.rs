//! The golden vectors: a pressure x temperature grid of raw FDC1004 readings synthesised from the
//! f64 forward model, the hard cases of model-core's tests, each with its expected flags and
//! every tier's f64 reference pressure, and the hard calibrations (build/hard_calibrations.rs).
//!
//! Expected flags are written by hand per case AND derived by an f64 re-statement of the
//! model's documented rules (thresholds, temperature handling, classification order); the build
//! fails if the two disagree, so a wrong hand-written expectation cannot slip through.

use crate::format::{
    GridRecord, HardCalibration, HardCase, Header, Setup, DESCRIPTION_BYTES, NAME_BYTES,
};
use crate::reference::References;
use model_core::{TaxelFlags, TaxelReading, Tier};

/// Unloaded sensor capacitance C0 at 25 °C, pF.
pub const SENSOR_PF: f64 = 4.5;
/// Parasitic capacitance of the grid's taxel, pF (does not follow the permittivity).
pub const GRID_PARASITIC_PF: f32 = 6.0;
/// CAPDAC setting of the grid's readings (9.375 pF offset).
pub const GRID_CAPDAC: u8 = 3;
/// Grid pressures: 0, 0.5, ... 50 kPa.
pub const GRID_PRESSURES: usize = 101;
/// Grid temperatures: 5, 10, ... 55 °C.
pub const GRID_TEMPERATURES: usize = 11;

/// Number of tiers (model-core's `Tier::ALL`).
const TIER_COUNT: usize = Tier::ALL.len();

/// Largest |on-target - f64 reference| accepted per tier on the grid, kPa (Tier::ALL order).
///
/// The f32 chain (split capacitance, temperature scale, one reciprocal) is good to about 1e-7 in
/// dC/C0, i.e. 4e-5 kPa where the curve is flattest; the Newton inverse adds its own rounding;
/// micromath's ln is about 1e-3 relative above 1 and the fitted B is about 30 kPa. The
/// tolerances leave a margin of several times the errors measured when they were set; the
/// default tier's 0.005 kPa is ten times tighter than its 0.05 kPa target.
pub const GRID_TOLERANCE_KPA: [f64; TIER_COUNT] = [1e-3, 1e-3, 5e-3, 5e-3, 0.1, 5e-3, 5e-3];

/// Relative tolerance of the tiny-change cases for the tiers whose f32 arithmetic keeps relative
/// precision near zero (all but the two saturating ones, whose A / (A - y) rounds to 1).
const TINY_RELATIVE_TOLERANCE: f64 = 0.01;

const CAPDAC_STEP_PF: f64 = 3.125;
const CODES_PER_PF: f64 = 524_288.0;
const SATURATED_HIGH_CODE: i32 = 0x7F_FFFF;
const SATURATED_LOW_CODE: i32 = -0x80_0000;
const OPEN_BELOW_PF: f64 = 1.0;
const SHORTED_BELOW_RELATIVE: f64 = 0.15;
const DEAD_BAND_RELATIVE: f64 = 0.003;
const CHARACTERISED_MIN_C: f64 = 5.0;
const CHARACTERISED_MAX_C: f64 = 55.0;
const REFERENCE_TEMPERATURE_C: f64 = 25.0;
/// Largest step of the measured temperature from the one in use that is applied as measured, °C.
const MAX_PLAUSIBLE_STEP_C: f64 = 2.0;

/// eps_r(T) / eps_r(25 °C): flat at or below 25 °C, linear to -3.24 % at 55 °C.
pub fn permittivity_ratio(temperature_c: f64) -> f64 {
    let temperature_c = temperature_c.clamp(CHARACTERISED_MIN_C, CHARACTERISED_MAX_C);
    if temperature_c <= 25.0 {
        1.0
    } else {
        1.0 - 0.0324 * (temperature_c - 25.0) / 30.0
    }
}

/// The FDC1004 code for a capacitance measured against a CAPDAC setting.
pub fn code_for(capacitance_pf: f64, capdac: u8) -> i32 {
    ((capacitance_pf - f64::from(capdac) * CAPDAC_STEP_PF) * CODES_PER_PF).round() as i32
}

/// Total capacitance of a taxel with parasitic `parasitic_pf` at a pressure and temperature.
pub fn synthesised_pf(
    references: &References,
    parasitic_pf: f32,
    pressure_kpa: f64,
    temperature_c: f64,
) -> f64 {
    f64::from(parasitic_pf)
        + SENSOR_PF
            * (1.0 + references.forward().relative_change_at(pressure_kpa))
            * permittivity_ratio(temperature_c)
}

enum Value {
    Capacitance(f64),
    Fault(TaxelFlags),
}

fn value_of(reading: TaxelReading) -> Value {
    match reading {
        TaxelReading::Raw { code, .. }
            if code == SATURATED_HIGH_CODE || code == SATURATED_LOW_CODE =>
        {
            Value::Fault(TaxelFlags::SATURATED)
        }
        TaxelReading::Raw { code, capdac }
            if (SATURATED_LOW_CODE..=SATURATED_HIGH_CODE).contains(&code) && capdac <= 31 =>
        {
            Value::Capacitance(f64::from(capdac) * CAPDAC_STEP_PF + f64::from(code) / CODES_PER_PF)
        }
        TaxelReading::Raw { .. } => Value::Fault(TaxelFlags::INVALID_INPUT),
        TaxelReading::CapacitancePf(pf) if pf.is_finite() => Value::Capacitance(f64::from(pf)),
        TaxelReading::CapacitancePf(_) => Value::Fault(TaxelFlags::INVALID_INPUT),
        TaxelReading::Unavailable => Value::Fault(TaxelFlags::CONVERTER_ERROR),
    }
}

/// Temperature used and its flags, as the model resolves one reading without a sample time:
/// clamped; a step further than [`MAX_PLAUSIBLE_STEP_C`] from the last valid temperature is
/// flagged implausible and not applied, the last valid temperature is kept (a single reading
/// never confirms a new level); when missing, the last valid one, else the fallback (the
/// tare's), else 25 °C.
fn resolve_temperature(
    measured_c: Option<f32>,
    last_valid_c: Option<f64>,
    fallback_c: Option<f64>,
) -> (f64, TaxelFlags) {
    match measured_c {
        Some(value) if value.is_finite() => {
            let value = f64::from(value);
            let clamped = value.clamp(CHARACTERISED_MIN_C, CHARACTERISED_MAX_C);
            let mut flags = if clamped != value {
                TaxelFlags::TEMPERATURE_OUT_OF_RANGE
            } else {
                TaxelFlags::empty()
            };
            let used = match last_valid_c {
                Some(last) if (clamped - last).abs() > MAX_PLAUSIBLE_STEP_C => {
                    flags |= TaxelFlags::TEMPERATURE_IMPLAUSIBLE;
                    last
                }
                _ => clamped,
            };
            (used, flags)
        }
        _ => (
            last_valid_c
                .or(fallback_c)
                .unwrap_or(REFERENCE_TEMPERATURE_C)
                .clamp(CHARACTERISED_MIN_C, CHARACTERISED_MAX_C),
            TaxelFlags::TEMPERATURE_MISSING,
        ),
    }
}

/// The last valid temperature the model holds after the tare sample set and the warm-up.
fn last_valid_after(setup: &Setup, warm_up_c: Option<f32>) -> Option<f64> {
    let after_tare = setup
        .tare_temperature_c
        .filter(|value| value.is_finite())
        .map(|value| f64::from(value).clamp(CHARACTERISED_MIN_C, CHARACTERISED_MAX_C));
    warm_up_c
        .map(|value| f64::from(value).clamp(CHARACTERISED_MIN_C, CHARACTERISED_MAX_C))
        .or(after_tare)
}

/// The tared state: sensor capacitance C0 and the tare's temperature.
struct Tare {
    sensor_pf: f64,
    temperature_c: f64,
}

fn tare(setup: &Setup) -> Option<Tare> {
    let (temperature_c, _) = resolve_temperature(setup.tare_temperature_c, None, None);
    let Value::Capacitance(capacitance_pf) = value_of(setup.tare_reading) else {
        return None;
    };
    let sensor_pf = capacitance_pf - f64::from(setup.parasitic_pf);
    (capacitance_pf >= 0.0 && sensor_pf >= OPEN_BELOW_PF).then_some(Tare {
        sensor_pf,
        temperature_c,
    })
}

/// Flags and per-tier reference pressures (NaN when the reading is a fault), for a reading after
/// the setup's tare, with `last_valid_c` the last valid temperature the model holds (None for a
/// fresh temperature state).
pub fn expected(
    references: &References,
    setup: &Setup,
    last_valid_c: Option<f64>,
    reading: TaxelReading,
    temperature_c: Option<f32>,
) -> (TaxelFlags, [f64; TIER_COUNT]) {
    let tare = tare(setup);
    // The baseline's temperature is the fallback when no valid temperature was seen.
    let fallback_c = tare.as_ref().map(|tare| tare.temperature_c);
    let (used_c, temperature_flags) = resolve_temperature(temperature_c, last_valid_c, fallback_c);
    let fault = |flags: TaxelFlags| (flags | temperature_flags, [f64::NAN; TIER_COUNT]);
    let capacitance_pf = match value_of(reading) {
        Value::Capacitance(capacitance_pf) => capacitance_pf,
        Value::Fault(flags) => return fault(flags),
    };
    if capacitance_pf < 0.0 {
        return fault(TaxelFlags::SHORTED);
    }
    let sensor_pf = capacitance_pf - f64::from(setup.parasitic_pf);
    if !(sensor_pf >= OPEN_BELOW_PF) {
        return fault(TaxelFlags::OPEN);
    }
    let Some(tare) = tare else {
        return fault(TaxelFlags::NOT_TARED);
    };
    let scale = permittivity_ratio(tare.temperature_c) / permittivity_ratio(used_c);
    let relative_change = sensor_pf * scale / tare.sensor_pf - 1.0;
    let (top_kpa, top_relative) = references.top();
    let constant = |flags: TaxelFlags, pressure_kpa: f64| (flags, [pressure_kpa; TIER_COUNT]);
    let (flags, pressures) = if relative_change < -SHORTED_BELOW_RELATIVE {
        return fault(TaxelFlags::SHORTED);
    } else if relative_change < -DEAD_BAND_RELATIVE {
        constant(TaxelFlags::BELOW_BASELINE, 0.0)
    } else if relative_change <= 0.0 {
        constant(TaxelFlags::empty(), 0.0)
    } else if relative_change > top_relative {
        constant(TaxelFlags::OVER_RANGE, top_kpa)
    } else {
        let mut pressures = [0.0; TIER_COUNT];
        for (slot, tier) in pressures.iter_mut().zip(Tier::ALL) {
            *slot = references.pressure_kpa(tier, relative_change);
        }
        (TaxelFlags::empty(), pressures)
    };
    (flags | temperature_flags, pressures)
}

/// The grid's setup: parasitic 6 pF, tared at 25 °C with the unloaded reading.
pub fn grid_setup(references: &References) -> Setup {
    let unloaded_pf = synthesised_pf(references, GRID_PARASITIC_PF, 0.0, 25.0);
    Setup {
        parasitic_pf: GRID_PARASITIC_PF,
        tare_reading: TaxelReading::Raw {
            code: code_for(unloaded_pf, GRID_CAPDAC),
            capdac: GRID_CAPDAC,
        },
        tare_temperature_c: Some(25.0),
    }
}

/// The 0–50 kPa x 5–55 °C grid.
pub fn grid(references: &References) -> Result<Vec<GridRecord>, String> {
    let setup = grid_setup(references);
    let mut records = Vec::new();
    for temperature_index in 0..GRID_TEMPERATURES {
        let temperature_c = 5.0 + 5.0 * temperature_index as f64;
        for pressure_index in 0..GRID_PRESSURES {
            let pressure_kpa = 0.5 * pressure_index as f64;
            let capacitance_pf =
                synthesised_pf(references, GRID_PARASITIC_PF, pressure_kpa, temperature_c);
            let reading = TaxelReading::Raw {
                code: code_for(capacitance_pf, GRID_CAPDAC),
                capdac: GRID_CAPDAC,
            };
            // The grid converts each reading with a fresh temperature state (no last valid
            // temperature, so no plausibility step), as `checks::GridTaxel` does.
            let (flags, reference_kpa) = expected(
                references,
                &setup,
                None,
                reading,
                Some(temperature_c as f32),
            );
            if flags.is_fault() || reference_kpa.iter().any(|value| !value.is_finite()) {
                return Err(format!(
                    "grid point {pressure_kpa} kPa {temperature_c} °C is a fault: {flags:?}"
                ));
            }
            records.push(GridRecord {
                pressure_kpa: pressure_kpa as f32,
                temperature_c: temperature_c as f32,
                reading,
                reference_kpa,
            });
        }
    }
    Ok(records)
}

struct CaseSpec {
    name: &'static str,
    description: &'static str,
    setup: Setup,
    warm_up_c: Option<f32>,
    reading: TaxelReading,
    temperature_c: Option<f32>,
    flags: TaxelFlags,
    tiny: bool,
}

fn text<const N: usize>(value: &str) -> Result<[u8; N], String> {
    let mut bytes = [0; N];
    if value.len() > N || !value.is_ascii() {
        return Err(format!("{value:?} does not fit {N} ASCII bytes"));
    }
    bytes[..value.len()].copy_from_slice(value.as_bytes());
    Ok(bytes)
}

/// The hard cases, with expected flags checked against the f64 rules.
pub fn hard_cases(references: &References) -> Result<Vec<HardCase>, String> {
    let grid = grid_setup(references);
    let raw = |pressure_kpa: f64, temperature_c: f64| TaxelReading::Raw {
        code: code_for(
            synthesised_pf(references, GRID_PARASITIC_PF, pressure_kpa, temperature_c),
            GRID_CAPDAC,
        ),
        capdac: GRID_CAPDAC,
    };
    let relative = |relative_change: f64| TaxelReading::Raw {
        code: code_for(
            f64::from(GRID_PARASITIC_PF) + SENSOR_PF * (1.0 + relative_change),
            GRID_CAPDAC,
        ),
        capdac: GRID_CAPDAC,
    };
    let plain = Setup {
        parasitic_pf: 0.0,
        tare_reading: TaxelReading::CapacitancePf(SENSOR_PF as f32),
        tare_temperature_c: Some(25.0),
    };
    let base_code = 1_234_567;
    let capdac_31 = Setup {
        parasitic_pf: (31.0 * CAPDAC_STEP_PF + f64::from(base_code) / CODES_PER_PF - SENSOR_PF)
            as f32,
        tare_reading: TaxelReading::Raw {
            code: base_code,
            capdac: 31,
        },
        tare_temperature_c: Some(25.0),
    };
    let cold_tare = Setup {
        tare_reading: raw(0.0, 15.0),
        tare_temperature_c: Some(15.0),
        ..grid
    };
    let untared = Setup {
        tare_reading: TaxelReading::CapacitancePf(0.0),
        ..plain
    };
    let (_, top_relative) = references.top();
    let sensor_ulp_up = f32::from_bits((SENSOR_PF as f32).to_bits() + 1);
    let sensor_ulp_down = f32::from_bits((SENSOR_PF as f32).to_bits() - 1);
    let none = TaxelFlags::empty();
    let case = |name, description, setup, reading, temperature_c, flags| CaseSpec {
        name,
        description,
        setup,
        warm_up_c: None,
        reading,
        temperature_c,
        flags,
        tiny: false,
    };
    let specs = [
        case(
            "unloaded",
            "the tare reading itself at 25 C",
            grid,
            raw(0.0, 25.0),
            Some(25.0),
            none,
        ),
        case(
            "calibration-point-10kpa",
            "dC/C0 = 0.0829 (Table 1) as a capacitance",
            plain,
            TaxelReading::CapacitancePf((SENSOR_PF * 1.0829) as f32),
            Some(25.0),
            none,
        ),
        case(
            "mid-range-25c",
            "27.3 kPa at 25 C, raw code",
            grid,
            raw(27.3, 25.0),
            Some(25.0),
            none,
        ),
        case(
            "just-below-top",
            "dC/C0 = top - 1e-5, raw code",
            grid,
            relative(top_relative - 1e-5),
            Some(25.0),
            none,
        ),
        case(
            "just-above-top",
            "dC/C0 = top + 1e-4: clamped to 50 kPa",
            grid,
            relative(top_relative + 1e-4),
            Some(25.0),
            TaxelFlags::OVER_RANGE,
        ),
        case(
            "far-above-top",
            "3 x C0",
            plain,
            TaxelReading::CapacitancePf(13.5),
            Some(25.0),
            TaxelFlags::OVER_RANGE,
        ),
        case(
            "largest-valid-code",
            "code 0x7FFFFE at CAPDAC 31 (112.9 pF)",
            grid,
            TaxelReading::Raw {
                code: SATURATED_HIGH_CODE - 1,
                capdac: 31,
            },
            Some(25.0),
            TaxelFlags::OVER_RANGE,
        ),
        case(
            "noise-below-baseline",
            "-0.1 % of C0: inside the dead band",
            grid,
            relative(-0.001),
            Some(25.0),
            none,
        ),
        case(
            "drift-below-baseline",
            "-5 % of C0",
            grid,
            relative(-0.05),
            Some(25.0),
            TaxelFlags::BELOW_BASELINE,
        ),
        case(
            "conducting",
            "-30 % of C0 (conduction through the dielectric)",
            grid,
            relative(-0.3),
            Some(25.0),
            TaxelFlags::SHORTED,
        ),
        case(
            "negative-capacitance",
            "-0.8 pF at CAPDAC 0 (concentrated load)",
            grid,
            TaxelReading::Raw {
                code: code_for(-0.8, 0),
                capdac: 0,
            },
            Some(25.0),
            TaxelFlags::SHORTED,
        ),
        case(
            "open-lead",
            "0.2 pF",
            plain,
            TaxelReading::CapacitancePf(0.2),
            Some(25.0),
            TaxelFlags::OPEN,
        ),
        case(
            "open-raw-zero",
            "code 0 at CAPDAC 0 with 6 pF parasitic",
            grid,
            TaxelReading::Raw { code: 0, capdac: 0 },
            Some(25.0),
            TaxelFlags::OPEN,
        ),
        CaseSpec {
            tiny: true,
            ..case(
                "one-code-up-capdac-31",
                "tare at CAPDAC 31, reading 1 code (1.9 aF) above",
                capdac_31,
                TaxelReading::Raw {
                    code: base_code + 1,
                    capdac: 31,
                },
                Some(25.0),
                none,
            )
        },
        case(
            "one-code-down-capdac-31",
            "tare at CAPDAC 31, reading 1 code below",
            capdac_31,
            TaxelReading::Raw {
                code: base_code - 1,
                capdac: 31,
            },
            Some(25.0),
            none,
        ),
        CaseSpec {
            tiny: true,
            ..case(
                "one-ulp-up",
                "4.5 pF + 1 f32 ulp",
                plain,
                TaxelReading::CapacitancePf(sensor_ulp_up),
                Some(25.0),
                none,
            )
        },
        case(
            "one-ulp-down",
            "4.5 pF - 1 f32 ulp",
            plain,
            TaxelReading::CapacitancePf(sensor_ulp_down),
            Some(25.0),
            none,
        ),
        case(
            "subnormal-smallest",
            "smallest positive subnormal pF",
            plain,
            TaxelReading::CapacitancePf(f32::from_bits(1)),
            Some(25.0),
            TaxelFlags::OPEN,
        ),
        case(
            "subnormal-half-min",
            "f32::MIN_POSITIVE / 2 pF",
            plain,
            TaxelReading::CapacitancePf(f32::MIN_POSITIVE / 2.0),
            Some(25.0),
            TaxelFlags::OPEN,
        ),
        case(
            "subnormal-negative",
            "minus the smallest subnormal pF",
            plain,
            TaxelReading::CapacitancePf(-f32::from_bits(1)),
            Some(25.0),
            TaxelFlags::SHORTED,
        ),
        case(
            "saturated-high",
            "code 0x7FFFFF",
            grid,
            TaxelReading::Raw {
                code: SATURATED_HIGH_CODE,
                capdac: GRID_CAPDAC,
            },
            Some(25.0),
            TaxelFlags::SATURATED,
        ),
        case(
            "saturated-low",
            "code -0x800000",
            grid,
            TaxelReading::Raw {
                code: SATURATED_LOW_CODE,
                capdac: GRID_CAPDAC,
            },
            Some(25.0),
            TaxelFlags::SATURATED,
        ),
        case(
            "code-out-of-range",
            "code 2^24",
            grid,
            TaxelReading::Raw {
                code: 1 << 24,
                capdac: 0,
            },
            Some(25.0),
            TaxelFlags::INVALID_INPUT,
        ),
        case(
            "capdac-32",
            "CAPDAC 32",
            grid,
            TaxelReading::Raw {
                code: 0,
                capdac: 32,
            },
            Some(25.0),
            TaxelFlags::INVALID_INPUT,
        ),
        case(
            "capacitance-nan",
            "NaN pF",
            plain,
            TaxelReading::CapacitancePf(f32::NAN),
            Some(25.0),
            TaxelFlags::INVALID_INPUT,
        ),
        case(
            "capacitance-infinite",
            "+inf pF",
            plain,
            TaxelReading::CapacitancePf(f32::INFINITY),
            Some(25.0),
            TaxelFlags::INVALID_INPUT,
        ),
        case(
            "unavailable",
            "no reading this cycle",
            grid,
            TaxelReading::Unavailable,
            Some(25.0),
            TaxelFlags::CONVERTER_ERROR,
        ),
        case(
            "temperature-nan",
            "20 kPa at 25 C, temperature NaN: the tare's is used",
            grid,
            raw(20.0, 25.0),
            Some(f32::NAN),
            TaxelFlags::TEMPERATURE_MISSING,
        ),
        case(
            "temperature-infinite",
            "20 kPa at 25 C, temperature +inf",
            grid,
            raw(20.0, 25.0),
            Some(f32::INFINITY),
            TaxelFlags::TEMPERATURE_MISSING,
        ),
        case(
            "temperature-negative-infinite",
            "20 kPa at 25 C, temperature -inf",
            grid,
            raw(20.0, 25.0),
            Some(f32::NEG_INFINITY),
            TaxelFlags::TEMPERATURE_MISSING,
        ),
        case(
            "temperature-missing",
            "20 kPa at 25 C, no temperature",
            grid,
            raw(20.0, 25.0),
            None,
            TaxelFlags::TEMPERATURE_MISSING,
        ),
        CaseSpec {
            warm_up_c: Some(5.0),
            ..case(
                "temperature-below-range",
                "cooled to 5 C in plausible steps, 20 kPa at 5 C, temperature -40 C: clamped to 5 C",
                grid,
                raw(20.0, 5.0),
                Some(-40.0),
                TaxelFlags::TEMPERATURE_OUT_OF_RANGE,
            )
        },
        CaseSpec {
            warm_up_c: Some(55.0),
            ..case(
                "temperature-above-range",
                "warmed to 55 C in plausible steps, 20 kPa at 55 C, temperature 85 C: clamped to 55 C",
                grid,
                raw(20.0, 55.0),
                Some(85.0),
                TaxelFlags::TEMPERATURE_OUT_OF_RANGE,
            )
        },
        CaseSpec {
            warm_up_c: Some(55.0),
            ..case(
                "warm-unloaded",
                "warmed to 55 C in plausible steps, unloaded at 55 C, corrected: 0 kPa",
                grid,
                raw(0.0, 55.0),
                Some(55.0),
                none,
            )
        },
        case(
            "warm-uncorrected",
            "unloaded at 55 C, converted as 25 C: -3.24 %",
            grid,
            raw(0.0, 55.0),
            Some(25.0),
            TaxelFlags::BELOW_BASELINE,
        ),
        CaseSpec {
            warm_up_c: Some(45.0),
            ..case(
                "tare-15c-read-45c",
                "tare at 15 C, warmed to 45 C in plausible steps, 20 kPa read at 45 C",
                cold_tare,
                raw(20.0, 45.0),
                Some(45.0),
                none,
            )
        },
        case(
            "temperature-jump",
            "tare at 25 C, 20 kPa at 25 C, temperature 55 C at once: implausible, 25 C kept",
            grid,
            raw(20.0, 25.0),
            Some(55.0),
            TaxelFlags::TEMPERATURE_IMPLAUSIBLE,
        ),
        case(
            "not-tared",
            "tare of 0 pF refused, then 5 % above 4.5 pF",
            untared,
            TaxelReading::CapacitancePf((SENSOR_PF * 1.05) as f32),
            Some(25.0),
            TaxelFlags::NOT_TARED,
        ),
    ];
    let mut cases = Vec::new();
    for spec in specs {
        let (flags, reference_kpa) = expected(
            references,
            &spec.setup,
            last_valid_after(&spec.setup, spec.warm_up_c),
            spec.reading,
            spec.temperature_c,
        );
        if flags != spec.flags {
            return Err(format!(
                "hard case {}: written {:?}, the f64 rules give {:?}",
                spec.name, spec.flags, flags
            ));
        }
        let mut tolerance_kpa = GRID_TOLERANCE_KPA;
        if spec.tiny {
            for (tier, tolerance) in Tier::ALL.iter().zip(tolerance_kpa.iter_mut()) {
                if !matches!(tier, Tier::Saturating | Tier::SaturatingMicromath) {
                    let reference = reference_kpa[*tier as usize];
                    if !(reference > 0.0) {
                        return Err(format!(
                            "hard case {}: tiny reference {reference}",
                            spec.name
                        ));
                    }
                    *tolerance = TINY_RELATIVE_TOLERANCE * reference;
                }
            }
        }
        cases.push(HardCase {
            name: text::<NAME_BYTES>(spec.name)?,
            description: text::<DESCRIPTION_BYTES>(spec.description)?,
            setup: spec.setup,
            warm_up_c: spec.warm_up_c,
            reading: spec.reading,
            temperature_c: spec.temperature_c,
            expected_flags: flags.bits(),
            reference_kpa,
            tolerance_kpa,
        });
    }
    Ok(cases)
}

/// The whole file.
pub fn file(references: &References, calibrations: &[HardCalibration]) -> Result<Vec<u8>, String> {
    let grid_records = grid(references)?;
    let cases = hard_cases(references)?;
    let header = Header {
        grid_count: grid_records.len() as u32,
        hard_case_count: cases.len() as u32,
        hard_calibration_count: calibrations.len() as u32,
        grid_setup: grid_setup(references),
        tolerance_kpa: GRID_TOLERANCE_KPA,
    };
    let mut bytes = header.encode().to_vec();
    if Header::decode(&bytes) != Some(header) {
        return Err("header does not survive encoding".into());
    }
    for record in &grid_records {
        let encoded = record.encode();
        if GridRecord::decode(&encoded) != Some(*record) {
            return Err(format!("grid record {record:?} does not survive encoding"));
        }
        bytes.extend_from_slice(&encoded);
    }
    for case in &cases {
        let encoded = case.encode();
        let decoded = HardCase::decode(&encoded);
        // NaN references and temperatures compare unequal: compare the bytes instead.
        if decoded.map(|decoded| decoded.encode()) != Some(encoded) {
            return Err("a hard case does not survive encoding".into());
        }
        bytes.extend_from_slice(&encoded);
    }
    for calibration in calibrations {
        let encoded = calibration.encode();
        if HardCalibration::decode(&encoded) != Some(*calibration) {
            return Err(format!(
                "hard calibration {} does not survive encoding",
                calibration.seed
            ));
        }
        bytes.extend_from_slice(&encoded);
    }
    if bytes.len() != header.file_bytes() {
        return Err("file size does not match its header".into());
    }
    Ok(bytes)
}
