//! The STM32F4's internal temperature sensor, the fallback temperature source: converting its
//! ADC readings to °C with the factory calibration words (STM32F411 datasheet, "Temperature
//! sensor calibration values" and "Internal reference voltage calibration values", all taken at
//! VDDA = 3.3 V), or with the datasheet's typical values when the words are implausible. Only the
//! ADC and the system-memory reads are the firmware's; this arithmetic is tested on the host.

use core::ops::Range;

/// Temperature of TS_CAL1, °C.
const TS_CAL1_TEMPERATURE_C: f32 = 30.0;
/// Temperature of TS_CAL2, °C.
const TS_CAL2_TEMPERATURE_C: f32 = 110.0;
/// VDDA at which the factory words were taken, V.
const CALIBRATION_VDDA_V: f32 = 3.3;
/// Datasheet typical sensor voltage at 25 °C, V.
const TYPICAL_V25_V: f32 = 0.76;
/// Datasheet typical slope, V/°C.
const TYPICAL_AVG_SLOPE_V_PER_C: f32 = 0.0025;
/// Datasheet typical internal reference, V.
const TYPICAL_VREFINT_V: f32 = 1.21;
/// Full scale of the 12-bit ADC.
const ADC_FULL_SCALE: f32 = 4095.0;

/// The sensor's specified range; a conversion outside it is a wrong channel or a broken read.
pub const PLAUSIBLE_DIE_TEMPERATURE_C: Range<f32> = -40.0..125.0;

/// The factory calibration words, each kept only when plausible.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DieSensorCalibration {
    ts_cal1: Option<u16>,
    ts_cal2: Option<u16>,
    vrefint_cal: Option<u16>,
}

impl DieSensorCalibration {
    /// The calibration from the raw words TS_CAL1, TS_CAL2 and VREFINT_CAL; a word outside its
    /// plausible range (or TS_CAL2 not above TS_CAL1) is replaced by the typical values.
    pub fn from_words(ts_cal1: u16, ts_cal2: u16, vrefint_cal: u16) -> Self {
        let plausible = |value: u16, range: Range<u16>| range.contains(&value).then_some(value);
        let (ts_cal1, ts_cal2) =
            match (plausible(ts_cal1, 700..1200), plausible(ts_cal2, 800..1500)) {
                (Some(low), Some(high)) if high > low => (Some(low), Some(high)),
                _ => (None, None),
            };
        Self {
            ts_cal1,
            ts_cal2,
            vrefint_cal: plausible(vrefint_cal, 1400..1600),
        }
    }

    fn vdda_v(&self, vrefint_raw: u16) -> f32 {
        let vrefint_raw = f32::from(vrefint_raw.max(1));
        match self.vrefint_cal {
            Some(vrefint_cal) => CALIBRATION_VDDA_V * f32::from(vrefint_cal) / vrefint_raw,
            None => TYPICAL_VREFINT_V * ADC_FULL_SCALE / vrefint_raw,
        }
    }

    /// The die temperature, °C, from a sensor conversion and a VREFINT conversion taken together.
    pub fn temperature_c(&self, sensor_raw: u16, vrefint_raw: u16) -> f32 {
        let vdda_v = self.vdda_v(vrefint_raw);
        match (self.ts_cal1, self.ts_cal2) {
            (Some(ts_cal1), Some(ts_cal2)) => {
                let raw_at_calibration_vdda = f32::from(sensor_raw) * vdda_v / CALIBRATION_VDDA_V;
                TS_CAL1_TEMPERATURE_C
                    + (TS_CAL2_TEMPERATURE_C - TS_CAL1_TEMPERATURE_C)
                        * (raw_at_calibration_vdda - f32::from(ts_cal1))
                        / f32::from(ts_cal2 - ts_cal1)
            }
            _ => {
                let sensor_v = f32::from(sensor_raw) * vdda_v / ADC_FULL_SCALE;
                25.0 + (sensor_v - TYPICAL_V25_V) / TYPICAL_AVG_SLOPE_V_PER_C
            }
        }
    }
}

/// Which of two candidate channels to use, given one conversion from each: the first when it
/// is plausible, else the second when it is, else none.
pub fn plausible_channel<C>(first: (C, f32), second: (C, f32)) -> Option<C> {
    if PLAUSIBLE_DIE_TEMPERATURE_C.contains(&first.1) {
        Some(first.0)
    } else if PLAUSIBLE_DIE_TEMPERATURE_C.contains(&second.1) {
        Some(second.0)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factory_words_give_their_own_temperatures() {
        let calibration = DieSensorCalibration::from_words(950, 1200, 1500);
        // VREFINT reads its calibration value: VDDA is 3.3 V, as at the factory.
        assert!((calibration.temperature_c(950, 1500) - 30.0).abs() < 1e-4);
        assert!((calibration.temperature_c(1200, 1500) - 110.0).abs() < 1e-4);
        assert!((calibration.temperature_c(1075, 1500) - 70.0).abs() < 1e-4);
        // At VDDA 3.0 V the same die reads 10 % higher codes, VREFINT too: the same temperature
        // within the rounding of the codes (0.3 LSB of 250 LSB per 80 °C).
        assert!((calibration.temperature_c(1182, 1650) - 70.0).abs() < 0.25);
    }

    #[test]
    fn implausible_words_fall_back_to_the_typical_values() {
        let calibration = DieSensorCalibration::from_words(0xFFFF, 0, 0);
        // 0.76 V at VDDA from the typical VREFINT (1.21 V read as 1502): 25 °C.
        let vrefint_raw = 1502;
        let vdda_v = 1.21 * 4095.0 / f32::from(vrefint_raw);
        let sensor_raw = (0.76 * 4095.0 / vdda_v) as u16;
        let temperature_c = calibration.temperature_c(sensor_raw, vrefint_raw);
        assert!((temperature_c - 25.0).abs() < 0.5, "{temperature_c}");
        assert_eq!(
            DieSensorCalibration::from_words(1200, 950, 1500),
            DieSensorCalibration::from_words(0, 0, 1500),
            "TS_CAL2 must be above TS_CAL1"
        );
    }

    #[test]
    fn the_first_plausible_channel_is_chosen() {
        assert_eq!(
            plausible_channel(("in18", 31.0), ("in16", 200.0)),
            Some("in18")
        );
        assert_eq!(
            plausible_channel(("in18", -300.0), ("in16", 35.0)),
            Some("in16")
        );
        assert_eq!(plausible_channel(("in18", f32::NAN), ("in16", 900.0)), None);
    }
}
