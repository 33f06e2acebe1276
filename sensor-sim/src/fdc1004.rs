//! The simulated TI FDC1004 (datasheet SNOSCY5B) at register level.
//!
//! Protocol: a write of `[pointer]` sets the register pointer; `[pointer, msb, lsb]` also writes
//! the register (further bytes are ignored: the pointer does not auto-increment); a read returns
//! the 16-bit big-endian register at the pointer (bytes past the second repeat the same two).
//! Writes to read-only registers (results, IDs, unknown pointers) are ignored; unknown pointers
//! read 0.
//!
//! Registers: MEAS1..4_MSB/LSB 0x00..0x07, CONF_MEAS1..4 0x08..0x0B (reset 0x1C00), FDC_CONF 0x0C
//! (RST bit 15, RATE 11:10, REPEAT 8, MEAS_1..4 enables 7:4 with bit 7 = MEAS_1, DONE_1..4 3:0
//! with bit 3 = DONE_1, read-only), OFFSET_CAL_CIN1..4 0x0D..0x10, GAIN_CAL_CIN1..4 0x11..0x14
//! (reset 0x4000), MANUFACTURER_ID 0xFE = 0x5449, DEVICE_ID 0xFF = 0x1004.
//!
//! Behaviour, and the assumptions where the datasheet is silent:
//! - **Timing.** Writing FDC_CONF with measurements enabled (and a valid RATE) starts them at
//!   the write: the enabled measurements complete one after another in ascending order, each
//!   taking 1/R (R = 100, 200 or 400 S/s), so with k enabled each one refreshes every k/R
//!   (100 Hz per taxel at 400 S/s with four enabled; the reading of the forum reports the notes
//!   ask to verify). REPEAT = 1 cycles for ever; REPEAT = 0 runs the enabled ones once. RATE = 00
//!   (reserved) runs nothing. Every write to FDC_CONF restarts the sequence and clears DONE.
//! - **DONE.** DONE_n sets when measurement n completes. The datasheet (8.5.3.4) says "once the
//!   measurement read is complete, the corresponding DONE_x field will return to 0", which does
//!   not say which of the two result reads completes it: here DONE_n clears when MEASn_MSB is
//!   read, the read that takes (latches) the result.
//! - **Latching.** Reading MEASn_MSB latches the 24-bit result, so the following MEASn_LSB read
//!   belongs to the same conversion even if a new one completed in between; the LSB read
//!   releases the latch (an LSB read without a latch gives the newest result).
//! - **Result.** `code = round((C(CHA) - C(CHB)) * 2^19 + noise)`, where C(CHB) is
//!   3.125 pF x CAPDAC for CHB = 100, 0 for CHB = 111 (or reserved), and the input's
//!   capacitance for CHB = CIN1..CIN4 (differential). CHA = 1xx (reserved) reads as 0 pF.
//!   Codes at or beyond the 24-bit range (about +-16 pF around the offset) are the saturation
//!   codes 0x7FFFFF / 0x800000. OFFSET_CAL and GAIN_CAL are stored and read back but not
//!   applied (the project's driver leaves them at reset).
//! - **Noise.** Gaussian, 0.5 fF rms at 100 S/s by default, scaled by sqrt(R / 100) for the
//!   faster rates (1/sqrt(conversion time), as for white noise averaged over the conversion),
//!   drawn once per conversion from a seeded generator whatever faults apply.
//! - **Software reset.** Writing RST restores every register to its reset value, stops the
//!   measurements, ends the channel shift and the faults that last until a reset; RST reads
//!   back as 1 for [`Fdc1004Config::reset_duration_us`] (an assumption: the datasheet gives no
//!   time).
//! - **Power-up.** The device does not acknowledge its address until
//!   [`Fdc1004Config::power_up_us`] after power-on (users report about 5 ms).
//! - **MCU-only reset.** After one, the device keeps its configuration but measurement n
//!   converts the input after the one its CHA selects (CIN1 -> CIN2, ..., CIN4 -> CIN1) until
//!   a software reset. By default CONF_MEASn still reads back what was written (the values are
//!   wrong, the configuration looks right); with
//!   [`Fdc1004Config::channel_shift_visible_in_readback`] CHA reads back rotated, so a driver's
//!   read-back check sees it.

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

use crate::fault::{Device, Fault};
use crate::simulation::Environment;

