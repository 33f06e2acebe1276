//! The sensor bus: I2C1 at 400 kHz with DMA, every transaction bounded in time by [`TimeoutI2c`],
//! shared by the FDC1004 and the TMP117 drivers through `embassy-embedded-hal` bus handles.

use embassy_stm32::i2c::{Config, I2c, Master};
use embassy_stm32::mode::Async;
use embassy_stm32::time::Hertz;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::{with_timeout, Duration};
use embedded_hal_async::i2c::{Error, ErrorKind, ErrorType, I2c as AsyncI2c, Operation};
use static_cell::StaticCell;

use crate::board::{I2cPeripherals, Irqs};

/// FDC1004 and TMP117 both support fast mode.
const I2C_FREQUENCY_HZ: u32 = 400_000;

/// Longest wait for one transaction; the longest the drivers issue (a register read: 1 byte out,
/// 2 bytes in) takes about 100 µs at 400 kHz.
const I2C_TRANSACTION_TIMEOUT: Duration = Duration::from_millis(20);

/// The bus with its timeout.
pub type I2cBus = TimeoutI2c<I2c<'static, Async, Master>>;

/// The bus behind a mutex; every driver gets its own `I2cDevice` handle to it. Only the
/// acquisition task uses it, hence the no-op mutex.
pub type SharedBus = Mutex<NoopRawMutex, I2cBus>;

/// Sets up I2C1; call once (a second call returns `None`).
pub fn shared_bus(peripherals: I2cPeripherals) -> Option<&'static SharedBus> {
    static BUS: StaticCell<SharedBus> = StaticCell::new();
    let mut config = Config::default();
    config.frequency = Hertz(I2C_FREQUENCY_HZ);
    // The sensor board carries the pull-ups; the ~40 kOhm internal ones are too weak for 400 kHz.
    config.scl_pullup = false;
    config.sda_pullup = false;
    let i2c = I2c::new(
        peripherals.i2c1,
        peripherals.scl,
        peripherals.sda,
        peripherals.tx_dma,
        peripherals.rx_dma,
        Irqs,
        config,
    );
    let bus = BUS.try_init(Mutex::new(TimeoutI2c::new(i2c, I2C_TRANSACTION_TIMEOUT)))?;
    Some(bus)
}

/// An I2C bus whose transactions fail with [`TimeoutI2cError::Timeout`] after a fixed time.
///
/// embassy-stm32's async I2C on the F4 never times out by itself: a slave holding SCL low would
/// hang the acquisition loop forever. A cancelled transfer sends no STOP: while a slave keeps
/// holding the bus, later transactions time out too (the acquisition loop counts them as I2C
/// errors and keeps running) until it lets go.
pub struct TimeoutI2c<B> {
    bus: B,
    timeout: Duration,
}

impl<B> TimeoutI2c<B> {
    /// Wraps `bus`; every transaction gets at most `timeout`.
    pub fn new(bus: B, timeout: Duration) -> Self {
        Self { bus, timeout }
    }
}

/// A [`TimeoutI2c`] transaction failed.
#[derive(Debug, defmt::Format)]
pub enum TimeoutI2cError<E> {
    /// The bus reported an error.
    Bus(E),
    /// The transaction did not finish in time.
    Timeout,
}

impl<E: Error> Error for TimeoutI2cError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Bus(bus_error) => bus_error.kind(),
            Self::Timeout => ErrorKind::Other,
        }
    }
}

impl<B: ErrorType> ErrorType for TimeoutI2c<B> {
    type Error = TimeoutI2cError<B::Error>;
}

impl<B: AsyncI2c> AsyncI2c for TimeoutI2c<B> {
    async fn read(&mut self, address: u8, read: &mut [u8]) -> Result<(), Self::Error> {
        bounded(self.timeout, self.bus.read(address, read)).await
    }

    async fn write(&mut self, address: u8, write: &[u8]) -> Result<(), Self::Error> {
        bounded(self.timeout, self.bus.write(address, write)).await
    }

    async fn write_read(
        &mut self,
        address: u8,
        write: &[u8],
        read: &mut [u8],
    ) -> Result<(), Self::Error> {
        bounded(self.timeout, self.bus.write_read(address, write, read)).await
    }

    async fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        bounded(self.timeout, self.bus.transaction(address, operations)).await
    }
}

async fn bounded<E>(
    timeout: Duration,
    transfer: impl core::future::Future<Output = Result<(), E>>,
) -> Result<(), TimeoutI2cError<E>> {
    match with_timeout(timeout, transfer).await {
        Ok(result) => result.map_err(TimeoutI2cError::Bus),
        Err(_) => Err(TimeoutI2cError::Timeout),
    }
}
