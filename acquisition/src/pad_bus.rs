//! Several pads on one I2C bus: [`MuxedBus`] owns the bus and remembers which TCA9548A channel
//! is selected; each pad talks through a [`PadBus`], which selects its channel (when the pad sits
//! behind the multiplexer) before its transaction, under the same lock, so no other pad can
//! switch the channel in between.
//!
//! The selection is written only when it changes, and forgotten after any failed transaction:
//! a multiplexer that reset behind our back (a brown-out on the pad cable) is then selected
//! again on the next transaction instead of leaving every later one on the wrong channel.

use core::ops::Deref;

use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::mutex::Mutex;
use embedded_hal_async::i2c::{Error, ErrorKind, ErrorType, I2c, Operation};
use tca9548a::{Address, Channel, ChannelMask, Tca9548a};

/// The bus with the multiplexer's selection as last written.
pub struct MuxedBus<BUS> {
    bus: BUS,
    mux: Option<Address>,
    selected: Option<ChannelMask>,
}

impl<BUS> MuxedBus<BUS> {
    /// A bus with a multiplexer at `mux` (or none: every pad is on the bus itself).
    pub fn new(bus: BUS, mux: Option<Address>) -> Self {
        Self {
            bus,
            mux,
            selected: None,
        }
    }

    /// The multiplexer's address, if there is one.
    pub fn mux(&self) -> Option<Address> {
        self.mux
    }

    /// The bus itself (discovery, tests).
    pub fn bus_mut(&mut self) -> &mut BUS {
        &mut self.bus
    }
}

/// A [`PadBus`] transaction failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PadBusError<E> {
    /// Selecting the pad's channel failed (the multiplexer did not answer).
    Select(tca9548a::Error<E>),
    /// The transaction itself failed.
    Bus(E),
}

impl<E: Error> Error for PadBusError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            PadBusError::Select(error) => error.kind(),
            PadBusError::Bus(error) => error.kind(),
        }
    }
}

/// One pad's handle on a shared [`MuxedBus`]: on `channel` of the multiplexer, or on the bus
/// itself (`None`: a pad without multiplexer, or a device upstream of it).
///
/// `S` is how the handle reaches the shared bus: a `&'static` on the MCU (the bus lives in a
/// static), a reference or a reference-counted pointer on the host (the simulated device owns
/// its bus).
pub struct PadBus<S> {
    shared: S,
    channel: Option<Channel>,
}

impl<S> PadBus<S> {
    /// A handle for the device(s) on `channel`.
    pub fn new(shared: S, channel: Option<Channel>) -> Self {
        Self { shared, channel }
    }

    /// The channel this handle selects.
    pub fn channel(&self) -> Option<Channel> {
        self.channel
    }
}

impl<S, M, BUS> ErrorType for PadBus<S>
where
    S: Deref<Target = Mutex<M, MuxedBus<BUS>>>,
    M: RawMutex,
    BUS: ErrorType,
{
    type Error = PadBusError<BUS::Error>;
}

impl<BUS: I2c> MuxedBus<BUS> {
    /// Selects `channel` unless it is selected already (or there is no multiplexer).
    async fn select(&mut self, channel: Option<Channel>) -> Result<(), PadBusError<BUS::Error>> {
        let (Some(mux), Some(channel)) = (self.mux, channel) else {
            return Ok(());
        };
        if self.selected == Some(channel.mask()) {
            return Ok(());
        }
        self.selected = None;
        Tca9548a::new(&mut self.bus, mux)
            .select(channel)
            .await
            .map_err(PadBusError::Select)?;
        self.selected = Some(channel.mask());
        Ok(())
    }

    /// A transaction's result, forgetting the selection when it failed.
    fn settle<T>(&mut self, result: Result<T, BUS::Error>) -> Result<T, PadBusError<BUS::Error>> {
        if result.is_err() {
            self.selected = None;
        }
        result.map_err(PadBusError::Bus)
    }
}

// Each method forwards to the same method of the bus (not all to `transaction`), so a bus
// with a faster `write_read` keeps it.
impl<S, M, BUS> I2c for PadBus<S>
where
    S: Deref<Target = Mutex<M, MuxedBus<BUS>>>,
    M: RawMutex,
    BUS: I2c,
{
    async fn read(&mut self, address: u8, read: &mut [u8]) -> Result<(), Self::Error> {
        let mut shared = self.shared.lock().await;
        shared.select(self.channel).await?;
        let result = shared.bus.read(address, read).await;
        shared.settle(result)
    }

    async fn write(&mut self, address: u8, write: &[u8]) -> Result<(), Self::Error> {
        let mut shared = self.shared.lock().await;
        shared.select(self.channel).await?;
        let result = shared.bus.write(address, write).await;
        shared.settle(result)
    }

    async fn write_read(
        &mut self,
        address: u8,
        write: &[u8],
        read: &mut [u8],
    ) -> Result<(), Self::Error> {
        let mut shared = self.shared.lock().await;
        shared.select(self.channel).await?;
        let result = shared.bus.write_read(address, write, read).await;
        shared.settle(result)
    }

    async fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let mut shared = self.shared.lock().await;
        shared.select(self.channel).await?;
        let result = shared.bus.transaction(address, operations).await;
        shared.settle(result)
    }
}