const MEAS1_MSB: u8 = 0x00;
const MEAS4_LSB: u8 = 0x07;
const CONF_MEAS1: u8 = 0x08;
const CONF_MEAS4: u8 = 0x0B;
const FDC_CONF: u8 = 0x0C;
const OFFSET_CAL_CIN1: u8 = 0x0D;
const OFFSET_CAL_CIN4: u8 = 0x10;
const GAIN_CAL_CIN1: u8 = 0x11;
const GAIN_CAL_CIN4: u8 = 0x14;
const MANUFACTURER_ID: u8 = 0xFE;
const DEVICE_ID: u8 = 0xFF;

const MANUFACTURER_ID_VALUE: u16 = 0x5449;
const DEVICE_ID_VALUE: u16 = 0x1004;
const CONF_MEAS_RESET: u16 = 0x1C00;
const GAIN_CAL_RESET: u16 = 0x4000;
/// CONF_MEASn bits 4:0 are reserved and read 0.
const CONF_MEAS_WRITABLE: u16 = 0xFFE0;
const RST: u16 = 1 << 15;
/// RATE, REPEAT and MEAS_1..4: the FDC_CONF bits a write keeps.
const FDC_CONF_WRITABLE: u16 = 0x0DF0;
const RATE_SHIFT: u16 = 10;
const REPEAT: u16 = 1 << 8;
const MEAS_ENABLE_SHIFT: u16 = 4;
const CHA_SHIFT: u16 = 13;
const CHB_SHIFT: u16 = 10;
const CAPDAC_SHIFT: u16 = 5;
const CHB_CAPDAC: u16 = 0b100;

/// Capacitance of one CAPDAC step, pF.
const CAPDAC_STEP_PF: f64 = 3.125;
/// Result codes per pF (2^19).
const CODES_PER_PF: f64 = 524_288.0;
const SATURATED_HIGH: i32 = 0x7F_FFFF;
const SATURATED_LOW: i32 = -0x80_0000;

/// Settings of the simulated FDC1004.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fdc1004Config {
    /// Noise of one result at 100 S/s, pF rms (default 0.0005 = 0.5 fF, about 16 effective
    /// bits); scaled by sqrt(R / 100) at the faster rates.
    pub noise_rms_pf_at_100_sps: f64,
    /// The address is not acknowledged until this long after power-on, µs (default 5000).
    pub power_up_us: u64,
    /// RST reads back as 1 for this long after a software reset, µs (default 50).
    pub reset_duration_us: u64,
    /// While the channel shift is active, CONF_MEASn reads back with CHA rotated like the
    /// measurement (default false: it reads back what was written).
    pub channel_shift_visible_in_readback: bool,
}

impl Default for Fdc1004Config {
    fn default() -> Self {
        Self {
            noise_rms_pf_at_100_sps: 0.0005,
            power_up_us: 5_000,
            reset_duration_us: 50,
            channel_shift_visible_in_readback: false,
        }
    }
}

/// The running measurement sequence.
#[derive(Debug, Clone, Copy)]
struct Sequence {
    start_ns: u64,
    period_ns: u64,
    completed: u64,
    enabled: [usize; 4],
    enabled_count: usize,
    repeat: bool,
}

impl Sequence {
    fn next_completion_ns(&self) -> u64 {
        self.start_ns + (self.completed + 1) * self.period_ns
    }
}

/// The FDC1004's state.
#[derive(Debug, Clone)]
pub(crate) struct Fdc1004Model {
    config: Fdc1004Config,
    rng: Xoshiro256PlusPlus,
    power_on_ns: u64,
    pointer: u8,
    conf_meas: [u16; 4],
    fdc_conf: u16,
    done: u16,
    results: [i32; 4],
    latched: [Option<i32>; 4],
    offset_cal: [u16; 4],
    gain_cal: [u16; 4],
    reset_until_ns: u64,
    channel_shift: bool,
    sequence: Option<Sequence>,
}

impl Fdc1004Model {
    pub(crate) fn new(config: Fdc1004Config, seed: u64, power_on_ns: u64) -> Self {
        Self {
            config,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            power_on_ns,
            pointer: 0,
            conf_meas: [CONF_MEAS_RESET; 4],
            fdc_conf: 0,
            done: 0,
            results: [0; 4],
            latched: [None; 4],
            offset_cal: [0; 4],
            gain_cal: [GAIN_CAL_RESET; 4],
            reset_until_ns: 0,
            channel_shift: false,
            sequence: None,
        }
    }

