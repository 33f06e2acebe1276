//! Async `no_std` driver for the TI FDC1004 4-channel capacitance-to-digital converter
//! (datasheet SNOSCY5B), generic over the `embedded-hal-async` I2C bus and delay traits.
//!
//! The tactile pad wires its four taxels to CIN1..CIN4. Measurement `n` is configured as
//! CIN`n` (CHA) against the CAPDAC offset (CHB), all four run in repeat mode, and
//! [`Fdc1004::read_measurements`] returns the four raw 24-bit codes. The model works in the
//! code domain; [`capacitance_pf`] converts a code to picofarads when a human wants to look.
//!
//! Pitfalls reported for this part shape the driver: [`Fdc1004::init`] software-resets the
//! device and reads back every configuration register it writes (the channel order has been
//! seen shifted after an MCU-only reset), waiting for DONE is bounded by a timeout (DONE has
//! been seen to never set), and [`Fdc1004::reinit`] is the recovery path for both.
//!
//! ```no_run
//! # async fn example<I2C, D>(i2c: I2C, delay: D) -> Result<(), fdc1004::Error<I2C::Error>>
//! # where I2C: embedded_hal_async::i2c::I2c, D: embedded_hal_async::delay::DelayNs {
//! use fdc1004::{Config, Fdc1004, Rate};
//!
//! let config = Config::new(Rate::Hz400, [0; 4]);
//! let mut converter = Fdc1004::new(i2c, delay, config);
//! converter.init().await?;
//! let measurements = converter.read_measurements().await?;
//! let cin1_pf = fdc1004::capacitance_pf(measurements.codes[0], 0);
//! # let _ = cin1_pf;
//! # Ok(())
//! # }
//! ```
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;

/// 7-bit I2C address of the FDC1004 (fixed, no address pins).
pub const DEVICE_ADDRESS: u8 = 0x50;

/// Value of the MANUFACTURER_ID register (Texas Instruments).
pub const MANUFACTURER_ID_VALUE: u16 = 0x5449;

/// Value of the DEVICE_ID register.
pub const DEVICE_ID_VALUE: u16 = 0x1004;

/// Largest valid CAPDAC setting (31 x 3.125 pF = 96.875 pF).
pub const CAPDAC_MAX: u8 = 31;

/// Offset added by one CAPDAC step, in picofarads.
pub const CAPDAC_STEP_PF: f32 = 3.125;

/// Result codes per picofarad: the 24-bit result has 19 fractional bits (1 code = 1.907 aF).
pub const CODES_PER_PF: f32 = 524_288.0;

/// Interval between two reads of FDC_CONF while waiting for the DONE bits, in microseconds.
pub const DONE_POLL_INTERVAL_US: u32 = 500;

/// Measurements in one converter cycle: one per taxel, CIN1..CIN4.
pub const MEASUREMENTS_PER_CYCLE: u32 = 4;

/// The DONE timeout as a percentage of one cycle's conversion time ([`Rate::cycle_time_us`]):
/// 250 % leaves 150 % for the tolerance of the converter's internal oscillator, the I2C traffic
/// and the scheduling between two polls, which the wait does not count.
pub const DONE_TIMEOUT_PERCENT_OF_CYCLE: u32 = 250;

/// Wait before the first bus access in [`Fdc1004::init`] unless configured otherwise, in
/// microseconds: the device needs about 5 ms after power-up before it answers.
pub const POWER_UP_DELAY_US: u32 = 5_000;

/// How many times FDC_CONF is read after a software reset before giving up.
pub const RESET_POLL_ATTEMPTS: u32 = 10;

/// Wait before each read of FDC_CONF after a software reset, in microseconds.
pub const RESET_POLL_INTERVAL_US: u32 = 100;

