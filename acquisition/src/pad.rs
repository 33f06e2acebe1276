//! One pad's part of the acquisition loop: its converter, its own temperature sensor if it has
//! one, its model and its recovery. A pad that fails is flagged and recovered on its own: a
//! converter that does not answer is looked for with one register read every back-off interval
//! (cheap for the other pads, quick to recover), and when other pads share the loop, a converter
//! that answers but fails what is costly to retry (an initialisation, a read that waits out the
//! DONE timeout) is retried at intervals that double up to a limit, so a stalled pad costs the
//! others a wait now and then, not one every sample set.

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use fdc1004::{Fdc1004, Rate};
use model_core::{PadModel, SampleInput, TaxelFlags, TaxelReading, TAXEL_COUNT};

use crate::{
    AcquisitionConfig, Clock, Counters, ProcessedSample, StuckDetector, TemperatureOrigin,
    TemperatureSource,
};

/// What the fallback temperature sensor reads above a pad's own sensor, learned while both
/// work.
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

/// When a failed converter is tried again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Backoff {
    /// No initialisation before this time, µs.
    retry_at_us: Option<u64>,
    /// The wait after the next failure, µs (0: the configured first wait).
    next_wait_us: u32,
}

/// One pad: converter, temperature sensor, model, recovery state.
pub struct PadAcquisition<I2C, D, T> {
    converter: Fdc1004<I2C, D>,
    primary_temperature: Option<T>,
    model: PadModel,
    counters: Counters,
    stuck: StuckDetector,
    converter_ready: bool,
    // The next initialisation applies a requested change, so it is no recovery to count.
    reconfiguration_requested: bool,
    backoff: Backoff,
    primary_failing_cycles: Option<u16>,
    fallback_offset: FallbackOffset,
    // The sensor of the last temperature read (None before the first): a switch to the other
    // one is told to the model, which applies the new sensor's level at once.
    last_temperature_sensor: Option<TemperatureOrigin>,
}

/// What one read of a pad did on the bus, for the loop's pacing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ConverterActivity {
    /// The converter's results were waited for and read.
    Read,
    /// It failed or is backing off: nothing paced the loop.
    Idle,
}