    /// Whether the device acknowledges its address at `now_ns`.
    pub(crate) fn answers(&self, now_ns: u64) -> bool {
        now_ns >= self.power_on_ns + self.config.power_up_us * 1_000
    }

    /// Power removed and restored at `now_ns`: everything at reset, the noise stream continues.
    pub(crate) fn power_cycle(&mut self, now_ns: u64) {
        self.restore_reset_values();
        self.pointer = 0;
        self.reset_until_ns = 0;
        self.power_on_ns = now_ns;
    }

    /// Power removed (the pad unplugged): everything at reset, nothing converts; the noise
    /// stream continues. [`Self::power_cycle`] brings it back.
    pub(crate) fn power_off(&mut self) {
        self.restore_reset_values();
        self.pointer = 0;
        self.reset_until_ns = 0;
    }

    pub(crate) fn simulate_mcu_only_reset(&mut self) {
        self.channel_shift = true;
    }

    pub(crate) fn channel_shift_active(&self) -> bool {
        self.channel_shift
    }

    /// Completion time of the next conversion, if one is running.
    pub(crate) fn next_event_ns(&self) -> Option<u64> {
        self.sequence.map(|sequence| sequence.next_completion_ns())
    }

    /// Completes the next conversion (at [`Self::next_event_ns`]).
    pub(crate) fn complete_conversion(&mut self, environment: &mut Environment<'_>) {
        let Some(mut sequence) = self.sequence else {
            return;
        };
        let time_ns = sequence.next_completion_ns();
        let time_us = time_ns / 1_000;
        let measurement =
            sequence.enabled[(sequence.completed % sequence.enabled_count as u64) as usize];
        sequence.completed += 1;
        let finished = !sequence.repeat && sequence.completed >= sequence.enabled_count as u64;
        self.sequence = if finished { None } else { Some(sequence) };

        let standard_normal: f64 = self.rng.sample(StandardNormal);
        let noise_pf = standard_normal * self.noise_rms_pf();

        if environment
            .faults
            .take(time_us, |fault| {
                matches!(fault, Fault::DoneStuck).then_some(())
            })
            .is_some()
        {
            environment.counters.conversions_stalled += 1;
            return;
        }

        let conf = self.conf_meas[measurement];
        let positive_input = self.effective_input((conf >> CHA_SHIFT) & 0b111);
        let frozen = positive_input.is_some_and(|input| {
            environment
                .faults
                .take(time_us, |fault| {
                    matches!(fault, Fault::FrozenResult { taxel } if *taxel == input).then_some(())
                })
                .is_some()
        });
        if frozen {
            environment.counters.frozen_conversions += 1;
            self.complete_measurement(measurement, environment);
            return;
        }
        let negative_field = (conf >> CHB_SHIFT) & 0b111;
        let capdac = (conf >> CAPDAC_SHIFT) & 0b1_1111;
        let point = environment.scene.sample(time_us);
        let input_pf = |input: usize, environment: &mut Environment<'_>| {
            input_capacitance_pf(
                input,
                point.pressure_kpa[input],
                point.temperature_c,
                time_us,
                environment,
            )
        };
        let positive_pf = positive_input.map_or(0.0, |input| input_pf(input, environment));
        let negative_pf = match negative_field {
            0..=3 => input_pf(negative_field as usize, environment),
            CHB_CAPDAC => CAPDAC_STEP_PF * capdac as f64,
            _ => 0.0,
        };
        let unclamped_code = ((positive_pf - negative_pf + noise_pf) * CODES_PER_PF).round();
        let mut code = if unclamped_code >= SATURATED_HIGH as f64 {
            SATURATED_HIGH
        } else if unclamped_code <= SATURATED_LOW as f64 {
            SATURATED_LOW
        } else {
            unclamped_code as i32
        };
        if let Some(high) = positive_input.and_then(|input| {
            environment.faults.take(time_us, |fault| match fault {
                Fault::Saturated { taxel, high } if *taxel == input => Some(*high),
                _ => None,
            })
        }) {
            environment.counters.saturations_injected += 1;
            code = if high { SATURATED_HIGH } else { SATURATED_LOW };
        }
        if code == SATURATED_HIGH || code == SATURATED_LOW {
            environment.counters.saturated_codes += 1;
        }
        self.results[measurement] = code;
        self.complete_measurement(measurement, environment);
    }

    /// Sets measurement `measurement`'s DONE bit and counts its conversion.
    fn complete_measurement(&mut self, measurement: usize, environment: &mut Environment<'_>) {
        self.done |= done_bit(measurement);
        environment.counters.conversions += 1;
        environment.counters.conversions_per_measurement[measurement] += 1;
        if let Some(pad) = environment.pad_counters() {
            pad.conversions += 1;
        }
    }

    /// Handles the data bytes of one write operation.
    pub(crate) fn write(&mut self, bytes: &[u8], now_ns: u64, environment: &mut Environment<'_>) {
        let Some((&pointer, data)) = bytes.split_first() else {
            return;
        };
        self.pointer = pointer;
        if let [high, low, ..] = *data {
            self.write_register(
                pointer,
                u16::from_be_bytes([high, low]),
                now_ns,
                environment,
            );
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
        let value = self.read_register(self.pointer, now_ns, environment);
        for (byte, source) in buffer
            .iter_mut()
            .zip(value.to_be_bytes().into_iter().cycle())
        {
            *byte = source;
        }
    }

    /// The register's value as a read would return it, without a read's side effects.
    pub(crate) fn peek_register(&self, pointer: u8, now_ns: u64) -> u16 {
        match pointer {
            MEAS1_MSB..=MEAS4_LSB => {
                let measurement = (pointer / 2) as usize;
                if pointer.is_multiple_of(2) {
                    msb_register(self.results[measurement])
                } else {
                    lsb_register(self.latched[measurement].unwrap_or(self.results[measurement]))
                }
            }
            CONF_MEAS1..=CONF_MEAS4 => {
                let conf = self.conf_meas[(pointer - CONF_MEAS1) as usize];
                if self.channel_shift && self.config.channel_shift_visible_in_readback {
                    let shifted = self
                        .effective_input((conf >> CHA_SHIFT) & 0b111)
                        .map_or((conf >> CHA_SHIFT) & 0b111, |input| input as u16);
                    (conf & !(0b111 << CHA_SHIFT)) | (shifted << CHA_SHIFT)
                } else {
                    conf
                }
            }
            FDC_CONF => {
                let resetting = if now_ns < self.reset_until_ns { RST } else { 0 };
                self.fdc_conf | self.done | resetting
            }
            OFFSET_CAL_CIN1..=OFFSET_CAL_CIN4 => {
                self.offset_cal[(pointer - OFFSET_CAL_CIN1) as usize]
            }
            GAIN_CAL_CIN1..=GAIN_CAL_CIN4 => self.gain_cal[(pointer - GAIN_CAL_CIN1) as usize],
            MANUFACTURER_ID => MANUFACTURER_ID_VALUE,
            DEVICE_ID => DEVICE_ID_VALUE,
            _ => 0,
        }
    }

    fn read_register(
        &mut self,
        pointer: u8,
        now_ns: u64,
        environment: &mut Environment<'_>,
    ) -> u16 {
        match pointer {
            MEAS1_MSB..=MEAS4_LSB if pointer.is_multiple_of(2) => {
                let measurement = (pointer / 2) as usize;
                let zero = environment
                    .faults
                    .take(now_ns / 1_000, |fault| {
                        matches!(fault, Fault::ZeroReads).then_some(())
                    })
                    .is_some();
                let code = if zero {
                    environment.counters.zero_reads_injected += 1;
                    0
                } else {
                    self.results[measurement]
                };
                self.latched[measurement] = Some(code);
                self.done &= !done_bit(measurement);
                msb_register(code)
            }
            MEAS1_MSB..=MEAS4_LSB => {
                let measurement = (pointer / 2) as usize;
                let code = self.latched[measurement]
                    .take()
                    .unwrap_or(self.results[measurement]);
                lsb_register(code)
            }
            _ => self.peek_register(pointer, now_ns),
        }
    }

    fn write_register(
        &mut self,
        pointer: u8,
        value: u16,
        now_ns: u64,
        environment: &mut Environment<'_>,
    ) {
        match pointer {
            CONF_MEAS1..=CONF_MEAS4 => {
                self.conf_meas[(pointer - CONF_MEAS1) as usize] = value & CONF_MEAS_WRITABLE;
            }
            FDC_CONF if value & RST != 0 => self.software_reset(now_ns, environment),
            FDC_CONF => {
                self.fdc_conf = value & FDC_CONF_WRITABLE;
                self.done = 0;
                self.sequence = self.start_sequence(now_ns);
            }
            OFFSET_CAL_CIN1..=OFFSET_CAL_CIN4 => {
                self.offset_cal[(pointer - OFFSET_CAL_CIN1) as usize] = value;
            }
            GAIN_CAL_CIN1..=GAIN_CAL_CIN4 => {
                self.gain_cal[(pointer - GAIN_CAL_CIN1) as usize] = value;
            }
            _ => environment.counters.ignored_writes += 1,
        }
    }

    fn software_reset(&mut self, now_ns: u64, environment: &mut Environment<'_>) {
        self.restore_reset_values();
        self.reset_until_ns = now_ns + self.config.reset_duration_us * 1_000;
        environment.faults.end_until_reset(Device::Fdc1004);
        environment.counters.software_resets += 1;
    }

    fn restore_reset_values(&mut self) {
        self.conf_meas = [CONF_MEAS_RESET; 4];
        self.fdc_conf = 0;
        self.done = 0;
        self.results = [0; 4];
        self.latched = [None; 4];
        self.offset_cal = [0; 4];
        self.gain_cal = [GAIN_CAL_RESET; 4];
        self.channel_shift = false;
        self.sequence = None;
    }

    fn start_sequence(&self, now_ns: u64) -> Option<Sequence> {
        let samples_per_second: u64 = match (self.fdc_conf >> RATE_SHIFT) & 0b11 {
            0b01 => 100,
            0b10 => 200,
            0b11 => 400,
            _ => return None,
        };
        let mut enabled = [0usize; 4];
        let mut enabled_count = 0;
        for measurement in 0..4 {
            if self.fdc_conf & (1 << (MEAS_ENABLE_SHIFT + 3 - measurement as u16)) != 0 {
                enabled[enabled_count] = measurement;
                enabled_count += 1;
            }
        }
        (enabled_count > 0).then_some(Sequence {
            start_ns: now_ns,
            period_ns: 1_000_000_000 / samples_per_second,
            completed: 0,
            enabled,
            enabled_count,
            repeat: self.fdc_conf & REPEAT != 0,
        })
    }

    fn noise_rms_pf(&self) -> f64 {
        let samples_per_second = match (self.fdc_conf >> RATE_SHIFT) & 0b11 {
            0b10 => 200.0,
            0b11 => 400.0,
            _ => 100.0,
        };
        self.config.noise_rms_pf_at_100_sps * (samples_per_second / 100.0f64).sqrt()
    }

    /// The input a CHA (or CHB) field value converts, after the channel shift.
    fn effective_input(&self, field: u16) -> Option<usize> {
        let input = match field {
            0..=3 => field as usize,
            _ => return None,
        };
        Some(if self.channel_shift {
            (input + 1) % 4
        } else {
            input
        })
    }
}

