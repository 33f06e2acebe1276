//! The acquisition loop, written against traits so that the firmware and the desktop simulator
//! run the same code: every sample set reads each pad's FDC1004 in turn (the converters convert
//! in parallel, in repeat mode) and its temperature source, runs the pad's model-core model and
//! stamps the result for a consumer that never makes the loop wait.
//!
//! Recovery is part of the loop, per pad: a converter error, an all-zero read or a stuck channel
//! flags that pad's sample, counts the event and re-initialises its converter, backing off while
//! it keeps failing; a temperature sensor that stops answering degrades to the fallback source,
//! and the pad's model is told of every switch between the two, so that it applies the new
//! sensor's level at once rather than taking the step between them for a glitch.
//! The other pads keep their rate, and nothing here ever stops the stream.
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

mod counters;
pub mod die_sensor;
pub mod discovery;
mod pad;
pub mod pad_bus;
mod stuck;
mod temperature;
mod timeout_i2c;

pub use counters::Counters;
pub use pad::PadAcquisition;
pub use stuck::StuckDetector;
pub use temperature::TemperatureSource;
pub use timeout_i2c::{TimeoutI2c, TimeoutI2cError};

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use fdc1004::{Fdc1004, Rate};
use heapless::Vec;
use model_core::{PadModel, PadOutput, SampleInput};

use crate::discovery::MAX_PADS;
use crate::pad::ConverterActivity;

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

/// One pad's reading of one sample set, as read and as converted.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProcessedSample {
    /// The pad, in the order the loop reads them (0 = the first).
    pub pad: u8,
    /// The sample set: increments every set, including sets that produced only faults, and is
    /// the same for every pad of a set; a gap at the consumer means sets were dropped.
    pub sequence: u32,
    /// When the converter's results were read, µs.
    pub timestamp_us: u64,
    /// The readings handed to the model.
    pub input: SampleInput,
    /// Where the temperature came from.
    pub temperature_origin: TemperatureOrigin,
    /// The model's result.
    pub output: PadOutput,
    /// The pad's counters as of this set.
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
    /// Wait after a converter failure before the next attempt, µs. With several pads, after a
    /// failure that is costly to retry (an initialisation, a DONE timeout) it doubles with every
    /// further one of the same pad, up to `reinit_backoff_max_us`.
    pub reinit_backoff_us: u32,
    /// Longest wait between two costly attempts on a failing converter, µs.
    pub reinit_backoff_max_us: u32,
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
            reinit_backoff_max_us: 320_000,
            tare_sets_at_start: 16,
            fallback_offset_check_cycles: 100,
        }
    }
}

/// The acquisition loop's state: the pads, the fallback temperature source, the clock.
pub struct Acquisition<I2C, D, T, F, K> {
    pads: Vec<PadAcquisition<I2C, D, T>, MAX_PADS>,
    fallback_temperature: F,
    clock: K,
    config: AcquisitionConfig,
    sequence: u32,
    // Whether any converter was waited for and read in the set under way.
    set_paced: bool,
    delay: D,
    rate: Rate,
}

/// The loop already reads [`MAX_PADS`] pads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TooManyPads;

