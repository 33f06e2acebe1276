//! The simulated TI TMP117 at register level (address 0x48, ADD0 to ground; a TMP117 shared on
//! the main bus of a multiplexed topology may be strapped to 0x48..=0x4B).
//!
//! Same pointer protocol as the FDC1004: `[pointer]` sets the pointer, `[pointer, msb, lsb]`
//! writes, a read returns the big-endian register at the pointer.
//!
//! Registers: TEMP_RESULT 0x00 (two's complement, 1/128 °C per LSB, 0x8000 until the first
//! conversion), CONFIGURATION 0x01 (reset 0x0220; HIGH_Alert, LOW_Alert, Data_Ready and
//! EEPROM_Busy read-only in bits 15:12), THigh_Limit 0x02 (0x6000), TLow_Limit 0x03 (0x8000),
//! TEMP_OFFSET 0x07 (added to results), DEVICE_ID 0x0F = 0x0117. The EEPROM registers read 0
//! and ignore writes.
//!
//! Behaviour, and the assumptions:
//! - A conversion result is the scene temperature plus gaussian noise
//!   ([`Tmp117Config::noise_rms_c`]) plus TEMP_OFFSET, rounded to 1/128 °C.
//! - The first conversion completes [`Tmp117Config::first_conversion_us`] after power-on
//!   (default 15.5 ms, one conversion without averaging; with the power-on averaging of 8 the
//!   datasheet's would be about 125 ms). Then, in continuous mode, one every conversion cycle
//!   of the CONV and AVG fields (datasheet table: 15.5 ms .. 16 s; 1 s at reset). Shutdown
//!   (MOD = 01) stops conversions; one-shot (MOD = 11) runs one after the averaging time, then
//!   shuts down. Soft_Reset (bit 1) restarts as at power-on.
//! - Data_Ready (bit 13) sets at each conversion and clears when CONFIGURATION or TEMP_RESULT
//!   is read. The alert flags are not modelled (they read 0).
//! - The address is not acknowledged until [`Tmp117Config::power_up_us`] after power-on
//!   (datasheet start-up time 1.5 ms).

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

use crate::fault::{Device, Fault};
use crate::simulation::Environment;

const TEMP_RESULT: u8 = 0x00;
const CONFIGURATION: u8 = 0x01;
const THIGH_LIMIT: u8 = 0x02;
const TLOW_LIMIT: u8 = 0x03;
const TEMP_OFFSET: u8 = 0x07;
const DEVICE_ID: u8 = 0x0F;

const DEVICE_ID_VALUE: u16 = 0x0117;
const TEMP_RESULT_RESET: u16 = 0x8000;
const CONFIGURATION_RESET: u16 = 0x0220;
const THIGH_LIMIT_RESET: u16 = 0x6000;
const TLOW_LIMIT_RESET: u16 = 0x8000;
/// MOD, CONV, AVG, T/nA, POL, DR/Alert: the CONFIGURATION bits a write keeps.
const CONFIGURATION_WRITABLE: u16 = 0x0FFC;
const DATA_READY: u16 = 1 << 13;
const SOFT_RESET: u16 = 1 << 1;
const MOD_SHIFT: u16 = 10;
const CONV_SHIFT: u16 = 7;
const AVG_SHIFT: u16 = 5;
const MOD_SHUTDOWN: u16 = 0b01;
const MOD_ONE_SHOT: u16 = 0b11;

/// TEMP_RESULT LSBs per °C.
const LSB_PER_C: f64 = 128.0;

/// Active conversion time per AVG setting (none, 8, 32, 64 averages), µs.
const ACTIVE_CONVERSION_US: [u64; 4] = [15_500, 125_000, 500_000, 1_000_000];
/// Conversion cycle time in continuous mode, per CONV (rows) and AVG (columns), µs.
const CYCLE_US: [[u64; 4]; 8] = [
    [15_500, 125_000, 500_000, 1_000_000],
    [125_000, 125_000, 500_000, 1_000_000],
    [250_000, 250_000, 500_000, 1_000_000],
    [500_000, 500_000, 500_000, 1_000_000],
    [1_000_000; 4],
    [4_000_000; 4],
    [8_000_000; 4],
    [16_000_000; 4],
];

