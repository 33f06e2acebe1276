//! The acquisition loop, written against traits so that the firmware and the desktop simulator
//! run the same code: every converter cycle reads the FDC1004 and a temperature source, runs
//! model-core, stamps the result and hands it to a consumer without ever waiting for it.
//!
//! Recovery is part of the loop: a converter error, an all-zero read or a stuck channel flags the
//! affected sample set, counts the event and re-initialises the converter on the next cycle; a
//! temperature sensor that stops answering degrades to the fallback source. Nothing here ever
//! stops the stream.
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

mod counters;
pub mod die_sensor;
pub mod discovery;
pub mod pad_bus;
mod stuck;
mod temperature;
mod timeout_i2c;

pub use counters::Counters;
pub use stuck::StuckDetector;
pub use temperature::TemperatureSource;
pub use timeout_i2c::{TimeoutI2c, TimeoutI2cError};

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use fdc1004::{Fdc1004, Rate};
use model_core::{PadModel, PadOutput, SampleInput, TaxelFlags, TaxelReading, TAXEL_COUNT};

/// A monotonic clock in microseconds.
pub trait Clock {
    /// Microseconds since an arbitrary start; never goes backwards.
    fn now_us(&self) -> u64;
}

/// Where a sample set's temperature came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TemperatureOrigin {
    /// The primary sensor (the TMP117 on the pad).
    Primary,
    /// The fallback sensor (the MCU's internal sensor): flagged, less accurate.
    Fallback,
    /// Neither answered; the model used the last valid temperature.
    None,
}

/// One converter cycle, as read and as converted.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProcessedSample {
    /// Increments every cycle, including cycles that produced only faults; a gap at the
    /// consumer means sets were dropped.
    pub sequence: u32,
    /// When the converter's results were read, µs.
    pub timestamp_us: u64,
    /// The readings handed to the model.
    pub input: SampleInput,
    /// Where the temperature came from.
    pub temperature_origin: TemperatureOrigin,
    /// The model's result.
    pub output: PadOutput,
    /// Counters as of this set.
    pub counters: Counters,
}

/// Tunables of the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AcquisitionConfig {
    /// A channel repeating the same code for this many cycles while another channel moves is
    /// flagged stuck and the converter is re-initialised.
    pub stuck_after_cycles: u16,
    /// While the primary temperature sensor is failing, try it again every this many cycles.
    pub primary_temperature_retry_cycles: u16,
    /// Wait after a failed converter initialisation before the next attempt, µs.
    pub reinit_backoff_us: u32,
    /// Sample sets averaged by the tare taken automatically at start (0 = none).
    pub tare_sets_at_start: u16,
    /// While the primary temperature sensor works, read the fallback every this many cycles to
    /// learn its offset (the MCU die runs warmer than the pad); 0 = never.
    pub fallback_offset_check_cycles: u16,
}

impl Default for AcquisitionConfig {
    fn default() -> Self {
        Self {
            stuck_after_cycles: 50,
            primary_temperature_retry_cycles: 100,
            reinit_backoff_us: 20_000,
            tare_sets_at_start: 16,
            fallback_offset_check_cycles: 100,
        }
    }
}

/// The acquisition loop's state: the converter, the temperature sources, the clock and the model.
pub struct Acquisition<I2C, D, T, F, K> {
    converter: Fdc1004<I2C, D>,
    primary_temperature: T,
    fallback_temperature: F,
    clock: K,
    pad: PadModel,
    config: AcquisitionConfig,
    counters: Counters,
    stuck: StuckDetector,
    sequence: u32,
    converter_ready: bool,
    // The next initialisation applies a requested change, so it is no recovery to count.
    reconfiguration_requested: bool,
    primary_failing_cycles: Option<u16>,
    fallback_offset: FallbackOffset,
    delay_after_failure: D,
}

/// What the fallback temperature sensor reads above the primary one, learned while both work.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct FallbackOffset {
    offset_c: Option<f32>,
    cycles_since_check: u16,
}

