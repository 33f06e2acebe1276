//! What the device application needs from the acquisition loop, so that it can be driven by the
//! real loop (firmware, simulator) and stays testable.

use acquisition::{Acquisition, Clock, Counters, ProcessedSample};
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use fdc1004::Rate;
use model_core::PadModel;
use tmp117::TemperatureSource;

/// The acquisition loop as the device application sees it.
#[allow(async_fn_in_trait)]
pub trait DeviceControl {
    /// Runs one converter cycle.
    async fn cycle(&mut self) -> ProcessedSample;
    /// The model.
    fn pad(&self) -> &PadModel;
    /// The model, to change tier, calibration or tare.
    fn pad_mut(&mut self) -> &mut PadModel;
    /// The converter rate, conversions per second.
    fn rate_sps(&self) -> u16;
    /// Sets the converter rate; false if the rate is not 100, 200 or 400.
    fn set_rate_sps(&mut self, rate_sps: u16) -> bool;
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

    fn rate_sps(&self) -> u16 {
        self.rate().samples_per_second() as u16
    }

    fn set_rate_sps(&mut self, rate_sps: u16) -> bool {
        let rate = match rate_sps {
            100 => Rate::Hz100,
            200 => Rate::Hz200,
            400 => Rate::Hz400,
            _ => return false,
        };
        self.set_rate(rate);
        true
    }

    fn counters(&self) -> Counters {
        Acquisition::counters(self)
    }
}