/// Settings of the simulated TMP117.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tmp117Config {
    /// The address is not acknowledged until this long after power-on, µs (default 1500).
    pub power_up_us: u64,
    /// The first conversion completes this long after power-on or Soft_Reset, µs (default
    /// 15 500).
    pub first_conversion_us: u64,
    /// Noise of one result, °C rms (default 0.005).
    pub noise_rms_c: f64,
}

impl Default for Tmp117Config {
    fn default() -> Self {
        Self {
            power_up_us: 1_500,
            first_conversion_us: 15_500,
            noise_rms_c: 0.005,
        }
    }
}

/// The TMP117's state.
#[derive(Debug, Clone)]
pub(crate) struct Tmp117Model {
    config: Tmp117Config,
    rng: Xoshiro256PlusPlus,
    power_on_ns: u64,
    pointer: u8,
    configuration: u16,
    high_limit: u16,
    low_limit: u16,
    temperature_offset: u16,
    temp_result: u16,
    data_ready: bool,
    next_conversion_ns: Option<u64>,
}

impl Tmp117Model {
    pub(crate) fn new(config: Tmp117Config, seed: u64, power_on_ns: u64) -> Self {
        let mut model = Self {
            config,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            power_on_ns,
            pointer: 0,
            configuration: CONFIGURATION_RESET,
            high_limit: THIGH_LIMIT_RESET,
            low_limit: TLOW_LIMIT_RESET,
            temperature_offset: 0,
            temp_result: TEMP_RESULT_RESET,
            data_ready: false,
            next_conversion_ns: None,
        };
        model.restart(power_on_ns);
        model
    }

    /// Whether the device acknowledges its address at `now_ns`.
    pub(crate) fn answers(&self, now_ns: u64) -> bool {
        now_ns >= self.power_on_ns + self.config.power_up_us * 1_000
    }

    /// Power removed and restored at `now_ns`.
    pub(crate) fn power_cycle(&mut self, now_ns: u64) {
        self.power_on_ns = now_ns;
        self.pointer = 0;
        self.restart(now_ns);
    }

    /// Power removed (the pad unplugged): registers at reset, nothing converts;
    /// [`Self::power_cycle`] brings it back.
    pub(crate) fn power_off(&mut self) {
        self.pointer = 0;
        self.restart(self.power_on_ns);
        self.next_conversion_ns = None;
    }

    fn restart(&mut self, now_ns: u64) {
        self.configuration = CONFIGURATION_RESET;
        self.high_limit = THIGH_LIMIT_RESET;
        self.low_limit = TLOW_LIMIT_RESET;
        self.temperature_offset = 0;
        self.temp_result = TEMP_RESULT_RESET;
        self.data_ready = false;
        self.next_conversion_ns = Some(now_ns + self.config.first_conversion_us * 1_000);
    }

    /// Completion time of the next conversion, if one is scheduled.
    pub(crate) fn next_event_ns(&self) -> Option<u64> {
        self.next_conversion_ns
    }

    /// Completes the next conversion (at [`Self::next_event_ns`]).
    pub(crate) fn complete_conversion(&mut self, environment: &mut Environment<'_>) {
        let Some(time_ns) = self.next_conversion_ns else {
            return;
        };
        let standard_normal: f64 = self.rng.sample(StandardNormal);
        let temperature_c = environment.scene.sample(time_ns / 1_000).temperature_c as f64;
        let temperature_c = if temperature_c.is_finite() {
            temperature_c
        } else {
            25.0
        };
        let result_lsb = ((temperature_c + standard_normal * self.config.noise_rms_c) * LSB_PER_C)
            .round()
            + self.temperature_offset as i16 as f64;
        self.temp_result = result_lsb.clamp(i16::MIN as f64, i16::MAX as f64) as i16 as u16;
        self.data_ready = true;
        environment.counters.temperature_conversions += 1;
        if let Some(pad) = environment.pad_counters() {
            pad.temperature_conversions += 1;
        }
        self.next_conversion_ns = match self.mode() {
            MOD_SHUTDOWN => None,
            MOD_ONE_SHOT => {
                self.configuration =
                    (self.configuration & !(0b11 << MOD_SHIFT)) | (MOD_SHUTDOWN << MOD_SHIFT);
                None
            }
            _ => Some(time_ns + self.cycle_us() * 1_000),
        };
    }

