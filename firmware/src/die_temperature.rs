//! The MCU's own temperature sensor as the fallback [`TemperatureSource`] for when the TMP117 on
//! the pad does not answer. It measures the die, not the pad, and far less accurately, but it
//! keeps the model's temperature correction going (the samples are flagged as such).
//!
//! The reference manual (RM0383) puts the F411's sensor on ADC1_IN18 (shared with VBAT), while
//! embassy-stm32 0.6 maps `Temperature` to IN16 for every "stm32f41x" part. Both are read at boot
//! and the plausible one is kept (IN18 preferred).

use core::ops::Range;

use acquisition::TemperatureSource;
use defmt::{info, warn};
use embassy_stm32::adc::{Adc, SampleTime, Temperature, Vbat, VrefInt};
use embassy_stm32::peripherals::ADC1;
use embassy_stm32::Peri;
use embassy_time::Timer;

/// Factory calibration in system memory (STM32F411 datasheet, "Temperature sensor calibration
/// values" and "Internal reference voltage calibration values"), all taken at VDDA = 3.3 V.
const TS_CAL1_ADDRESS: usize = 0x1FFF_7A2C;
const TS_CAL2_ADDRESS: usize = 0x1FFF_7A2E;
const VREFINT_CAL_ADDRESS: usize = 0x1FFF_7A2A;
const TS_CAL1_TEMPERATURE_C: f32 = 30.0;
const TS_CAL2_TEMPERATURE_C: f32 = 110.0;
const CALIBRATION_VDDA_V: f32 = 3.3;
/// Datasheet typical values, used when the factory words are implausible.
const TYPICAL_V25_V: f32 = 0.76;
const TYPICAL_AVG_SLOPE_V_PER_C: f32 = 0.0025;
const TYPICAL_VREFINT_V: f32 = 1.21;
const ADC_FULL_SCALE: f32 = 4095.0;
/// The sensor's specified range; a conversion outside it is a wrong channel or a broken read.
const PLAUSIBLE_DIE_TEMPERATURE_C: Range<f32> = -40.0..125.0;
/// F411 datasheet: the sensor needs at least 10 µs of sampling; 480 cycles at ADCCLK 24 MHz
/// (PCLK2 96 MHz / 4) are 20 µs.
const SAMPLE_TIME: SampleTime = SampleTime::CYCLES480;

/// The die temperature sensor has no usable channel, or gave an implausible value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct DieTemperatureUnavailable;

/// The die temperature sensor on ADC1.
pub struct DieTemperature {
    adc: Adc<'static, ADC1>,
    channel: Option<SensorChannel>,
    calibration: FactoryCalibration,
}

#[derive(Clone, Copy, defmt::Format)]
enum SensorChannel {
    In16,
    In18,
}

impl DieTemperature {
    /// Powers the sensor, waits for it to settle and picks the channel it is on.
    pub async fn new(adc: Peri<'static, ADC1>) -> Self {
        let adc = Adc::new(adc);
        // TSVREFE powers the sensor and VREFINT; VBATE stays clear so IN18 reads the sensor.
        let _ = adc.enable_temperature();
        let _ = adc.enable_vrefint();
        Timer::after_micros(u64::from(
            Temperature::start_time_us().max(VrefInt::start_time_us()),
        ))
        .await;

        let mut sensor = Self {
            adc,
            channel: None,
            calibration: FactoryCalibration::read(),
        };
        let in18_c = sensor.convert_c(SensorChannel::In18);
        let in16_c = sensor.convert_c(SensorChannel::In16);
        sensor.channel = if PLAUSIBLE_DIE_TEMPERATURE_C.contains(&in18_c) {
            Some(SensorChannel::In18)
        } else if PLAUSIBLE_DIE_TEMPERATURE_C.contains(&in16_c) {
            Some(SensorChannel::In16)
        } else {
            None
        };
        match sensor.channel {
            Some(channel) => info!(
                "die temperature on {} (IN18 {} °C, IN16 {} °C)",
                channel, in18_c, in16_c
            ),
            None => warn!(
                "die temperature implausible on both channels (IN18 {} °C, IN16 {} °C)",
                in18_c, in16_c
            ),
        }
        sensor
    }

    fn convert_c(&mut self, channel: SensorChannel) -> f32 {
        let sensor_raw = match channel {
            SensorChannel::In16 => self.adc.blocking_read(&mut Temperature, SAMPLE_TIME),
            SensorChannel::In18 => self.adc.blocking_read(&mut Vbat, SAMPLE_TIME),
        };
        let vrefint_raw = self.adc.blocking_read(&mut VrefInt, SAMPLE_TIME);
        self.calibration.temperature_c(sensor_raw, vrefint_raw)
    }
}

impl TemperatureSource for DieTemperature {
    type Error = DieTemperatureUnavailable;

    /// Two blocking conversions of about 20 µs each; only used while the TMP117 is failing.
    async fn read_temperature_c(&mut self) -> Result<f32, Self::Error> {
        let channel = self.channel.ok_or(DieTemperatureUnavailable)?;
        let temperature_c = self.convert_c(channel);
        if PLAUSIBLE_DIE_TEMPERATURE_C.contains(&temperature_c) {
            Ok(temperature_c)
        } else {
            Err(DieTemperatureUnavailable)
        }
    }
}

/// The factory calibration words that passed a plausibility check.
#[derive(Clone, Copy)]
struct FactoryCalibration {
    ts_cal1: Option<u16>,
    ts_cal2: Option<u16>,
    vrefint_cal: Option<u16>,
}

impl FactoryCalibration {
    fn read() -> Self {
        let plausible = |value: u16, range: Range<u16>| range.contains(&value).then_some(value);
        let ts_cal1 = plausible(read_system_memory_u16(TS_CAL1_ADDRESS), 700..1200);
        let ts_cal2 = plausible(read_system_memory_u16(TS_CAL2_ADDRESS), 800..1500);
        let vrefint_cal = plausible(read_system_memory_u16(VREFINT_CAL_ADDRESS), 1400..1600);
        let (ts_cal1, ts_cal2) = match (ts_cal1, ts_cal2) {
            (Some(low), Some(high)) if high > low => (Some(low), Some(high)),
            _ => (None, None),
        };
        Self {
            ts_cal1,
            ts_cal2,
            vrefint_cal,
        }
    }

    fn vdda_v(&self, vrefint_raw: u16) -> f32 {
        let vrefint_raw = f32::from(vrefint_raw.max(1));
        match self.vrefint_cal {
            Some(vrefint_cal) => CALIBRATION_VDDA_V * f32::from(vrefint_cal) / vrefint_raw,
            None => TYPICAL_VREFINT_V * ADC_FULL_SCALE / vrefint_raw,
        }
    }

    fn temperature_c(&self, sensor_raw: u16, vrefint_raw: u16) -> f32 {
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

#[allow(unsafe_code)]
fn read_system_memory_u16(address: usize) -> u16 {
    // SAFETY: the address is a half-word-aligned location in the always-readable, read-only
    // system memory of the STM32F411 (factory calibration area); embassy-stm32 0.6 exposes no
    // accessor for these words on the F4.
    unsafe { core::ptr::read_volatile(address as *const u16) }
}
