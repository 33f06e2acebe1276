//! The temperature sources the acquisition loop reads: anything that measures a temperature in
//! degrees Celsius (the TMP117, the MCU's die sensor, a simulation), without the loop knowing
//! which sensor it is.

use embedded_hal_async::i2c::I2c;
use tmp117::Tmp117;

/// Anything that can measure a temperature in degrees Celsius.
#[allow(async_fn_in_trait)]
pub trait TemperatureSource {
    /// Why a reading failed.
    type Error;

    /// Reads the current temperature in degrees Celsius.
    async fn read_temperature_c(&mut self) -> Result<f32, Self::Error>;
}

impl<I2C: I2c> TemperatureSource for Tmp117<I2C> {
    type Error = tmp117::Error<I2C::Error>;

    async fn read_temperature_c(&mut self) -> Result<f32, Self::Error> {
        Tmp117::read_temperature_c(self).await
    }
}
