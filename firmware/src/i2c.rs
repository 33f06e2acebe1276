//! The sensor bus: I2C1 at 400 kHz with DMA, every transaction bounded in time by
//! `acquisition::TimeoutI2c`, shared by the FDC1004 and the TMP117 drivers through
//! `embassy-embedded-hal` bus handles.

use acquisition::TimeoutI2c;
use embassy_stm32::i2c::{Config, I2c, Master};
use embassy_stm32::mode::Async;
use embassy_stm32::time::Hertz;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::Delay;
use static_cell::StaticCell;

use crate::board::{I2cPeripherals, Irqs};

/// FDC1004 and TMP117 both support fast mode.
const I2C_FREQUENCY_HZ: u32 = 400_000;

/// Longest wait for one transaction; the longest the drivers issue (a register read: 1 byte out,
/// 2 bytes in) takes about 100 µs at 400 kHz.
const I2C_TRANSACTION_TIMEOUT_US: u32 = 20_000;

/// The bus with its timeout.
pub type I2cBus = TimeoutI2c<I2c<'static, Async, Master>, Delay>;

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
    let bus = TimeoutI2c::new(i2c, Delay, I2C_TRANSACTION_TIMEOUT_US);
    BUS.try_init(Mutex::new(bus)).map(|bus| &*bus)
}
