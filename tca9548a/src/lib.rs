//! Async `no_std` driver for the TI TCA9548A 8-channel I2C multiplexer (datasheet SCPS207),
//! generic over the `embedded-hal-async` I2C bus.
//!
//! The FDC1004 has a fixed I2C address (0x50), so the pad firmware reaches up to eight pads
//! through one TCA9548A, one pad per downstream channel: select the pad's channel, then talk
//! to the FDC1004 behind it at 0x50 on the same bus. [`Tca9548a::select`] therefore enables
//! exactly one channel; with two enabled, two FDC1004s would answer at the same address.
//!
//! The mux has a single 8-bit control register and no register pointer: writing one byte sets
//! the enabled channels (bit n = channel n, several at once allowed, 0 = all off) and reading
//! one byte returns it. After power-on or a reset all channels are off. A new selection takes
//! effect at the STOP that ends the write, so every access here is a transaction of its own and
//! the downstream device is addressed only after it.
//!
//! The driver keeps no copy of the selection: every call goes to the bus, so nothing goes stale
//! when the mux is reset behind its back, and a driver made for a single access (for example
//! over `&mut` to the bus) costs nothing. On a bus shared between tasks, hold the bus (or the
//! lock around it) from the selection to the end of the downstream transfer, or another task
//! may select another channel in between.
//!
//! The driver takes no RESET pin. Its effect (all channels off) is what
//! [`Tca9548a::disable_all`] does over the bus; pulsing RESET is for recovering a bus held low
//! by a downstream device, which is board-level recovery that the firmware does with its own
//! GPIO (and on boards where RESET is tied high there is nothing to drive). A pin would add a
//! type parameter and a second error type to every user for that rare path.
//!
//! The example selects the pad on channel 3 of the mux at 0x71 with read-back, then reads the
//! DEVICE_ID register (0xFF) of the FDC1004 behind it; the mock bus checks every byte.
//!
//! ```
//! use embassy_futures::block_on;
//! use embedded_hal_async::i2c::{ErrorKind, I2c};
//! use embedded_hal_mock::eh1::i2c::{Mock, Transaction};
//! use tca9548a::{Address, Channel, Error, Tca9548a};
//!
//! const FDC1004_ADDRESS: u8 = 0x50;
//! const FDC1004_DEVICE_ID: u8 = 0xFF;
//!
//! let mut bus = Mock::new(&[
//!     // One data byte to the mux, no register address: bit 3 = channel 3.
//!     Transaction::write(0x71, vec![0b0000_1000]),
//!     Transaction::read(0x71, vec![0b0000_1000]),
//!     Transaction::write_read(FDC1004_ADDRESS, vec![FDC1004_DEVICE_ID], vec![0x10, 0x04]),
//! ]);
//! block_on(async {
//!     // A2 and A1 to ground, A0 high.
//!     let mut mux = Tca9548a::new(&mut bus, Address::from_pins(false, false, true));
//!     mux.select_verified(Channel::Ch3).await?;
//!     let bus = mux.release();
//!     let mut device_id = [0u8; 2];
//!     bus.write_read(FDC1004_ADDRESS, &[FDC1004_DEVICE_ID], &mut device_id)
//!         .await
//!         .map_err(Error::I2c)?;
//!     assert_eq!(u16::from_be_bytes(device_id), 0x1004);
//!     Ok::<(), Error<ErrorKind>>(())
//! })?;
//! bus.done();
//! # Ok::<(), Error<ErrorKind>>(())
//! ```
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use embedded_hal_async::i2c::{self, ErrorKind, I2c};

/// Lowest 7-bit address (A2 = A1 = A0 = low): the fixed part 1110 then the three pins.
pub const ADDRESS_BASE: u8 = 0x70;

/// Highest 7-bit address (A2 = A1 = A0 = high).
pub const ADDRESS_LAST: u8 = 0x77;

/// Number of downstream channels (SC0/SD0 to SC7/SD7).
pub const CHANNEL_COUNT: usize = 8;