/// Register addresses (pointer values), named as in the datasheet.
pub mod register {
    /// Measurement 1 result, bits 23:8.
    pub const MEAS1_MSB: u8 = 0x00;
    /// Measurement 1 result, bits 7:0 in register bits 15:8.
    pub const MEAS1_LSB: u8 = 0x01;
    /// Measurement 2 result, bits 23:8.
    pub const MEAS2_MSB: u8 = 0x02;
    /// Measurement 2 result, bits 7:0 in register bits 15:8.
    pub const MEAS2_LSB: u8 = 0x03;
    /// Measurement 3 result, bits 23:8.
    pub const MEAS3_MSB: u8 = 0x04;
    /// Measurement 3 result, bits 7:0 in register bits 15:8.
    pub const MEAS3_LSB: u8 = 0x05;
    /// Measurement 4 result, bits 23:8.
    pub const MEAS4_MSB: u8 = 0x06;
    /// Measurement 4 result, bits 7:0 in register bits 15:8.
    pub const MEAS4_LSB: u8 = 0x07;
    /// Measurement 1 configuration (reset 0x1C00).
    pub const CONF_MEAS1: u8 = 0x08;
    /// Measurement 2 configuration (reset 0x1C00).
    pub const CONF_MEAS2: u8 = 0x09;
    /// Measurement 3 configuration (reset 0x1C00).
    pub const CONF_MEAS3: u8 = 0x0A;
    /// Measurement 4 configuration (reset 0x1C00).
    pub const CONF_MEAS4: u8 = 0x0B;
    /// Capacitance-to-digital configuration: reset, rate, repeat, enables, done flags.
    pub const FDC_CONF: u8 = 0x0C;
    /// CIN1 offset calibration.
    pub const OFFSET_CAL_CIN1: u8 = 0x0D;
    /// CIN2 offset calibration.
    pub const OFFSET_CAL_CIN2: u8 = 0x0E;
    /// CIN3 offset calibration.
    pub const OFFSET_CAL_CIN3: u8 = 0x0F;
    /// CIN4 offset calibration.
    pub const OFFSET_CAL_CIN4: u8 = 0x10;
    /// CIN1 gain calibration (reset 0x4000 = gain 1).
    pub const GAIN_CAL_CIN1: u8 = 0x11;
    /// CIN2 gain calibration (reset 0x4000 = gain 1).
    pub const GAIN_CAL_CIN2: u8 = 0x12;
    /// CIN3 gain calibration (reset 0x4000 = gain 1).
    pub const GAIN_CAL_CIN3: u8 = 0x13;
    /// CIN4 gain calibration (reset 0x4000 = gain 1).
    pub const GAIN_CAL_CIN4: u8 = 0x14;
    /// Manufacturer ID, reads 0x5449.
    pub const MANUFACTURER_ID: u8 = 0xFE;
    /// Device ID, reads 0x1004.
    pub const DEVICE_ID: u8 = 0xFF;

    /// MEASn_MSB for measurement 1..4, indexed from 0.
    pub const MEAS_MSB: [u8; 4] = [MEAS1_MSB, MEAS2_MSB, MEAS3_MSB, MEAS4_MSB];
    /// MEASn_LSB for measurement 1..4, indexed from 0.
    pub const MEAS_LSB: [u8; 4] = [MEAS1_LSB, MEAS2_LSB, MEAS3_LSB, MEAS4_LSB];
    /// CONF_MEASn for measurement 1..4, indexed from 0.
    pub const CONF_MEAS: [u8; 4] = [CONF_MEAS1, CONF_MEAS2, CONF_MEAS3, CONF_MEAS4];
}

/// Bit fields of the CONF_MEASn and FDC_CONF registers.
pub mod field {
    /// CONF_MEASn: position of CHA (positive input), bits 15:13.
    pub const CHA_SHIFT: u16 = 13;
    /// CONF_MEASn: position of CHB (negative input), bits 12:10.
    pub const CHB_SHIFT: u16 = 10;
    /// CONF_MEASn: CHB value selecting the CAPDAC as the negative input.
    pub const CHB_CAPDAC: u16 = 0b100;
    /// CONF_MEASn: CHB value disabling the negative input.
    pub const CHB_DISABLED: u16 = 0b111;
    /// CONF_MEASn: position of CAPDAC, bits 9:5.
    pub const CAPDAC_SHIFT: u16 = 5;
    /// CONF_MEASn: mask of CAPDAC after shifting.
    pub const CAPDAC_MASK: u16 = 0b1_1111;

