//! The acquisition task: builds the portable device application (`device::Device` around
//! `acquisition::Acquisition`) from the board's parts and runs it, one converter cycle per step,
//! reporting progress to the watchdog.

use acquisition::Clock;
use defmt::{info, warn};
use device::{BoardParts, DeviceIdentity, ResetKind, BOARD};
use embassy_embedded_hal::shared_bus::asynch::i2c::I2cDevice;
use embassy_stm32::peripherals::ADC1;
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_time::{Delay, Instant};
use tmp117::{Address, Tmp117};
use wire::FirmwareVersion;

use crate::die_temperature::DieTemperature;
use crate::host_port::UsbHostPort;
use crate::i2c::SharedBus;
use crate::retained;
use crate::storage::FlashPersistence;
use crate::watchdog;

/// This firmware's version, from the package version.
const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: version_component(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: version_component(env!("CARGO_PKG_VERSION_MINOR")),
    patch: version_component(env!("CARGO_PKG_VERSION_PATCH")),
};

const _: () = assert!(
    FIRMWARE_VERSION.major != u8::MAX
        && FIRMWARE_VERSION.minor != u8::MAX
        && FIRMWARE_VERSION.patch != u8::MAX,
    "every component of the package version must be below 255"
);

const fn version_component(text: &str) -> u8 {
    match u8::from_str_radix(text, 10) {
        Ok(component) => component,
        Err(_) => u8::MAX,
    }
}

type FirmwareParts = BoardParts<
    SharedI2cDevice,
    Delay,
    Tmp117<SharedI2cDevice>,
    DieTemperature,
    EmbassyClock,
    FlashPersistence,
>;

type FirmwareDevice = device::BootedDevice<
    SharedI2cDevice,
    Delay,
    Tmp117<SharedI2cDevice>,
    DieTemperature,
    EmbassyClock,
    FlashPersistence,
>;

/// One device's handle on the shared I2C bus.
type SharedI2cDevice = I2cDevice<'static, NoopRawMutex, crate::i2c::I2cBus>;

/// The shared boot, outside the async body so that the model exists once in the task's state,
/// not twice.
#[inline(never)]
fn boot(
    parts: FirmwareParts,
    stored: Option<calibration_store::LoadOutcome<embassy_stm32::flash::Error>>,
    reset: ResetKind,
) -> (FirmwareDevice, device::BootReport) {
    device::boot(parts, &BOARD, stored, reset, retained::read())
}

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
            firmware_version: FIRMWARE_VERSION,
            board_serial: embassy_stm32::uid::uid(),
        },
    };
    info!("{}", parts.identity);
    let (mut device, report) = boot(parts, stored, reset);
    match (reset, report.restored) {
        (ResetKind::PowerOn, _) => info!(
            "power-on: taring over {=u16} sets",
            report.tare_sets_at_start
        ),
        (ResetKind::McuOnly, true) => info!(
            "MCU reset: baselines restored (mask {=u8:#06b})",
            report.restored_mask
        ),
        (ResetKind::McuOnly, false) => {
            warn!("MCU reset without a retained record: not tared until the host tares")
        }
    }
    let calibration_source = report.calibration_source;
    let mut port = UsbHostPort::new();
    info!("acquisition running, calibration {}", calibration_source);
    loop {
        device.step(&mut port).await;
        if let Some(state) = device.retained_state_change() {
            retained::write(&state);
        }
        watchdog::heartbeat();
    }
}
