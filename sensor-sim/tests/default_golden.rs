//! The default single-pad simulation, byte for byte: a fixed script of register accesses, faults
//! and delays with the default seed, its bus time and noise on, hashed. The expected values were
//! recorded from the simulator before the multiplexer topology existed; any change to what the
//! default setup puts on the bus changes the hash.

mod common;

use common::*;
use sensor_sim::{Device, Fault, Keyframe, ScriptedScene, SimI2c, Simulation, Window};

/// FNV-1a, 64 bits.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xCBF2_9CE4_8422_2325)
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.0 ^= byte as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01B3);
        }
    }

    fn u64(&mut self, value: u64) {
        self.bytes(&value.to_le_bytes());
    }
}

fn read(bus: &mut SimI2c, hash: &mut Fnv, address: u8, pointer: u8) {
    match read_register(bus, address, pointer) {
        Ok(value) => hash.bytes(&value.to_be_bytes()),
        Err(_) => hash.bytes(b"nack"),
    }
}

/// The script; returns the hash of every byte read, NACK and clock reading, and the counters
/// that existed before the multiplexer.
fn run_script() -> TestResult<(u64, [u64; 12])> {
    let simulation = Simulation::default();
    let scene = ScriptedScene::new(vec![
        Keyframe::new(0.0, [0.0, 0.0, 0.0, 0.0], 25.0),
        Keyframe::new(0.05, [12.0, 3.0, 0.0, 40.0], 31.0),
        Keyframe::new(0.1, [0.0, 25.0, 8.0, 2.0], 28.0),
    ])?;
    simulation.set_scene(scene);
    let mut bus = simulation.i2c();
    let mut hash = Fnv::new();
    // Still powering up: NACKs.
    read(&mut bus, &mut hash, FDC1004, DEVICE_ID);
    read(&mut bus, &mut hash, TMP117, TMP117_DEVICE_ID);
    simulation.advance_us(POWERED_UP_US);
    read(&mut bus, &mut hash, FDC1004, DEVICE_ID);
    read(&mut bus, &mut hash, FDC1004, MANUFACTURER_ID);
    read(&mut bus, &mut hash, TMP117, TMP117_DEVICE_ID);
    read(&mut bus, &mut hash, 0x33, 0x00);
    start_all(&mut bus, RATE_400)?;
    simulation.inject(Fault::Nack(Device::Fdc1004), Window::Next(2));
    simulation.inject(Fault::DoneStuck, Window::Next(1));
    simulation.inject(Fault::ZeroReads, Window::Next(1));
    for step in 0..40u64 {
        simulation.advance_us(2_500);
        read(&mut bus, &mut hash, FDC1004, FDC_CONF);
        for measurement in 0..4 {
            match read_result(&mut bus, measurement) {
                Ok(code) => hash.bytes(&code.to_le_bytes()),
                Err(_) => hash.bytes(b"nack"),
            }
        }
        read(&mut bus, &mut hash, TMP117, CONFIGURATION);
        read(&mut bus, &mut hash, TMP117, TEMP_RESULT);
        if step == 20 {
            simulation.simulate_mcu_only_reset();
        }
        hash.u64(simulation.now_ns());
    }
    let counters = simulation.counters();
    Ok((
        hash.0,
        [
            counters.transactions,
            counters.fdc1004_transactions,
            counters.tmp117_transactions,
            counters.nacks,
            counters.nacks_injected,
            counters.nacks_powering_up,
            counters.nacks_unknown_address,
            counters.conversions,
            counters.conversions_stalled,
            counters.zero_reads_injected,
            counters.temperature_conversions,
            simulation.now_ns(),
        ],
    ))
}

#[test]
fn the_default_simulation_puts_the_same_bytes_on_the_bus() {
    let (hash, counters) = run_script().unwrap();
    assert_eq!(hash, GOLDEN_HASH);
    assert_eq!(counters, GOLDEN_COUNTERS);
}

const GOLDEN_HASH: u64 = 0xD308_EB58_4B4F_8363;
const GOLDEN_COUNTERS: [u64; 12] = [450, 367, 82, 5, 2, 2, 1, 60, 1, 1, 1, 158_412_500];