    /// FDC_CONF: software reset, self-clearing (bit 15).
    pub const RST: u16 = 1 << 15;
    /// FDC_CONF: position of RATE, bits 11:10.
    pub const RATE_SHIFT: u16 = 10;
    /// FDC_CONF: repeat measurements (bit 8).
    pub const REPEAT: u16 = 1 << 8;
    /// FDC_CONF: MEAS_1 enable (bit 7); MEAS_2..4 are bits 6..4.
    pub const MEAS_1: u16 = 1 << 7;
    /// FDC_CONF: all four measurement enables, bits 7:4.
    pub const MEAS_ALL: u16 = 0b1111 << 4;
    /// FDC_CONF: DONE_1 (bit 3); DONE_2..4 are bits 2..0. Read-only.
    pub const DONE_1: u16 = 1 << 3;
    /// FDC_CONF: all four DONE flags, bits 3:0. Read-only.
    pub const DONE_ALL: u16 = 0b1111;
}

/// Output data rate of one measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Rate {
    /// 100 samples/s (RATE = 01); about 16 effective bits.
    #[default]
    Hz100,
    /// 200 samples/s (RATE = 10).
    Hz200,
    /// 400 samples/s (RATE = 11).
    Hz400,
}

impl Rate {
    /// Every rate, slowest first.
    pub const ALL: [Rate; 3] = [Rate::Hz100, Rate::Hz200, Rate::Hz400];

    /// The RATE field value (FDC_CONF bits 11:10).
    pub const fn field_value(self) -> u16 {
        match self {
            Rate::Hz100 => 0b01,
            Rate::Hz200 => 0b10,
            Rate::Hz400 => 0b11,
        }
    }

    /// Samples per second of this rate.
    pub const fn samples_per_second(self) -> u32 {
        match self {
            Rate::Hz100 => 100,
            Rate::Hz200 => 200,
            Rate::Hz400 => 400,
        }
    }

    /// Duration of one conversion at this rate, in microseconds (1 / rate).
    pub const fn conversion_time_us(self) -> u32 {
        1_000_000 / self.samples_per_second()
    }

    /// Duration of one cycle of the four measurements in repeat mode, in microseconds
    /// ([`MEASUREMENTS_PER_CYCLE`] conversions: 40 ms at 100 S/s, 10 ms at 400 S/s).
    pub const fn cycle_time_us(self) -> u32 {
        MEASUREMENTS_PER_CYCLE * self.conversion_time_us()
    }

    /// How long to wait for all four DONE flags at this rate, in microseconds:
    /// [`DONE_TIMEOUT_PERCENT_OF_CYCLE`] of [`Rate::cycle_time_us`] (100 ms at 100 S/s, 50 ms
    /// at 200 S/s, 25 ms at 400 S/s). The one place the timeout is derived from the rate.
    pub const fn done_timeout_us(self) -> u32 {
        self.cycle_time_us() / 100 * DONE_TIMEOUT_PERCENT_OF_CYCLE
    }
}

/// A single-ended input pin of the converter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Channel {
    /// Input CIN1 (CHA = 000).
    Cin1,
    /// Input CIN2 (CHA = 001).
    Cin2,
    /// Input CIN3 (CHA = 010).
    Cin3,
    /// Input CIN4 (CHA = 011).
    Cin4,
}

impl Channel {
    /// All inputs in measurement order: measurement `n` reads `ALL[n]`.
    pub const ALL: [Channel; 4] = [Channel::Cin1, Channel::Cin2, Channel::Cin3, Channel::Cin4];

    /// The CHA field value selecting this input.
    pub const fn field_value(self) -> u16 {
        match self {
            Channel::Cin1 => 0b000,
            Channel::Cin2 => 0b001,
            Channel::Cin3 => 0b010,
            Channel::Cin4 => 0b011,
        }
    }
}

/// Converter settings applied by [`Fdc1004::init`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Output data rate of each measurement.
    pub rate: Rate,
    /// CAPDAC setting (0..=31) for measurement `n`, which measures CIN`n+1` against it.
    /// Keep it fixed between calibration and use: changing it shifts every reading.
    pub capdac: [u8; 4],
    /// How long [`Fdc1004::read_measurements`] waits for all four DONE flags, in microseconds.
    /// It must follow the rate: [`Config::new`] and [`Config::with_rate`] set it to
    /// [`Rate::done_timeout_us`]; set it by hand only to test the timeout itself.
    pub done_timeout_us: u32,
    /// Wait before the first bus access in [`Fdc1004::init`], in microseconds
    /// (the device needs about 5 ms after power-up before it answers).
    pub power_up_delay_us: u32,
}

