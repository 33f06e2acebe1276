//! What the device application needs from the acquisition loop, so that it can be driven by the
//! real loop (firmware, simulator) and stays testable.

use acquisition::TemperatureSource;
use acquisition::{Acquisition, Clock, Counters, ProcessedSample};
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use model_core::PadModel;
use wire::SampleRate;

use crate::convert::{converter_rate, wire_sample_rate};

/// The acquisition loop as the device application sees it.
#[allow(async_fn_in_trait)]
pub trait DeviceControl {
    /// Runs one converter cycle.
    async fn cycle(&mut self) -> ProcessedSample;
    /// The model.
    fn pad(&self) -> &PadModel;
    /// The model, to change tier, calibration or tare.
    fn pad_mut(&mut self) -> &mut PadModel;
    /// The converter rate.
    fn sample_rate(&self) -> SampleRate;
    /// Sets the converter rate (its DONE timeout follows it); takes effect on the next cycle.
    fn set_sample_rate(&mut self, rate: SampleRate);
    /// The loop's counters.
    fn counters(&self) -> Counters;
}

impl<I2C, D, T, F, K> DeviceControl for Acquisition<I2C, D, T, F, K>
where
    I2C: I2c,
    D: DelayNs,
    T: TemperatureSource,
    F: TemperatureSource,
    K: Clock,
{
    async fn cycle(&mut self) -> ProcessedSample {
        Acquisition::cycle(self).await
    }

    fn pad(&self) -> &PadModel {
        Acquisition::pad(self)
    }

    fn pad_mut(&mut self) -> &mut PadModel {
        Acquisition::pad_mut(self)
    }

    fn sample_rate(&self) -> SampleRate {
        wire_sample_rate(self.rate())
    }

    fn set_sample_rate(&mut self, rate: SampleRate) {
        self.set_rate(converter_rate(rate));
    }

    fn counters(&self) -> Counters {
        Acquisition::counters(self)
    }
}
