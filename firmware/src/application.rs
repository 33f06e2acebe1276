//! The acquisition task: builds the portable device application (`device::Device` around
//! `acquisition::Acquisition`) from the board's parts and runs it, one converter cycle per step,
//! reporting progress to the watchdog.

use acquisition::{Acquisition, AcquisitionConfig, Clock, ProcessedSample, TemperatureOrigin};
use defmt::{debug, error, info, warn};
use device::{boot_plan, Device, DeviceConfig, DeviceIdentity, ResetKind};
use embassy_embedded_hal::shared_bus::asynch::i2c::I2cDevice;
use embassy_stm32::peripherals::ADC1;
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_time::{Delay, Instant};
use fdc1004::{Fdc1004, Rate};
use model_core::{PadModel, TaxelFlags};
use tmp117::{Address, Tmp117};
use wire::FirmwareVersion;

use crate::die_temperature::DieTemperature;
use crate::host_port::UsbHostPort;
use crate::i2c::SharedBus;
use crate::retained;
use crate::storage::FlashPersistence;
use crate::watchdog;

/// CAPDAC of each measurement (CIN1..CIN4): no offset. A taxel is about 4.5 pF unloaded and
/// 26 % more at 50 kPa; with the cable shields driven by SHLD1/SHLD2 the cable adds little, so
/// everything stays inside the ±15 pF input range. Calibrations are only valid for the CAPDAC
/// they were taken with: change it and the pad must be calibrated again.
const CAPDAC_PER_CHANNEL: [u8; 4] = [0; 4];

/// The fastest rate: four conversions (one per taxel) take about 10 ms, so about 100 sets/s.
/// The DONE timeout follows from the rate (`fdc1004::Rate::done_timeout_us`), here and after a
/// SetRate, and the power-up wait is the driver's (the FDC1004 answers about 5 ms after
/// power-up).
const CONVERTER_RATE: Rate = Rate::Hz400;

/// Sample sets averaged by the tare a power-on takes (the pad is taken to be unloaded then).
const TARE_SETS_AT_POWER_ON: u16 = 16;

/// A counters line goes to the log (at debug level) every this many sample sets.
const LOG_COUNTERS_EVERY_SETS: u32 = 1_000;

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
    let converter = Fdc1004::new(
        I2cDevice::new(i2c_bus),
        Delay,
        fdc1004::Config::new(CONVERTER_RATE, CAPDAC_PER_CHANNEL),
    );
    let (calibration, calibration_source) = persistence.load_at_boot().await;
    // Built outside the async body so the model exists once in the task's state, not twice.
    let mut device = assemble(
        converter,
        tmp117,
        die_temperature,
        persistence,
        calibration,
        calibration_source,
        reset,
    );
    let mut port = UsbHostPort::new();
    let mut health = HealthLog::default();
    info!("acquisition running, calibration {}", calibration_source);
    loop {
        let sample = device.step(&mut port).await;
        if let Some(state) = device.retained_state_change() {
            retained::write(&state);
        }
        watchdog::heartbeat();
        health.update(&sample);
    }
}

/// One device's handle on the shared I2C bus.
type SharedI2cDevice = I2cDevice<'static, NoopRawMutex, crate::i2c::I2cBus>;

/// The device application type the task runs.
type FirmwareDevice = Device<
    Acquisition<SharedI2cDevice, Delay, Tmp117<SharedI2cDevice>, DieTemperature, EmbassyClock>,
    FlashPersistence,
>;

/// Boots the model (baselines and tier restored after an MCU-only reset, a tare after a
/// power-on) and assembles the device application.
#[inline(never)]
fn assemble(
    converter: Fdc1004<SharedI2cDevice, Delay>,
    tmp117: Tmp117<SharedI2cDevice>,
    die_temperature: DieTemperature,
    persistence: FlashPersistence,
    calibration: model_core::Calibration,
    calibration_source: wire::CalibrationSource,
    reset: ResetKind,
) -> FirmwareDevice {
    let plan = boot_plan(reset, retained::read(), TARE_SETS_AT_POWER_ON);
    let mut pad = PadModel::new(calibration);
    let restored_mask = plan.apply_to(&mut pad);
    match (reset, plan.restore.is_some()) {
        (ResetKind::PowerOn, _) => {
            info!("power-on: taring over {=u16} sets", TARE_SETS_AT_POWER_ON)
        }
        (ResetKind::McuOnly, true) => info!(
            "MCU reset: baselines restored (mask {=u8:#06b})",
            restored_mask
        ),
        (ResetKind::McuOnly, false) => {
            warn!("MCU reset without a retained record: not tared until the host tares")
        }
    }
    let acquisition = Acquisition::new(
        converter,
        tmp117,
        die_temperature,
        EmbassyClock,
        pad,
        AcquisitionConfig {
            tare_sets_at_start: plan.tare_sets_at_start,
            ..AcquisitionConfig::default()
        },
        Delay,
    );
    let identity = DeviceIdentity {
        firmware_version: FIRMWARE_VERSION,
        board_serial: embassy_stm32::uid::uid(),
    };
    info!("{}", identity);
    Device::new(
        acquisition,
        persistence,
        identity,
        calibration_source,
        DeviceConfig::default(),
    )
}

/// Logs changes of the converter's and the temperature sources' state, not every sample.
#[derive(Default)]
struct HealthLog {
    converter_faulted: Option<bool>,
    temperature_origin: Option<TemperatureOrigin>,
    sets_since_counters: u32,
}

impl HealthLog {
    fn update(&mut self, sample: &ProcessedSample) {
        let converter_faulted = sample
            .input
            .reading_flags
            .iter()
            .any(|flags| flags.contains(TaxelFlags::CONVERTER_ERROR));
        if self.converter_faulted != Some(converter_faulted) {
            if converter_faulted {
                warn!("FDC1004 not converting; re-initialising it every cycle");
            } else {
                info!("FDC1004 converting");
            }
            self.converter_faulted = Some(converter_faulted);
        }
        if self.temperature_origin != Some(sample.temperature_origin) {
            match sample.temperature_origin {
                TemperatureOrigin::Primary => info!("temperature from the TMP117"),
                TemperatureOrigin::Fallback => {
                    warn!("temperature from the die sensor (TMP117 not answering)")
                }
                TemperatureOrigin::None => {
                    error!("no temperature sensor answering; holding the last temperature")
                }
            }
            self.temperature_origin = Some(sample.temperature_origin);
        }
        self.sets_since_counters = self.sets_since_counters.wrapping_add(1);
        if self.sets_since_counters >= LOG_COUNTERS_EVERY_SETS {
            self.sets_since_counters = 0;
            debug!("sequence {=u32}: {}", sample.sequence, sample.counters);
        }
    }
}