impl Default for Config {
    /// 100 S/s and CAPDAC 0 on every channel, as [`Config::new`] makes them.
    fn default() -> Self {
        Self::new(Rate::Hz100, [0; 4])
    }
}

impl Config {
    /// Settings for `rate` and `capdac`, with the DONE timeout derived from the rate
    /// ([`Rate::done_timeout_us`]) and the [`POWER_UP_DELAY_US`] power-up delay.
    pub const fn new(rate: Rate, capdac: [u8; 4]) -> Self {
        Self {
            rate,
            capdac,
            done_timeout_us: rate.done_timeout_us(),
            power_up_delay_us: POWER_UP_DELAY_US,
        }
    }

    /// The same settings at another rate, the DONE timeout following it
    /// ([`Rate::done_timeout_us`]). Change the rate only this way: a timeout shorter than a
    /// cycle turns every read into [`Error::DoneTimeout`].
    pub const fn with_rate(self, rate: Rate) -> Self {
        Self {
            rate,
            done_timeout_us: rate.done_timeout_us(),
            ..self
        }
    }

    /// Checks the settings: every CAPDAC must be at most [`CAPDAC_MAX`].
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        if self.capdac.iter().all(|&capdac| capdac <= CAPDAC_MAX) {
            Ok(())
        } else {
            Err(InvalidConfig)
        }
    }
}

/// A [`Config`] value was rejected by [`Config::validate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InvalidConfig;

/// Errors of the driver; `E` is the I2C bus error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The I2C transfer failed (NACK, arbitration loss, bus error).
    I2c(E),
    /// The ID registers do not hold the FDC1004 values.
    WrongDeviceId {
        /// Value read from MANUFACTURER_ID (expected 0x5449).
        manufacturer: u16,
        /// Value read from DEVICE_ID (expected 0x1004).
        device: u16,
    },
    /// A configuration register read back differently from what was written.
    ConfigMismatch {
        /// Register address.
        register: u8,
        /// Value written.
        wrote: u16,
        /// Value read back (for FDC_CONF with the DONE bits cleared).
        read: u16,
    },
    /// Not all four DONE flags were set within [`Config::done_timeout_us`].
    DoneTimeout {
        /// DONE_1..4 as last read (FDC_CONF bits 3:0; bit 3 = DONE_1).
        done_bits: u8,
    },
    /// The RST bit did not clear after a software reset.
    ResetTimeout,
    /// The [`Config`] is invalid (a CAPDAC above 31).
    InvalidConfig,
}

/// A raw measurement result: the 24-bit two's-complement code, sign-extended.
///
/// One code is 2^-19 pF (1.907 aF) above the CAPDAC offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RawCode(pub i32);

impl RawCode {
    /// Largest code (0x7FFFFF): the input is saturated high.
    pub const MAX: RawCode = RawCode(0x7F_FFFF);
    /// Smallest code (0x800000 = -8388608): the input is saturated low.
    pub const MIN: RawCode = RawCode(-0x80_0000);

    /// True for the two saturation codes: the input is outside about +-16 pF around the offset.
    pub const fn is_saturated(self) -> bool {
        self.0 == Self::MAX.0 || self.0 == Self::MIN.0
    }
}

/// The four results of one converter cycle; `codes[n]` is measurement `n+1` (input CIN`n+1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Measurements {
    /// Raw codes of measurements 1..4.
    pub codes: [RawCode; 4],
}

impl Measurements {
    /// True when all four codes are zero, a known glitch of this part (not a real reading).
    pub fn all_zero(&self) -> bool {
        self.codes.iter().all(|code| code.0 == 0)
    }

    /// True when at least one code is a saturation code.
    pub fn any_saturated(&self) -> bool {
        self.codes.iter().any(|code| code.is_saturated())
    }
}

