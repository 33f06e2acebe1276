//! What the device application needs from the acquisition loop, so that it can be driven by the
//! real loop (firmware, simulator) and stays testable.

use acquisition::TemperatureSource;
use acquisition::{Acquisition, Clock, Counters, ProcessedSample};
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use model_core::PadModel;
use wire::SampleRate;

use crate::convert::{converter_rate, wire_sample_rate};

/// The acquisition loop as the device application sees it: pads read one by one within a
/// sample set.
#[allow(async_fn_in_trait)]
pub trait DeviceControl {
    /// How many pads are read.
    fn pad_count(&self) -> usize;
    /// Reads one pad for the set under way (`None`: no such pad).
    async fn read_pad(&mut self, pad: usize) -> Option<ProcessedSample>;
    /// Ends the set under way.
    async fn finish_set(&mut self);
    /// A pad's model.
    fn pad(&self, pad: usize) -> Option<&PadModel>;
    /// A pad's model, to change tier, calibration or tare.
    fn pad_mut(&mut self, pad: usize) -> Option<&mut PadModel>;
    /// The converter rate.
    fn sample_rate(&self) -> SampleRate;
    /// Sets the converter rate (its DONE timeout follows it); takes effect on the next cycle.
    fn set_sample_rate(&mut self, rate: SampleRate);
    /// Every pad's counters added up.
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
    fn pad_count(&self) -> usize {
        Acquisition::pad_count(self)
    }

    async fn read_pad(&mut self, pad: usize) -> Option<ProcessedSample> {
        Acquisition::read_pad(self, pad).await
    }

    async fn finish_set(&mut self) {
        Acquisition::finish_set(self).await
    }

    fn pad(&self, pad: usize) -> Option<&PadModel> {
        Acquisition::pad(self, pad)
    }

    fn pad_mut(&mut self, pad: usize) -> Option<&mut PadModel> {
        Acquisition::pad_mut(self, pad)
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