impl<I2C, D, T, F, K> Acquisition<I2C, D, T, F, K>
where
    I2C: I2c,
    D: DelayNs,
    T: TemperatureSource,
    F: TemperatureSource,
    K: Clock,
{
    /// A loop with no pad yet (see [`Acquisition::add_pad`]); `delay` paces sample sets in
    /// which no converter could be read. Pads are read at `rate` ([`Acquisition::set_rate`]).
    pub fn without_pads(
        fallback_temperature: F,
        clock: K,
        config: AcquisitionConfig,
        delay: D,
        rate: Rate,
    ) -> Self {
        Self {
            pads: Vec::new(),
            fallback_temperature,
            clock,
            config,
            sequence: 0,
            set_paced: false,
            delay,
            rate,
        }
    }

    /// The single-pad loop: one converter, its temperature source, the fallback, the model.
    /// The converter is initialised on the first cycle; `backoff_delay` paces the sets in which
    /// it could not be read.
    pub fn new(
        converter: Fdc1004<I2C, D>,
        primary_temperature: T,
        fallback_temperature: F,
        clock: K,
        pad: PadModel,
        config: AcquisitionConfig,
        backoff_delay: D,
    ) -> Self {
        let rate = converter.config().rate;
        let mut acquisition =
            Self::without_pads(fallback_temperature, clock, config, backoff_delay, rate);
        // Cannot fail: the loop has no pad yet.
        let _ = acquisition.add_pad(converter, Some(primary_temperature), pad);
        acquisition
    }

    /// Adds a pad, read after the ones added before it; its converter is set to the loop's
    /// rate and initialised on its first read.
    pub fn add_pad(
        &mut self,
        mut converter: Fdc1004<I2C, D>,
        primary_temperature: Option<T>,
        model: PadModel,
    ) -> Result<(), TooManyPads> {
        let config = converter.config().with_rate(self.rate);
        converter.set_config(config);
        self.pads
            .push(PadAcquisition::new(
                converter,
                primary_temperature,
                model,
                &self.config,
            ))
            .map_err(|_| TooManyPads)
    }

    /// How many pads the loop reads.
    pub fn pad_count(&self) -> usize {
        self.pads.len()
    }

    /// A pad's model.
    pub fn pad(&self, pad: usize) -> Option<&PadModel> {
        self.pads.get(pad).map(PadAcquisition::model)
    }

    /// A pad's model, for commands between sets (tier, calibration, tare).
    pub fn pad_mut(&mut self, pad: usize) -> Option<&mut PadModel> {
        self.pads.get_mut(pad).map(PadAcquisition::model_mut)
    }

    /// Every pad's model, in order.
    pub fn pads_mut(&mut self) -> impl Iterator<Item = &mut PadModel> {
        self.pads.iter_mut().map(PadAcquisition::model_mut)
    }

    /// Whether a pad has a primary temperature sensor (its own or a shared TMP117).
    pub fn pad_has_primary_temperature(&self, pad: usize) -> bool {
        self.pads
            .get(pad)
            .is_some_and(PadAcquisition::has_primary_temperature)
    }

    /// A pad's counters so far.
    pub fn pad_counters(&self, pad: usize) -> Option<Counters> {
        self.pads.get(pad).map(PadAcquisition::counters)
    }

    /// Every pad's counters added up (each saturating).
    pub fn counters(&self) -> Counters {
        self.pads.iter().fold(Counters::default(), |total, pad| {
            total.plus(&pad.counters())
        })
    }

    /// The converters' sample rate.
    pub fn rate(&self) -> Rate {
        self.rate
    }

    /// Changes every converter's rate, its DONE timeout following it
    /// ([`fdc1004::Config::with_rate`]). Takes effect through an initialisation on the pad's
    /// next read; that one is a requested reconfiguration, not a recovery, so it is not counted
    /// in [`Counters::converter_inits`] (unless the converter was waiting for a recovery anyway).
    pub fn set_rate(&mut self, rate: Rate) {
        self.rate = rate;
        for pad in self.pads.iter_mut() {
            pad.set_rate(rate);
        }
    }

    /// The sample set being read (the sequence number its samples carry).
    pub fn sequence(&self) -> u32 {
        self.sequence
    }

    /// Reads one pad for the set under way; `None` if there is no such pad.
    pub async fn read_pad(&mut self, pad: usize) -> Option<ProcessedSample> {
        let pad_index = u8::try_from(pad).ok()?;
        let shares_loop = self.pads.len() > 1;
        let reader = self.pads.get_mut(pad)?;
        let (sample, activity) = reader
            .read(
                pad_index,
                self.sequence,
                &mut self.fallback_temperature,
                &self.clock,
                &self.config,
                shares_loop,
            )
            .await;
        if activity == ConverterActivity::Read {
            self.set_paced = true;
        }
        Some(sample)
    }

    /// Ends the set under way: the next reads belong to the next set. When no converter was
    /// waited for in this set (every pad failing or backing off, or no pad), waits the first
    /// back-off interval, so a board with no working pad does not spin.
    pub async fn finish_set(&mut self) {
        if !core::mem::take(&mut self.set_paced) {
            self.delay.delay_us(self.config.reinit_backoff_us).await;
        }
        self.sequence = self.sequence.wrapping_add(1);
    }

    /// One sample set of a single-pad loop: reads every pad in turn, ends the set and returns
    /// the first pad's sample (`None` without pads). A multi-pad consumer calls
    /// [`Acquisition::read_pad`] per pad and [`Acquisition::finish_set`] instead, to handle each
    /// pad's sample as soon as it is read.
    pub async fn cycle(&mut self) -> Option<ProcessedSample> {
        let mut first = None;
        for pad in 0..self.pads.len() {
            let sample = self.read_pad(pad).await;
            if first.is_none() {
                first = sample;
            }
        }
        self.finish_set().await;
        first
    }

    /// A pad's learned offset of the fallback sensor above its primary, °C (None until
    /// learned).
    pub fn fallback_offset_c(&self, pad: usize) -> Option<f32> {
        self.pads
            .get(pad)
            .and_then(PadAcquisition::fallback_offset_c)
    }
}