/// Assembles a result from the MEASn_MSB and MEASn_LSB register values: MSB bits 15:0 then
/// LSB bits 15:8, a 24-bit two's-complement number. LSB bits 7:0 are ignored.
pub const fn decode_result(msb: u16, lsb: u16) -> RawCode {
    let unsigned_24 = ((msb as u32) << 8) | ((lsb as u32) >> 8);
    // Shift the 24-bit value to the top of an i32 and back to sign-extend it.
    RawCode(((unsigned_24 << 8) as i32) >> 8)
}

/// Capacitance in picofarads measured with CAPDAC `capdac`: code / 2^19 + 3.125 pF x `capdac`.
///
/// Both terms are exact in `f32`, but their sum is rounded: above 64 pF one `f32` step is
/// 2^-17 pF (4 codes), so work in the code domain when single codes matter.
pub fn capacitance_pf(code: RawCode, capdac: u8) -> f32 {
    relative_capacitance_pf(code) + CAPDAC_STEP_PF * capdac as f32
}

/// Capacitance above the CAPDAC offset in picofarads, code / 2^19 (exact in `f32`).
pub fn relative_capacitance_pf(code: RawCode) -> f32 {
    code.0 as f32 / CODES_PER_PF
}

/// CONF_MEASn value measuring `channel` (CHA) against the CAPDAC (CHB = 100) set to `capdac`.
/// `capdac` is masked to its 5 bits; [`Config::validate`] rejects larger values.
pub const fn conf_meas_value(channel: Channel, capdac: u8) -> u16 {
    (channel.field_value() << field::CHA_SHIFT)
        | (field::CHB_CAPDAC << field::CHB_SHIFT)
        | ((capdac as u16 & field::CAPDAC_MASK) << field::CAPDAC_SHIFT)
}

/// FDC_CONF value for repeated measurements 1..4 at `rate`.
pub const fn fdc_conf_value(rate: Rate) -> u16 {
    (rate.field_value() << field::RATE_SHIFT) | field::REPEAT | field::MEAS_ALL
}

/// The FDC1004 on an I2C bus, with a delay source for power-up, reset and DONE polling.
pub struct Fdc1004<I2C, D> {
    i2c: I2C,
    delay: D,
    config: Config,
}