/// DONE_n of measurement n (0-based): bit 3 is DONE_1.
const fn done_bit(measurement: usize) -> u16 {
    1 << (3 - measurement)
}

const fn msb_register(code: i32) -> u16 {
    ((code >> 8) & 0xFFFF) as u16
}

const fn lsb_register(code: i32) -> u16 {
    ((code & 0xFF) << 8) as u16
}

/// What the converter sees on an input: the physics, unless a fault replaces it.
fn input_capacitance_pf(
    input: usize,
    pressure_kpa: f32,
    temperature_c: f32,
    time_us: u64,
    environment: &mut Environment<'_>,
) -> f64 {
    let parasitic_pf = environment.physics.physics().taxels[input].parasitic_pf;
    let replaced = environment.faults.take(time_us, |fault| match fault {
        Fault::Shorted {
            taxel,
            capacitance_pf,
        } if *taxel == input => Some((*capacitance_pf, true)),
        Fault::OpenLead {
            taxel,
            capacitance_pf,
        } if *taxel == input => Some((capacitance_pf.unwrap_or(parasitic_pf), false)),
        _ => None,
    });
    match replaced {
        Some((capacitance_pf, shorted)) => {
            if shorted {
                environment.counters.shorted_conversions += 1;
            } else {
                environment.counters.open_conversions += 1;
            }
            capacitance_pf as f64
        }
        None => environment
            .physics
            .convert(input, pressure_kpa, temperature_c),
    }
}