/// 7-bit I2C address of a TCA9548A, 0x70 | A2 A1 A0; only 0x70..=0x77 can be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Address(u8);

impl Default for Address {
    /// All three address pins to ground: 0x70.
    fn default() -> Self {
        Self(ADDRESS_BASE)
    }
}

impl Address {
    /// The address set by the A2, A1, A0 pins (`true` = pin high), 0x70 | A2 A1 A0.
    pub const fn from_pins(a2: bool, a1: bool, a0: bool) -> Self {
        Self(ADDRESS_BASE | ((a2 as u8) << 2) | ((a1 as u8) << 1) | (a0 as u8))
    }

    /// The address for a 7-bit value; `None` outside 0x70..=0x77.
    pub const fn new(seven_bit: u8) -> Option<Self> {
        if seven_bit >= ADDRESS_BASE && seven_bit <= ADDRESS_LAST {
            Some(Self(seven_bit))
        } else {
            None
        }
    }

    /// The 7-bit I2C address.
    pub const fn seven_bit(self) -> u8 {
        self.0
    }

    /// The pin levels `(a2, a1, a0)` that set this address (`true` = high).
    pub const fn pins(self) -> (bool, bool, bool) {
        (
            self.0 & 0b100 != 0,
            self.0 & 0b010 != 0,
            self.0 & 0b001 != 0,
        )
    }
}

/// A downstream channel, SCn/SDn; bit n of the control register.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Channel {
    /// Channel 0 (SC0/SD0), bit 0.
    Ch0 = 0,
    /// Channel 1 (SC1/SD1), bit 1.
    Ch1 = 1,
    /// Channel 2 (SC2/SD2), bit 2.
    Ch2 = 2,
    /// Channel 3 (SC3/SD3), bit 3.
    Ch3 = 3,
    /// Channel 4 (SC4/SD4), bit 4.
    Ch4 = 4,
    /// Channel 5 (SC5/SD5), bit 5.
    Ch5 = 5,
    /// Channel 6 (SC6/SD6), bit 6.
    Ch6 = 6,
    /// Channel 7 (SC7/SD7), bit 7.
    Ch7 = 7,
}

impl Channel {
    /// Every channel, channel 0 first: `ALL[n]` is channel n.
    pub const ALL: [Channel; CHANNEL_COUNT] = [
        Channel::Ch0,
        Channel::Ch1,
        Channel::Ch2,
        Channel::Ch3,
        Channel::Ch4,
        Channel::Ch5,
        Channel::Ch6,
        Channel::Ch7,
    ];

    /// Channel `index`; `None` above 7.
    pub const fn new(index: u8) -> Option<Self> {
        match index {
            0 => Some(Channel::Ch0),
            1 => Some(Channel::Ch1),
            2 => Some(Channel::Ch2),
            3 => Some(Channel::Ch3),
            4 => Some(Channel::Ch4),
            5 => Some(Channel::Ch5),
            6 => Some(Channel::Ch6),
            7 => Some(Channel::Ch7),
            _ => None,
        }
    }

    /// The channel number, 0..=7 (also its bit position in the control register).
    pub const fn index(self) -> u8 {
        self as u8
    }

    /// The control-register value enabling only this channel.
    pub const fn mask(self) -> ChannelMask {
        ChannelMask(1 << self.index())
    }
}

/// A control-register value: bit n set = channel n enabled. Every `u8` is valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChannelMask(pub u8);

impl ChannelMask {
    /// All channels off, the power-on and reset value.
    pub const NONE: ChannelMask = ChannelMask(0);
    /// All eight channels on.
    pub const ALL: ChannelMask = ChannelMask(0xFF);

    /// This mask with `channel` enabled as well.
    pub const fn with(self, channel: Channel) -> Self {
        Self(self.0 | channel.mask().0)
    }

    /// This mask with `channel` disabled.
    pub const fn without(self, channel: Channel) -> Self {
        Self(self.0 & !channel.mask().0)
    }

