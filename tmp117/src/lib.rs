//! Async `no_std` driver for the TI TMP117 digital temperature sensor, generic over the
//! `embedded-hal-async` I2C bus. (The application reads temperatures through the acquisition
//! crate's `TemperatureSource`, which this sensor implements there.)
//!
//! The pad uses the temperature to correct the dielectric drift of the taxels. The driver does
//! not change the sensor's power-on configuration (continuous conversion); it checks the
//! device ID and reads TEMP_RESULT, treating the reset value 0x8000 (-256 °C, before the
//! first conversion has finished) as "no data yet" rather than as a temperature.
//!
//! ```no_run
//! # async fn example<I2C: embedded_hal_async::i2c::I2c>(i2c: I2C) -> Result<(), tmp117::Error<I2C::Error>> {
//! use tmp117::{Address, Tmp117};
//!
//! let mut sensor = Tmp117::new(i2c, Address::Gnd);
//! sensor.init().await?;
//! let temperature_c = sensor.read_temperature_c().await?;
//! # let _ = temperature_c;
//! # Ok(())
//! # }
//! ```
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use embedded_hal_async::i2c::I2c;

/// Register addresses (pointer values), named as in the datasheet.
pub mod register {
    /// Temperature result, two's complement, 7.8125 m°C per LSB.
    pub const TEMP_RESULT: u8 = 0x00;
    /// Configuration and status flags.
    pub const CONFIGURATION: u8 = 0x01;
    /// Device ID (bits 11:0) and revision (bits 15:12).
    pub const DEVICE_ID: u8 = 0x0F;
}

/// Bit fields of the CONFIGURATION and DEVICE_ID registers.
pub mod field {
    /// CONFIGURATION: Data_Ready (bit 13), set when a conversion completes, cleared when
    /// CONFIGURATION or TEMP_RESULT is read.
    pub const DATA_READY: u16 = 1 << 13;
    /// DEVICE_ID: mask of the DID field (bits 11:0).
    pub const DID_MASK: u16 = 0x0FFF;
}

/// Value of the DID field of DEVICE_ID.
pub const DEVICE_ID_VALUE: u16 = 0x0117;

/// TEMP_RESULT after reset, before the first conversion is complete (-256 °C).
pub const TEMP_RESULT_NOT_READY: u16 = 0x8000;

/// Degrees Celsius per TEMP_RESULT LSB (7.8125 m°C = 1/128 °C).
pub const CELSIUS_PER_LSB: f32 = 1.0 / 128.0;

/// I2C address, selected by what the ADD0 pin is connected to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Address {
    /// ADD0 to ground: 0x48.
    #[default]
    Gnd,
    /// ADD0 to V+: 0x49.
    Vplus,
    /// ADD0 to SDA: 0x4A.
    Sda,
    /// ADD0 to SCL: 0x4B.
    Scl,
}

impl Address {
    /// The 7-bit I2C address.
    pub const fn seven_bit(self) -> u8 {
        match self {
            Address::Gnd => 0x48,
            Address::Vplus => 0x49,
            Address::Sda => 0x4A,
            Address::Scl => 0x4B,
        }
    }
}

/// Errors of the driver; `E` is the I2C bus error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The I2C transfer failed (NACK, arbitration loss, bus error).
    I2c(E),
    /// DEVICE_ID does not identify a TMP117; holds the whole register value.
    WrongDeviceId(u16),
    /// TEMP_RESULT still holds its reset value: no conversion has finished yet.
    NotReady,
}

/// Converts a TEMP_RESULT value to degrees Celsius; `None` for the reset value 0x8000.
pub fn temperature_c_from_register(temp_result: u16) -> Option<f32> {
    if temp_result == TEMP_RESULT_NOT_READY {
        None
    } else {
        Some(temp_result as i16 as f32 * CELSIUS_PER_LSB)
    }
}

/// A TMP117 on an I2C bus.
pub struct Tmp117<I2C> {
    i2c: I2C,
    address: Address,
}

impl<I2C: I2c> Tmp117<I2C> {
    /// Wraps the bus; no bus traffic until [`Tmp117::init`].
    pub fn new(i2c: I2C, address: Address) -> Self {
        Self { i2c, address }
    }

    /// Gives the bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }

    /// Checks that DEVICE_ID identifies a TMP117 (DID = 0x117, any revision).
    pub async fn init(&mut self) -> Result<(), Error<I2C::Error>> {
        let device_id = self.read_register(register::DEVICE_ID).await?;
        if device_id & field::DID_MASK == DEVICE_ID_VALUE {
            Ok(())
        } else {
            Err(Error::WrongDeviceId(device_id))
        }
    }

    /// Reads TEMP_RESULT in degrees Celsius; [`Error::NotReady`] before the first conversion.
    pub async fn read_temperature_c(&mut self) -> Result<f32, Error<I2C::Error>> {
        let temp_result = self.read_register(register::TEMP_RESULT).await?;
        temperature_c_from_register(temp_result).ok_or(Error::NotReady)
    }

    /// Reads the Data_Ready flag of CONFIGURATION: a conversion finished since the last read
    /// of CONFIGURATION or TEMP_RESULT. Reading clears the flag (and the alert flags).
    pub async fn data_ready(&mut self) -> Result<bool, Error<I2C::Error>> {
        let configuration = self.read_register(register::CONFIGURATION).await?;
        Ok(configuration & field::DATA_READY != 0)
    }

    async fn read_register(&mut self, pointer: u8) -> Result<u16, Error<I2C::Error>> {
        let mut buffer = [0u8; 2];
        self.i2c
            .write_read(self.address.seven_bit(), &[pointer], &mut buffer)
            .await
            .map_err(Error::I2c)?;
        Ok(u16::from_be_bytes(buffer))
    }
}