impl FallbackOffset {
    /// Weight of a new difference in the running offset.
    const SMOOTHING: f32 = 0.2;

    fn learn(&mut self, fallback_c: f32, primary_c: f32) {
        let difference_c = fallback_c - primary_c;
        self.offset_c = Some(match self.offset_c {
            Some(offset_c) => offset_c + Self::SMOOTHING * (difference_c - offset_c),
            None => difference_c,
        });
    }

    fn correct(&self, fallback_c: f32) -> f32 {
        fallback_c - self.offset_c.unwrap_or(0.0)
    }
}

impl<I2C, D, T, F, K> Acquisition<I2C, D, T, F, K>
where
    I2C: I2c,
    D: DelayNs,
    T: TemperatureSource,
    F: TemperatureSource,
    K: Clock,
{
    /// Assembles the loop. The converter is initialised on the first cycle; `backoff_delay`
    /// waits between failed initialisations.
    pub fn new(
        converter: Fdc1004<I2C, D>,
        primary_temperature: T,
        fallback_temperature: F,
        clock: K,
        pad: PadModel,
        config: AcquisitionConfig,
        backoff_delay: D,
    ) -> Self {
        let mut acquisition = Self {
            converter,
            primary_temperature,
            fallback_temperature,
            clock,
            pad,
            config,
            counters: Counters::default(),
            stuck: StuckDetector::new(config.stuck_after_cycles),
            sequence: 0,
            converter_ready: false,
            reconfiguration_requested: false,
            primary_failing_cycles: None,
            fallback_offset: FallbackOffset {
                offset_c: None,
                cycles_since_check: config.fallback_offset_check_cycles,
            },
            delay_after_failure: backoff_delay,
        };
        if config.tare_sets_at_start > 0 {
            acquisition.pad.start_tare(config.tare_sets_at_start);
        }
        acquisition
    }

    /// The model (tier, calibration, tare) for commands between cycles.
    pub fn pad_mut(&mut self) -> &mut PadModel {
        &mut self.pad
    }

    /// The model.
    pub fn pad(&self) -> &PadModel {
        &self.pad
    }

    /// The counters so far.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// The converter's sample rate.
    pub fn rate(&self) -> Rate {
        self.converter.config().rate
    }

    /// Changes the converter's rate, its DONE timeout following it
    /// ([`fdc1004::Config::with_rate`]). Takes effect through an initialisation on the next
    /// cycle; that one is a requested reconfiguration, not a recovery, so it is not counted in
    /// [`Counters::converter_inits`] (unless the converter was waiting for a recovery anyway).
    pub fn set_rate(&mut self, rate: Rate) {
        if self.rate() == rate {
            // Nothing to apply: the converter keeps running as it is.
            return;
        }
        let config = self.converter.config().with_rate(rate);
        self.converter.set_config(config);
        if self.converter_ready {
            self.reconfiguration_requested = true;
            self.converter_ready = false;
        }
    }

    /// One converter cycle: (re-)initialise if needed, read, check, convert.
    pub async fn cycle(&mut self) -> ProcessedSample {
        let mut reading_flags = [TaxelFlags::empty(); TAXEL_COUNT];
        let readings = match self.read_converter().await {
            Some(codes) => {
                let capdac = self.converter.config().capdac;
                let stuck = self.stuck.update(&codes);
                for (flags, is_stuck) in reading_flags.iter_mut().zip(stuck) {
                    if is_stuck {
                        *flags |= TaxelFlags::STUCK;
                    }
                }
                if stuck.iter().any(|is_stuck| *is_stuck) {
                    Counters::bump(&mut self.counters.stuck_events);
                    self.converter_ready = false;
                }
                let mut readings = [TaxelReading::Unavailable; TAXEL_COUNT];
                for ((reading, code), capdac) in readings.iter_mut().zip(codes).zip(capdac) {
                    *reading = TaxelReading::Raw { code, capdac };
                }
                readings
            }
            None => {
                reading_flags = [TaxelFlags::CONVERTER_ERROR; TAXEL_COUNT];
                [TaxelReading::Unavailable; TAXEL_COUNT]
            }
        };
        let (temperature_c, temperature_origin) = self.read_temperature().await;
        if temperature_origin == TemperatureOrigin::Fallback {
            for flags in reading_flags.iter_mut() {
                *flags |= TaxelFlags::TEMPERATURE_FALLBACK;
            }
        }
        let timestamp_us = self.clock.now_us();
        let input = SampleInput {
            readings,
            reading_flags,
            temperature_c,
            time_us: Some(timestamp_us),
        };
        let output = self.pad.process(&input);
        let sample = ProcessedSample {
            sequence: self.sequence,
            timestamp_us,
            input,
            temperature_origin,
            output,
            counters: self.counters,
        };
        self.sequence = self.sequence.wrapping_add(1);
        sample
    }

    async fn read_converter(&mut self) -> Option<[i32; TAXEL_COUNT]> {
        if !self.converter_ready {
            if !core::mem::take(&mut self.reconfiguration_requested) {
                Counters::bump(&mut self.counters.converter_inits);
            }
            if let Err(error) = self.converter.init().await {
                self.counters.count_converter_error(&error);
                self.delay_after_failure
                    .delay_us(self.config.reinit_backoff_us)
                    .await;
                return None;
            }
            self.stuck.reset();
            self.converter_ready = true;
        }
        match self.converter.read_measurements().await {
            Ok(measurements) if measurements.all_zero() => {
                Counters::bump(&mut self.counters.zero_reads);
                self.converter_ready = false;
                None
            }
            Ok(measurements) => Some(measurements.codes.map(|code| code.0)),
            Err(error) => {
                self.counters.count_converter_error(&error);
                self.converter_ready = false;
                None
            }
        }
    }

    /// Reads the fallback sensor now and then while the primary works, to learn its offset.
    async fn check_fallback_offset(&mut self, primary_c: f32) {
        let interval = self.config.fallback_offset_check_cycles;
        if interval == 0 {
            return;
        }
        self.fallback_offset.cycles_since_check =
            self.fallback_offset.cycles_since_check.saturating_add(1);
        if self.fallback_offset.cycles_since_check < interval {
            return;
        }
        self.fallback_offset.cycles_since_check = 0;
        if let Ok(fallback_c) = self.fallback_temperature.read_temperature_c().await {
            if fallback_c.is_finite() {
                self.fallback_offset.learn(fallback_c, primary_c);
            }
        }
    }

    /// The fallback sensor's learned offset above the primary, °C (None until learned).
    pub fn fallback_offset_c(&self) -> Option<f32> {
        self.fallback_offset.offset_c
    }

    async fn read_temperature(&mut self) -> (Option<f32>, TemperatureOrigin) {
        let try_primary = match self.primary_failing_cycles {
            None => true,
            Some(cycles) => cycles >= self.config.primary_temperature_retry_cycles,
        };
        if try_primary {
            match self.primary_temperature.read_temperature_c().await {
                Ok(temperature_c) if temperature_c.is_finite() => {
                    self.primary_failing_cycles = None;
                    self.check_fallback_offset(temperature_c).await;
                    return (Some(temperature_c), TemperatureOrigin::Primary);
                }
                _ => {
                    Counters::bump(&mut self.counters.temperature_errors);
                    self.primary_failing_cycles = Some(0);
                }
            }
        } else if let Some(cycles) = self.primary_failing_cycles.as_mut() {
            *cycles = cycles.saturating_add(1);
        }
        match self.fallback_temperature.read_temperature_c().await {
            Ok(temperature_c) if temperature_c.is_finite() => (
                Some(self.fallback_offset.correct(temperature_c)),
                TemperatureOrigin::Fallback,
            ),
            _ => {
                Counters::bump(&mut self.counters.temperature_errors);
                (None, TemperatureOrigin::None)
            }
        }
    }
}