    /// Handles the data bytes of one write operation.
    pub(crate) fn write(&mut self, bytes: &[u8], now_ns: u64, environment: &mut Environment<'_>) {
        let Some((&pointer, data)) = bytes.split_first() else {
            return;
        };
        self.pointer = pointer;
        let [high, low, ..] = *data else {
            return;
        };
        let value = u16::from_be_bytes([high, low]);
        match pointer {
            CONFIGURATION if value & SOFT_RESET != 0 => {
                self.restart(now_ns);
                environment.faults.end_until_reset(Device::Tmp117);
                environment.counters.software_resets += 1;
            }
            CONFIGURATION => self.write_configuration(value & CONFIGURATION_WRITABLE, now_ns),
            THIGH_LIMIT => self.high_limit = value,
            TLOW_LIMIT => self.low_limit = value,
            TEMP_OFFSET => self.temperature_offset = value,
            _ => environment.counters.ignored_writes += 1,
        }
    }

    /// Fills the buffer of one read operation.
    pub(crate) fn read(
        &mut self,
        buffer: &mut [u8],
        now_ns: u64,
        environment: &mut Environment<'_>,
    ) {
        if buffer.is_empty() {
            return;
        }
        let value = match self.pointer {
            TEMP_RESULT => {
                self.data_ready = false;
                match environment
                    .faults
                    .take(now_ns / 1_000, |fault| match fault {
                        Fault::TemperatureStuck { temp_result } => Some(*temp_result),
                        _ => None,
                    }) {
                    Some(stuck) => {
                        environment.counters.stuck_temperature_reads += 1;
                        stuck
                    }
                    None => self.temp_result,
                }
            }
            CONFIGURATION => {
                let value = self.peek_register(CONFIGURATION);
                self.data_ready = false;
                value
            }
            pointer => self.peek_register(pointer),
        };
        for (byte, source) in buffer
            .iter_mut()
            .zip(value.to_be_bytes().into_iter().cycle())
        {
            *byte = source;
        }
    }

    /// The register's value as a read would return it, without a read's side effects.
    pub(crate) fn peek_register(&self, pointer: u8) -> u16 {
        match pointer {
            TEMP_RESULT => self.temp_result,
            CONFIGURATION => self.configuration | if self.data_ready { DATA_READY } else { 0 },
            THIGH_LIMIT => self.high_limit,
            TLOW_LIMIT => self.low_limit,
            TEMP_OFFSET => self.temperature_offset,
            DEVICE_ID => DEVICE_ID_VALUE,
            _ => 0,
        }
    }

    fn write_configuration(&mut self, value: u16, now_ns: u64) {
        self.configuration = value;
        let active_ns = ACTIVE_CONVERSION_US[self.averaging_index()] * 1_000;
        match self.mode() {
            MOD_SHUTDOWN => self.next_conversion_ns = None,
            MOD_ONE_SHOT => self.next_conversion_ns = Some(now_ns + active_ns),
            _ => {
                if self.next_conversion_ns.is_none() {
                    self.next_conversion_ns = Some(now_ns + active_ns);
                }
            }
        }
    }

    fn mode(&self) -> u16 {
        (self.configuration >> MOD_SHIFT) & 0b11
    }

    fn averaging_index(&self) -> usize {
        ((self.configuration >> AVG_SHIFT) & 0b11) as usize
    }

    fn cycle_us(&self) -> u64 {
        CYCLE_US[((self.configuration >> CONV_SHIFT) & 0b111) as usize][self.averaging_index()]
    }
}
