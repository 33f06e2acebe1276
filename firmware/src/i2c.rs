//! The sensor bus: I2C1 at 400 kHz with DMA, every transaction bounded in time by
//! `acquisition::TimeoutI2c`; after discovery it is shared by every pad's FDC1004 and TMP117
//! through `acquisition::pad_bus` handles, which select the pad's multiplexer channel.

use acquisition::discovery::Topology;
use acquisition::pad_bus::MuxedBus;
use acquisition::TimeoutI2c;
use embassy_stm32::i2c::{Config, I2c, Master};
use embassy_stm32::mode::Async;
use embassy_stm32::time::Hertz;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::Delay;
use static_cell::StaticCell;

use crate::board::{I2cPeripherals, Irqs};

/// Longest wait for one transaction; the longest the drivers issue (a register read: 1 byte out,
/// 2 bytes in) takes about 100 µs at 400 kHz.
const I2C_TRANSACTION_TIMEOUT_US: u32 = 20_000;

/// The bus with its timeout.
pub type I2cBus = TimeoutI2c<I2c<'static, Async, Master>, Delay>;

/// The bus with its multiplexer behind a mutex; every pad's drivers get their own handle to it.
/// Only the acquisition task uses it, hence the no-op mutex.
pub type SharedBus = Mutex<NoopRawMutex, MuxedBus<I2cBus>>;

/// Shares the bus between the pads discovery found on it; call once (a second call returns
/// `None`).
pub fn share(bus: I2cBus, topology: &Topology) -> Option<&'static SharedBus> {
    static BUS: StaticCell<SharedBus> = StaticCell::new();
    BUS.try_init(Mutex::new(MuxedBus::new(bus, topology.mux)))
        .map(|bus| &*bus)
}

/// Sets up I2C1.
pub fn bus(peripherals: I2cPeripherals) -> I2cBus {
    let mut config = Config::default();
    config.frequency = Hertz(device::BOARD.i2c_frequency_hz);
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
    TimeoutI2c::new(i2c, Delay, I2C_TRANSACTION_TIMEOUT_US)
}
