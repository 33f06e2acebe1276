//! Firmware of the taxel pad on a WeAct STM32F411CEU6 "Black Pill": brings the board up and
//! spawns the tasks. The application itself (acquisition, model, protocol) lives in the portable
//! crates; the modules here only connect them to the hardware.

#![no_std]
#![no_main]

mod application;
mod board;
mod die_temperature;
mod host_port;
mod i2c;
mod panic;
mod retained;
mod storage;
mod usb;
mod watchdog;

use defmt::{error, info};
use defmt_rtt as _;
use embassy_executor::{SpawnError, SpawnToken, Spawner};

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let board = board::init();
    info!("taxel firmware {=str} starting", env!("CARGO_PKG_VERSION"));
    let reset = watchdog::report_reset_cause();
    watchdog::start(board.iwdg);

    match usb::build(board.usb) {
        Some(usb) => {
            spawn(&spawner, "USB device", usb::device_task(usb.device));
            spawn(&spawner, "USB control", usb::control_task(usb.control));
            spawn(&spawner, "USB writer", usb::writer_task(usb.sender));
            spawn(&spawner, "USB reader", usb::reader_task(usb.receiver));
        }
        None => error!("the USB device was already built"),
    }
    let persistence = storage::FlashPersistence::new(board.flash);
    spawn(
        &spawner,
        "acquisition",
        application::acquisition_task(i2c::bus(board.i2c), board.adc, persistence, reset),
    );

    watchdog::supervise(board.led).await
}

fn spawn<S>(spawner: &Spawner, name: &str, token: Result<SpawnToken<S>, SpawnError>) {
    match token {
        Ok(token) => spawner.spawn(token),
        Err(spawn_error) => error!("cannot spawn the {=str} task: {}", name, spawn_error),
    }
}