impl<I2C, D, T> PadAcquisition<I2C, D, T>
where
    I2C: I2c,
    D: DelayNs,
    T: TemperatureSource,
{
    /// A pad whose converter is initialised on its first read; `primary_temperature` is its
    /// own (or a shared) TMP117, `None` when it has only the fallback.
    pub(crate) fn new(
        converter: Fdc1004<I2C, D>,
        primary_temperature: Option<T>,
        model: PadModel,
        config: &AcquisitionConfig,
    ) -> Self {
        let mut pad = Self {
            converter,
            primary_temperature,
            model,
            counters: Counters::default(),
            stuck: StuckDetector::new(config.stuck_after_cycles),
            converter_ready: false,
            reconfiguration_requested: false,
            backoff: Backoff::default(),
            primary_failing_cycles: None,
            fallback_offset: FallbackOffset {
                offset_c: None,
                cycles_since_check: config.fallback_offset_check_cycles,
            },
            last_temperature_sensor: None,
        };
        if config.tare_sets_at_start > 0 {
            pad.model.start_tare(config.tare_sets_at_start);
        }
        pad
    }

    pub(crate) fn model(&self) -> &PadModel {
        &self.model
    }

    pub(crate) fn model_mut(&mut self) -> &mut PadModel {
        &mut self.model
    }

    pub(crate) fn counters(&self) -> Counters {
        self.counters
    }

    pub(crate) fn rate(&self) -> Rate {
        self.converter.config().rate
    }

    pub(crate) fn has_primary_temperature(&self) -> bool {
        self.primary_temperature.is_some()
    }

    pub(crate) fn fallback_offset_c(&self) -> Option<f32> {
        self.fallback_offset.offset_c
    }

    pub(crate) fn set_rate(&mut self, rate: Rate) {
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

    /// Reads the pad once: (re-)initialise if due, read, check, convert.
    /// `shares_loop`: other pads are read in the same loop (their sets wait while this pad's
    /// converter is retried).
    pub(crate) async fn read<F: TemperatureSource, K: Clock>(
        &mut self,
        pad_index: u8,
        sequence: u32,
        fallback: &mut F,
        clock: &K,
        config: &AcquisitionConfig,
        shares_loop: bool,
    ) -> (ProcessedSample, ConverterActivity) {
        let mut reading_flags = [TaxelFlags::empty(); TAXEL_COUNT];
        let codes = self.read_converter(clock, config, shares_loop).await;
        let activity = if codes.is_some() {
            ConverterActivity::Read
        } else {
            ConverterActivity::Idle
        };
        let readings = match codes {
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
                    if shares_loop {
                        self.back_off(clock, config, true);
                    }
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
        let (temperature_c, temperature_origin) = self.read_temperature(fallback, config).await;
        if temperature_origin == TemperatureOrigin::Fallback {
            for flags in reading_flags.iter_mut() {
                *flags |= TaxelFlags::TEMPERATURE_FALLBACK;
            }
        }
        self.note_temperature_sensor(temperature_origin);
        let timestamp_us = clock.now_us();
        let input = SampleInput {
            readings,
            reading_flags,
            temperature_c,
            time_us: Some(timestamp_us),
        };
        let output = self.model.process(&input);
        let sample = ProcessedSample {
            pad: pad_index,
            sequence,
            timestamp_us,
            input,
            temperature_origin,
            output,
            counters: self.counters,
        };
        (sample, activity)
    }

    async fn read_converter<K: Clock>(
        &mut self,
        clock: &K,
        config: &AcquisitionConfig,
        shares_loop: bool,
    ) -> Option<[i32; TAXEL_COUNT]> {
        if !self.converter_ready {
            if self
                .backoff
                .retry_at_us
                .is_some_and(|retry_at_us| clock.now_us() < retry_at_us)
            {
                return None;
            }
            if self.backoff.retry_at_us.is_some() {
                // After a failed initialisation, look before waiting out a power-up: an
                // unplugged pad then costs the other pads one register read per attempt.
                match self.converter.answers().await {
                    Ok(true) => {}
                    Ok(false) => {
                        Counters::bump(&mut self.counters.converter_check_failures);
                        self.back_off(clock, config, false);
                        return None;
                    }
                    Err(error) => {
                        self.counters.count_converter_error(&error);
                        self.back_off(clock, config, false);
                        return None;
                    }
                }
            }
            if !core::mem::take(&mut self.reconfiguration_requested) {
                if self.counters.converter_inits > 0 {
                    Counters::bump(&mut self.counters.converter_reinits);
                }
                Counters::bump(&mut self.counters.converter_inits);
            }
            if let Err(error) = self.converter.init().await {
                self.counters.count_converter_error(&error);
                self.back_off(clock, config, shares_loop);
                return None;
            }
            self.stuck.reset();
            self.converter_ready = true;
        }
        match self.converter.read_measurements().await {
            Ok(measurements) if measurements.all_zero() => {
                Counters::bump(&mut self.counters.zero_reads);
                self.converter_ready = false;
                // Recovery is a full initialisation (its power-up wait included), which the
                // other pads sharing the loop would pay in every set.
                if shares_loop {
                    self.back_off(clock, config, true);
                }
                None
            }
            Ok(measurements) => {
                self.backoff = Backoff::default();
                Some(measurements.codes.map(|code| code.0))
            }
            Err(error) => {
                // A stalled converter answers and initialises, then makes every read wait out
                // the DONE timeout: retrying it at once would cost the other pads that wait in
                // every set, so it backs off like a converter that does not initialise.
                // With other pads, any failed read is followed by an initialisation they would
                // wait for, so it backs off too.
                if shares_loop || matches!(error, fdc1004::Error::DoneTimeout { .. }) {
                    self.back_off(clock, config, shares_loop);
                }
                self.counters.count_converter_error(&error);
                self.converter_ready = false;
                None
            }
        }
    }

    /// After a failure: the next attempt waits the first back-off interval, or with `escalate`
    /// the current interval, which then doubles up to the configured longest wait.
    fn back_off<K: Clock>(&mut self, clock: &K, config: &AcquisitionConfig, escalate: bool) {
        let current_us = self.backoff.next_wait_us.max(config.reinit_backoff_us);
        let wait_us = if escalate {
            current_us
        } else {
            config.reinit_backoff_us
        };
        let next_wait_us = if escalate {
            current_us
                .saturating_mul(2)
                .min(config.reinit_backoff_max_us.max(config.reinit_backoff_us))
        } else {
            self.backoff.next_wait_us
        };
        self.backoff = Backoff {
            retry_at_us: Some(clock.now_us().saturating_add(u64::from(wait_us))),
            next_wait_us,
        };
    }

    /// Reads the fallback sensor now and then while the primary works, to learn its offset.
    async fn check_fallback_offset<F: TemperatureSource>(
        &mut self,
        fallback: &mut F,
        primary_c: f32,
        config: &AcquisitionConfig,
    ) {
        let interval = config.fallback_offset_check_cycles;
        if interval == 0 {
            return;
        }
        self.fallback_offset.cycles_since_check =
            self.fallback_offset.cycles_since_check.saturating_add(1);
        if self.fallback_offset.cycles_since_check < interval {
            return;
        }
        self.fallback_offset.cycles_since_check = 0;
        if let Ok(fallback_c) = fallback.read_temperature_c().await {
            if fallback_c.is_finite() {
                self.fallback_offset.learn(fallback_c, primary_c);
            }
        }
    }

    /// Tells the model when this set's temperature comes from another sensor than the last one
    /// read: the step between the TMP117 and the die sensor (with its offset) is no glitch, so
    /// the model applies the new sensor's level at once instead of flagging it while it
    /// confirms it. A set without a temperature changes nothing (the model keeps the one in
    /// use; the sensor that answers next is compared with the last that did).
    fn note_temperature_sensor(&mut self, origin: TemperatureOrigin) {
        if origin == TemperatureOrigin::None {
            return;
        }
        if self
            .last_temperature_sensor
            .is_some_and(|last| last != origin)
        {
            self.model.temperature_source_changed();
        }
        self.last_temperature_sensor = Some(origin);
    }

    async fn read_temperature<F: TemperatureSource>(
        &mut self,
        fallback: &mut F,
        config: &AcquisitionConfig,
    ) -> (Option<f32>, TemperatureOrigin) {
        if let Some(primary) = self.primary_temperature.as_mut() {
            let try_primary = match self.primary_failing_cycles {
                None => true,
                Some(cycles) => cycles >= config.primary_temperature_retry_cycles,
            };
            if try_primary {
                match primary.read_temperature_c().await {
                    Ok(temperature_c) if temperature_c.is_finite() => {
                        self.primary_failing_cycles = None;
                        self.check_fallback_offset(fallback, temperature_c, config)
                            .await;
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
        }
        match fallback.read_temperature_c().await {
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