impl<I2C, D> Fdc1004<I2C, D>
where
    I2C: I2c,
    D: DelayNs,
{
    /// Wraps the bus and delay; no bus traffic until [`Fdc1004::init`].
    pub fn new(i2c: I2C, delay: D, config: Config) -> Self {
        Self { i2c, delay, config }
    }

    /// Gives the bus and delay back.
    pub fn release(self) -> (I2C, D) {
        (self.i2c, self.delay)
    }

    /// The settings this driver applies.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Replaces the settings; they reach the converter at the next [`Fdc1004::init`] or
    /// [`Fdc1004::reinit`] (CAPDAC must not change between calibration and use, so nothing is
    /// written behind the caller's back).
    pub fn set_config(&mut self, config: Config) {
        self.config = config;
    }

    /// Brings the converter into repeated measurement of CIN1..CIN4 against their CAPDACs.
    ///
    /// Waits [`Config::power_up_delay_us`], software-resets the device (polling until RST
    /// clears, at most [`RESET_POLL_ATTEMPTS`] reads), checks both ID registers, writes and
    /// reads back CONF_MEAS1..4, then writes FDC_CONF (rate, REPEAT, MEAS_1..4) and reads it
    /// back ignoring the DONE flags.
    pub async fn init(&mut self) -> Result<(), Error<I2C::Error>> {
        self.config
            .validate()
            .map_err(|InvalidConfig| Error::InvalidConfig)?;
        self.delay.delay_us(self.config.power_up_delay_us).await;

        self.software_reset().await?;

        let manufacturer = self.read_register(register::MANUFACTURER_ID).await?;
        let device = self.read_register(register::DEVICE_ID).await?;
        if manufacturer != MANUFACTURER_ID_VALUE || device != DEVICE_ID_VALUE {
            return Err(Error::WrongDeviceId {
                manufacturer,
                device,
            });
        }

        let measurements = Channel::ALL
            .into_iter()
            .zip(register::CONF_MEAS)
            .zip(self.config.capdac);
        for ((channel, address), capdac) in measurements {
            let value = conf_meas_value(channel, capdac);
            self.write_register(address, value).await?;
            let read = self.read_register(address).await?;
            if read != value {
                return Err(Error::ConfigMismatch {
                    register: address,
                    wrote: value,
                    read,
                });
            }
        }

        let value = fdc_conf_value(self.config.rate);
        self.write_register(register::FDC_CONF, value).await?;
        let read = self.read_register(register::FDC_CONF).await? & !field::DONE_ALL;
        if read != value {
            return Err(Error::ConfigMismatch {
                register: register::FDC_CONF,
                wrote: value,
                read,
            });
        }
        Ok(())
    }

    /// Whether an FDC1004 answers with its manufacturer ID: one register read, no wait, for
    /// deciding whether a converter that went missing is worth the full [`Fdc1004::init`]
    /// (with its power-up wait) yet.
    pub async fn answers(&mut self) -> Result<bool, Error<I2C::Error>> {
        Ok(self.read_register(register::MANUFACTURER_ID).await? == MANUFACTURER_ID_VALUE)
    }

    /// Recovery after an error (DONE timeout, all-zero or shifted readings): the full
    /// [`Fdc1004::init`] sequence again, including the power-up wait and software reset.
    pub async fn reinit(&mut self) -> Result<(), Error<I2C::Error>> {
        self.init().await
    }

    /// Waits until DONE_1..4 are all set, then reads the four results (MSB before LSB).
    ///
    /// FDC_CONF is read every [`DONE_POLL_INTERVAL_US`]; after [`Config::done_timeout_us`]
    /// of waiting without all four flags, returns [`Error::DoneTimeout`]. Reading a result
    /// clears its DONE flag (datasheet 8.5.3.4), so the next call waits for new results.
    pub async fn read_measurements(&mut self) -> Result<Measurements, Error<I2C::Error>> {
        self.wait_for_done().await?;
        let mut measurements = Measurements::default();
        let registers = register::MEAS_MSB.into_iter().zip(register::MEAS_LSB);
        for (code, (msb_register, lsb_register)) in measurements.codes.iter_mut().zip(registers) {
            let msb = self.read_register(msb_register).await?;
            let lsb = self.read_register(lsb_register).await?;
            *code = decode_result(msb, lsb);
        }
        Ok(measurements)
    }

    async fn software_reset(&mut self) -> Result<(), Error<I2C::Error>> {
        self.write_register(register::FDC_CONF, field::RST).await?;
        for _ in 0..RESET_POLL_ATTEMPTS {
            self.delay.delay_us(RESET_POLL_INTERVAL_US).await;
            if self.read_register(register::FDC_CONF).await? & field::RST == 0 {
                return Ok(());
            }
        }
        Err(Error::ResetTimeout)
    }

    async fn wait_for_done(&mut self) -> Result<(), Error<I2C::Error>> {
        let mut waited_us: u32 = 0;
        loop {
            let done_bits = self.read_register(register::FDC_CONF).await? & field::DONE_ALL;
            if done_bits == field::DONE_ALL {
                return Ok(());
            }
            if waited_us >= self.config.done_timeout_us {
                return Err(Error::DoneTimeout {
                    done_bits: done_bits as u8,
                });
            }
            let step_us = DONE_POLL_INTERVAL_US.min(self.config.done_timeout_us - waited_us);
            self.delay.delay_us(step_us).await;
            waited_us += step_us;
        }
    }

    async fn read_register(&mut self, address: u8) -> Result<u16, Error<I2C::Error>> {
        let mut buffer = [0u8; 2];
        self.i2c
            .write_read(DEVICE_ADDRESS, &[address], &mut buffer)
            .await
            .map_err(Error::I2c)?;
        Ok(u16::from_be_bytes(buffer))
    }

    async fn write_register(&mut self, address: u8, value: u16) -> Result<(), Error<I2C::Error>> {
        let [high, low] = value.to_be_bytes();
        self.i2c
            .write(DEVICE_ADDRESS, &[address, high, low])
            .await
            .map_err(Error::I2c)
    }
}