    /// True when `channel` is enabled.
    pub const fn contains(self, channel: Channel) -> bool {
        self.0 & channel.mask().0 != 0
    }

    /// True when no channel is enabled.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The enabled channel when exactly one is enabled, else `None`.
    pub const fn single_channel(self) -> Option<Channel> {
        if self.0.count_ones() == 1 {
            Channel::new(self.0.trailing_zeros() as u8)
        } else {
            None
        }
    }

    /// The enabled channels, channel 0 first.
    pub fn channels(self) -> impl Iterator<Item = Channel> {
        Channel::ALL
            .into_iter()
            .filter(move |&channel| self.contains(channel))
    }
}

impl From<Channel> for ChannelMask {
    /// The mask enabling only `channel`.
    fn from(channel: Channel) -> Self {
        channel.mask()
    }
}

/// Errors of the driver; `E` is the I2C bus error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The I2C transfer failed (NACK, arbitration loss, bus error).
    I2c(E),
    /// The control register read back differently from what was written: the mux was reset in
    /// between, is stuck, or another device answered at its address.
    ReadBack {
        /// Value written.
        expected: ChannelMask,
        /// Value read back.
        read: ChannelMask,
    },
}

impl<E: i2c::Error> i2c::Error for Error<E> {
    /// The bus error's own kind; [`ErrorKind::Other`] for a read-back mismatch, so code
    /// generic over `embedded-hal` errors can pass the mux error on.
    fn kind(&self) -> ErrorKind {
        match self {
            Error::I2c(error) => error.kind(),
            Error::ReadBack { .. } => ErrorKind::Other,
        }
    }
}

/// A TCA9548A on an I2C bus.
pub struct Tca9548a<I2C> {
    i2c: I2C,
    address: Address,
}

impl<I2C: I2c> Tca9548a<I2C> {
    /// Wraps the bus; no bus traffic (the mux keeps whatever selection it has).
    pub fn new(i2c: I2C, address: Address) -> Self {
        Self { i2c, address }
    }

    /// The address the driver talks to.
    pub fn address(&self) -> Address {
        self.address
    }

    /// Gives the bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }

    /// Enables `channel` and disables the seven others (writes one byte, bit n = channel n).
    pub async fn select(&mut self, channel: Channel) -> Result<(), Error<I2C::Error>> {
        self.select_mask(channel.mask()).await
    }

    /// Enables exactly the channels in `mask` (writes the mask as the one data byte).
    pub async fn select_mask(&mut self, mask: ChannelMask) -> Result<(), Error<I2C::Error>> {
        self.i2c
            .write(self.address.seven_bit(), &[mask.0])
            .await
            .map_err(Error::I2c)
    }

    /// Disables every channel (writes 0x00), the state after power-on or reset.
    pub async fn disable_all(&mut self) -> Result<(), Error<I2C::Error>> {
        self.select_mask(ChannelMask::NONE).await
    }

    /// Reads the control register: the channels enabled now.
    pub async fn enabled(&mut self) -> Result<ChannelMask, Error<I2C::Error>> {
        let mut control = [0u8; 1];
        self.i2c
            .read(self.address.seven_bit(), &mut control)
            .await
            .map_err(Error::I2c)?;
        let [bits] = control;
        Ok(ChannelMask(bits))
    }

    /// [`Tca9548a::select`], then reads the control register back; [`Error::ReadBack`] when
    /// it holds anything but `channel` alone.
    pub async fn select_verified(&mut self, channel: Channel) -> Result<(), Error<I2C::Error>> {
        self.select_mask_verified(channel.mask()).await
    }

    /// [`Tca9548a::select_mask`], then reads the control register back; [`Error::ReadBack`]
    /// when it differs from `mask`.
    pub async fn select_mask_verified(
        &mut self,
        mask: ChannelMask,
    ) -> Result<(), Error<I2C::Error>> {
        self.select_mask(mask).await?;
        let read = self.enabled().await?;
        if read == mask {
            Ok(())
        } else {
            Err(Error::ReadBack {
                expected: mask,
                read,
            })
        }
    }
}
