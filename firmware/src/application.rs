//! The acquisition task: builds the portable device application (`device::Device` around
//! `acquisition::Acquisition`) from the board's parts and runs it, one converter cycle per step,
//! reporting progress to the watchdog.

use acquisition::Clock;
use defmt::{info, warn};
use device::{BoardParts, DeviceIdentity, ResetKind, BOARD};
use embassy_embedded_hal::shared_bus::asynch::i2c::I2cDevice;
use embassy_stm32::peripherals::ADC1;
use embassy_stm32::Peri;
use embassy_time::{Delay, Instant};
use tmp117::{Address, Tmp117};

use crate::die_temperature::DieTemperature;
use crate::host_port::UsbHostPort;
use crate::i2c::SharedBus;
use crate::retained;
use crate::storage::FlashPersistence;
use crate::watchdog;

/// The embassy time driver as the acquisition loop's clock.
struct EmbassyClock;

impl Clock for EmbassyClock {
    fn now_us(&self) -> u64 {
        Instant::now().as_micros()
    }
}

/// Builds the device application and runs it forever.
#[embassy_executor::task]
pub async fn acquisition_task(
    i2c_bus: &'static SharedBus,
    adc: Peri<'static, ADC1>,
    mut persistence: FlashPersistence,
    reset: ResetKind,
) -> ! {
    let mut tmp117 = Tmp117::new(I2cDevice::new(i2c_bus), Address::Gnd);
    match tmp117.init().await {
        Ok(()) => info!("TMP117 found"),
        Err(tmp117_error) => warn!("TMP117 not found: {}", tmp117_error),
    }
    let die_temperature = DieTemperature::new(adc).await;
    let stored = persistence.load().await;
    let parts = BoardParts {
        converter_i2c: I2cDevice::new(i2c_bus),
        delay: Delay,
        temperature: tmp117,
        fallback_temperature: die_temperature,
        clock: EmbassyClock,
        persistence,
        identity: DeviceIdentity {
            firmware_version: device::FIRMWARE_VERSION,
            board_serial: embassy_stm32::uid::uid(),
        },
    };
    info!("{}", parts.identity);
    let (mut device, report) = device::boot(parts, &BOARD, stored, reset, retained::read());
    info!("booted after {}: {}", reset, report);
    if reset == ResetKind::McuOnly && !report.restored {
        warn!("MCU reset without a retained record: not tared until the host tares");
    }
    let mut port = UsbHostPort::new();
    loop {
        device.step(&mut port).await;
        if let Some(state) = device.retained_state_change() {
            retained::write(&state);
        }
        watchdog::heartbeat();
    }
}
