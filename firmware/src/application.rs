//! The acquisition task: finds the pads on the sensor bus, builds the portable device
//! application (`device::Device` around `acquisition::Acquisition`) from the board's parts and
//! runs it, one sample set of every pad per step, reporting progress to the watchdog.

use acquisition::discovery::{discover, PadTemperature};
use acquisition::pad_bus::PadBus;
use acquisition::Clock;
use defmt::{error, info, warn};
use device::{BoardParts, DeviceIdentity, ResetKind, BOARD};
use embassy_stm32::peripherals::ADC1;
use embassy_stm32::Peri;
use embassy_time::{Delay, Instant};
use tmp117::Tmp117;

use crate::die_temperature::DieTemperature;
use crate::host_port::UsbHostPort;
use crate::i2c::{self, I2cBus};
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
    mut bus: I2cBus,
    adc: Peri<'static, ADC1>,
    persistence: FlashPersistence,
    reset: ResetKind,
) -> ! {
    let topology = discover(&mut bus, &mut Delay, BOARD.multiplexer).await;
    info!("sensor bus: {}", topology);
    let Some(shared) = i2c::share(bus, &topology) else {
        error!("the sensor bus was already shared");
        // Only a second start of this task gets here; the watchdog resets the board.
        loop {
            embassy_time::Timer::after_secs(1).await;
        }
    };
    for slot in &topology.pads {
        let (channel, address) = match slot.temperature {
            PadTemperature::Own(address) => (slot.channel, address),
            PadTemperature::Shared(address) => (None, address),
            PadTemperature::DieOnly => continue,
        };
        if let Err(tmp117_error) = Tmp117::new(PadBus::new(shared, channel), address)
            .init()
            .await
        {
            warn!("TMP117 {} not set up: {}", address, tmp117_error);
        }
    }
    let die_temperature = DieTemperature::new(adc).await;
    let parts = BoardParts {
        bus: shared,
        topology,
        delay: Delay,
        fallback_temperature: die_temperature,
        clock: EmbassyClock,
        persistence,
        identity: DeviceIdentity {
            firmware_version: device::FIRMWARE_VERSION,
            board_serial: embassy_stm32::uid::uid(),
            clock_us_per_s: device::REAL_TIME_CLOCK_US_PER_S,
        },
    };
    info!("{}", parts.identity);
    let (mut device, report) = device::boot(parts, &BOARD, reset, retained::read());
    info!("booted after {}: {}", reset, report);
    if reset == ResetKind::McuOnly && !report.restored {
        warn!("MCU reset without a retained record: not tared until the host tares");
    }
    let mut port = UsbHostPort::new();
    loop {
        device.step(&mut port).await;
        retained::write_if_changed(&device.retained_record());
        watchdog::heartbeat();
    }
}
