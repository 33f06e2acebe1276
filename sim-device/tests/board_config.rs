//! The simulated device runs the board's configuration (`device::BOARD`, the one the firmware
//! boots with): read back from the simulated converter's registers, as the datasheet lays them
//! out, not from the code that wrote them.

// Test helpers may unwrap: a failure is the test failing.
#![allow(clippy::unwrap_used)]

use device::BOARD;
use sim_device::{MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};

/// FDC1004 CONF_MEAS1..4 (0x08..0x0B): CHA in bits 15:13, CHB in 12:10, CAPDAC in 9:5.
const CONF_MEAS: [u8; 4] = [0x08, 0x09, 0x0A, 0x0B];
/// FDC1004 FDC_CONF (0x0C): RATE in bits 11:10 (01 = 100, 10 = 200, 11 = 400 S/s).
const FDC_CONF: u8 = 0x0C;

#[test]
fn the_simulated_converter_is_configured_as_the_board() {
    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1).with_seed(2),
    )
    .unwrap();
    let mut port = MemoryPort::new(usize::MAX);
    for _ in 0..30 {
        device.step(&mut port);
    }
    let simulation = device.simulation();
    for (measurement, (&pointer, &capdac)) in CONF_MEAS.iter().zip(&BOARD.capdac).enumerate() {
        let register = simulation.peek_fdc1004_register(pointer);
        assert_eq!(
            (register >> 13) & 0b111,
            measurement as u16,
            "CHA of {measurement}"
        );
        assert_eq!((register >> 10) & 0b111, 0b100, "CHB = CAPDAC");
        assert_eq!(
            (register >> 5) & 0b1_1111,
            u16::from(capdac),
            "CAPDAC of {measurement}"
        );
    }
    let rate_bits = (simulation.peek_fdc1004_register(FDC_CONF) >> 10) & 0b11;
    let rate_sps = match rate_bits {
        0b01 => 100,
        0b10 => 200,
        0b11 => 400,
        other => unreachable!("reserved rate bits {other:#b}"),
    };
    assert_eq!(rate_sps, BOARD.converter_rate.samples_per_second());
    assert_eq!(u32::from(device.device_mut().info().rate.sps()), rate_sps);
}

/// The simulated calibration flash has the board's geometry: the region of sectors 6 and 7 of
/// the STM32F411CE (RM0383: 128 KiB each), erased a sector at a time.
#[test]
fn the_simulated_flash_has_the_board_sectors() {
    use embedded_storage_async::nor_flash::NorFlash;
    assert_eq!(sim_device::FLASH_SECTOR_LEN, 128 * 1024);
    assert_eq!(sim_device::FLASH_REGION_LEN, 2 * 128 * 1024);
    assert_eq!(
        <sim_device::SimulatedFlash as NorFlash>::ERASE_SIZE,
        128 * 1024
    );
    assert_eq!(
        calibration_store::STM32F411_CALIBRATION_RANGE.len(),
        sim_device::FLASH_REGION_LEN
    );
}
