//! Shared by the simulator's tests: the register maps re-declared from the datasheets (not taken
//! from the simulator or the drivers), raw register access over the simulated bus, and a few
//! configurations.
#![allow(dead_code)]

use embassy_futures::block_on;
use embedded_hal_async::i2c::I2c;
use sensor_sim::{SimI2c, SimI2cError, SimulationConfig};

pub const FDC1004: u8 = 0x50;
pub const TMP117: u8 = 0x48;

pub const MEAS1_MSB: u8 = 0x00;
pub const MEAS1_LSB: u8 = 0x01;
pub const CONF_MEAS1: u8 = 0x08;
pub const CONF_MEAS2: u8 = 0x09;
pub const CONF_MEAS3: u8 = 0x0A;
pub const CONF_MEAS4: u8 = 0x0B;
pub const FDC_CONF: u8 = 0x0C;
pub const OFFSET_CAL_CIN1: u8 = 0x0D;
pub const GAIN_CAL_CIN1: u8 = 0x11;
pub const GAIN_CAL_CIN4: u8 = 0x14;
pub const MANUFACTURER_ID: u8 = 0xFE;
pub const DEVICE_ID: u8 = 0xFF;

pub const CONF_MEAS: [u8; 4] = [CONF_MEAS1, CONF_MEAS2, CONF_MEAS3, CONF_MEAS4];

/// FDC_CONF bits.
pub const RST: u16 = 1 << 15;
pub const REPEAT: u16 = 1 << 8;
pub const MEAS_ALL: u16 = 0b1111 << 4;
pub const DONE_ALL: u16 = 0b1111;
pub const RATE_100: u16 = 0b01 << 10;
pub const RATE_200: u16 = 0b10 << 10;
pub const RATE_400: u16 = 0b11 << 10;

/// DONE_n of measurement n (0-based): DONE_1 is bit 3.
pub const fn done_bit(measurement: usize) -> u16 {
    1 << (3 - measurement)
}

/// MEAS_n enable of measurement n (0-based): MEAS_1 is bit 7.
pub const fn meas_enable(measurement: usize) -> u16 {
    1 << (7 - measurement)
}

/// CONF_MEASn: CHA = CIN(input + 1) (bits 15:13), CHB = CAPDAC (100, bits 12:10), CAPDAC
/// (bits 9:5).
pub const fn conf_meas(input: u16, capdac: u16) -> u16 {
    (input << 13) | (0b100 << 10) | (capdac << 5)
}

/// CONF_MEASn with CHB disabled (111).
pub const fn conf_meas_single_ended(input: u16) -> u16 {
    (input << 13) | (0b111 << 10)
}

/// CONF_MEASn with CHB = another input (differential).
pub const fn conf_meas_differential(positive: u16, negative: u16) -> u16 {
    (positive << 13) | (negative << 10)
}

pub const TEMP_RESULT: u8 = 0x00;
pub const CONFIGURATION: u8 = 0x01;
pub const TEMP_OFFSET: u8 = 0x07;
pub const TMP117_DEVICE_ID: u8 = 0x0F;
pub const DATA_READY: u16 = 1 << 13;

/// Codes per pF of the FDC1004 result (2^19).
pub const CODES_PER_PF: f64 = 524_288.0;

/// What a test helper returns: any error, so that the test itself unwraps it.
pub type TestResult<T> = Result<T, Box<dyn std::error::Error>>;

pub fn read_register(bus: &mut SimI2c, address: u8, pointer: u8) -> Result<u16, SimI2cError> {
    let mut buffer = [0u8; 2];
    block_on(bus.write_read(address, &[pointer], &mut buffer))?;
    Ok(u16::from_be_bytes(buffer))
}

pub fn write_register(
    bus: &mut SimI2c,
    address: u8,
    pointer: u8,
    value: u16,
) -> Result<(), SimI2cError> {
    let [high, low] = value.to_be_bytes();
    block_on(bus.write(address, &[pointer, high, low]))
}

/// Reads measurement n's 24-bit result, MSB first, sign-extended.
pub fn read_result(bus: &mut SimI2c, measurement: usize) -> Result<i32, SimI2cError> {
    let msb = read_register(bus, FDC1004, MEAS1_MSB + 2 * measurement as u8)?;
    let lsb = read_register(bus, FDC1004, MEAS1_LSB + 2 * measurement as u8)?;
    let unsigned_24 = ((msb as u32) << 8) | ((lsb as u32) >> 8);
    Ok(((unsigned_24 << 8) as i32) >> 8)
}

/// Configures measurement n to convert CIN(n+1) against CAPDAC 0 for every n, then starts
/// repeated measurements of all four at `rate` (an FDC_CONF RATE field value).
pub fn start_all(bus: &mut SimI2c, rate: u16) -> Result<(), SimI2cError> {
    for (measurement, &pointer) in CONF_MEAS.iter().enumerate() {
        write_register(bus, FDC1004, pointer, conf_meas(measurement as u16, 0))?;
    }
    write_register(bus, FDC1004, FDC_CONF, rate | REPEAT | MEAS_ALL)
}

/// No bus time and no noise: register values and times are exact.
pub fn exact_config() -> SimulationConfig {
    let mut config = SimulationConfig {
        bus_frequency_hz: None,
        ..SimulationConfig::default()
    };
    config.fdc1004.noise_rms_pf_at_100_sps = 0.0;
    config.tmp117.noise_rms_c = 0.0;
    config
}

/// Past both devices' power-up.
pub const POWERED_UP_US: u64 = 5_000;
