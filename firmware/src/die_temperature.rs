//! The MCU's own temperature sensor as the fallback [`TemperatureSource`] for when the TMP117 on
//! the pad does not answer. It measures the die, not the pad, and far less accurately, but it
//! keeps the model's temperature correction going (the samples are flagged as such). The
//! conversion is portable (`acquisition::die_sensor`); this is the ADC and system-memory glue.
//!
//! The reference manual (RM0383) puts the F411's sensor on ADC1_IN18 (shared with VBAT), while
//! embassy-stm32 0.6 maps `Temperature` to IN16 for every "stm32f41x" part. Both are read at boot
//! and the plausible one is kept (IN18 preferred).

use acquisition::die_sensor::{
    plausible_channel, DieSensorCalibration, PLAUSIBLE_DIE_TEMPERATURE_C,
};
use acquisition::TemperatureSource;
use defmt::{info, warn};
use embassy_stm32::adc::{Adc, SampleTime, Temperature, Vbat, VrefInt};
use embassy_stm32::peripherals::ADC1;
use embassy_stm32::Peri;
use embassy_time::Timer;

/// Factory calibration words in system memory (STM32F411 datasheet).
const TS_CAL1_ADDRESS: usize = 0x1FFF_7A2C;
const TS_CAL2_ADDRESS: usize = 0x1FFF_7A2E;
const VREFINT_CAL_ADDRESS: usize = 0x1FFF_7A2A;

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
    calibration: DieSensorCalibration,
}

#[derive(Clone, Copy, defmt::Format)]
enum SensorChannel {
    In16,
    In18,
}

impl DieTemperature {
    /// Enables the sensor and VREFINT, waits for them to start, and picks the channel.
    pub async fn new(adc: Peri<'static, ADC1>) -> Self {
        let adc = Adc::new(adc);
        let _ = adc.enable_temperature();
        let _ = adc.enable_vrefint();
        Timer::after_micros(u64::from(
            Temperature::start_time_us().max(VrefInt::start_time_us()),
        ))
        .await;
        let mut sensor = Self {
            adc,
            channel: None,
            calibration: DieSensorCalibration::from_words(
                read_system_memory_u16(TS_CAL1_ADDRESS),
                read_system_memory_u16(TS_CAL2_ADDRESS),
                read_system_memory_u16(VREFINT_CAL_ADDRESS),
            ),
        };
        let in18_c = sensor.convert_c(SensorChannel::In18);
        let in16_c = sensor.convert_c(SensorChannel::In16);
        sensor.channel =
            plausible_channel((SensorChannel::In18, in18_c), (SensorChannel::In16, in16_c));
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

    async fn read_temperature_c(&mut self) -> Result<f32, Self::Error> {
        let channel = self.channel.ok_or(DieTemperatureUnavailable)?;
        let temperature_c = self.convert_c(channel);
        (PLAUSIBLE_DIE_TEMPERATURE_C.contains(&temperature_c))
            .then_some(temperature_c)
            .ok_or(DieTemperatureUnavailable)
    }
}

#[allow(unsafe_code)]
fn read_system_memory_u16(address: usize) -> u16 {
    // SAFETY: the address is a half-word-aligned location in the always-readable, read-only
    // system memory of the STM32F411 (factory calibration area); embassy-stm32 0.6 exposes no
    // accessor for these words on the F4.
    unsafe { core::ptr::read_volatile(address as *const u16) }
}
