//! The sample-set rate each pad reaches with several pads on one sensor bus, measured on the
//! simulated device: the firmware's discovery, acquisition and device code on simulated
//! FDC1004s, a shared TMP117 and a TCA9548A whose transactions take their time at the bus
//! clock (start, address, data bytes with acknowledges, stop). Simulated time, so the figures do
//! not depend on the machine that computes them.

use std::fmt::Write;

use anyhow::{anyhow, Result};
use device::{HostInputEvent, HostPort, Outgoing, QueueFull};
use sim_device::{pads_topology, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::DeviceFrame;

/// The pad counts measured.
pub const PAD_COUNTS: [usize; 5] = [1, 2, 4, 6, 8];
/// The bus clocks measured: standard and fast mode.
pub const BUS_FREQUENCIES_HZ: [u32; 2] = [100_000, 400_000];
/// Boot, converter initialisation and the start-up tare, not measured.
const WARM_UP_US: u64 = 1_000_000;
/// Simulated time measured after the warm-up.
const MEASURED_US: u64 = 4_000_000;
const SEED: u64 = 1;
/// Pad indices the wire carries.
const PAD_SLOTS: usize = wire::PadIndex::MAX as usize + 1;

/// One pad count at one bus clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadRate {
    /// Pads on the bus.
    pub pads: usize,
    /// The bus clock, Hz.
    pub bus_frequency_hz: u32,
    /// Sample sets per second of the slowest pad.
    pub slowest_pad_sets_per_s: f64,
    /// Sample sets per second of the fastest pad.
    pub fastest_pad_sets_per_s: f64,
    /// Bus transactions per sample set of all pads.
    pub transactions_per_set: f64,
}

/// Counts each pad's sample frames within the measured window.
struct CountingPort {
    frames_per_pad: [u64; PAD_SLOTS],
}

impl HostPort for CountingPort {
    fn host_connected(&mut self) -> bool {
        true
    }

    fn try_receive(&mut self) -> Option<HostInputEvent> {
        None
    }

    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull> {
        if let Outgoing::Frame(DeviceFrame::Sample(frame)) = outgoing {
            let measured = WARM_UP_US..WARM_UP_US + MEASURED_US;
            if measured.contains(&frame.timestamp_us) {
                if let Some(count) = self.frames_per_pad.get_mut(usize::from(frame.pad.get())) {
                    *count += 1;
                }
            }
        }
        Ok(())
    }
}

/// Runs the simulated device with `pads` pads at `bus_frequency_hz`.
pub fn measure_one(pads: usize, bus_frequency_hz: u32) -> Result<PadRate> {
    let scene = SceneFile::default_scene().map_err(|error| anyhow!("default scene: {error:?}"))?;
    let mut device = SimulatedDevice::new(SimulatedDeviceConfig {
        scene,
        seed: SEED,
        speed: None,
        topology: pads_topology(pads),
        bus_frequency_hz: Some(bus_frequency_hz),
    })
    .map_err(|error| anyhow!("starting the simulated device: {error}"))?;
    let mut port = CountingPort {
        frames_per_pad: [0; PAD_SLOTS],
    };
    while device.simulation().now_us() < WARM_UP_US {
        device.step(&mut port);
    }
    let transactions_before = device.simulation().counters().transactions;
    let mut sets = 0u64;
    while device.simulation().now_us() < WARM_UP_US + MEASURED_US {
        device.step(&mut port);
        sets += 1;
    }
    let transactions = device.simulation().counters().transactions - transactions_before;
    let per_s = |frames: u64| frames as f64 / (MEASURED_US as f64 / 1e6);
    let counts = port.frames_per_pad.get(..pads).unwrap_or_default();
    let slowest = counts.iter().copied().min().unwrap_or(0);
    let fastest = counts.iter().copied().max().unwrap_or(0);
    Ok(PadRate {
        pads,
        bus_frequency_hz,
        slowest_pad_sets_per_s: per_s(slowest),
        fastest_pad_sets_per_s: per_s(fastest),
        transactions_per_set: transactions as f64 / sets.max(1) as f64,
    })
}

/// Every pad count at every bus clock.
pub fn measure() -> Result<Vec<PadRate>> {
    let mut rates = Vec::new();
    for bus_frequency_hz in BUS_FREQUENCIES_HZ {
        for pads in PAD_COUNTS {
            rates.push(measure_one(pads, bus_frequency_hz)?);
        }
    }
    Ok(rates)
}

/// The rates as the report's Markdown table, with how they were measured.
pub fn table(rates: &[PadRate]) -> String {
    let mut out = String::new();
    let out = &mut out;
    let _ = writeln!(
        out,
        "Measured on the simulated device (`xtask/src/pad_rates.rs`): the firmware's discovery, \
         acquisition and device code with 2 to 8 pads behind the simulated TCA9548A (one \
         FDC1004 per channel, converting in repeat mode at 400 conversions/s, and a TMP117 on \
         the main bus that every pad reads) and 1 pad as the single-pad board carries it, \
         directly on the bus with no multiplexer (so its transactions per set include no \
         channel selection), each I2C transaction taking its time at the bus \
         clock (start, 9 bits per byte with the acknowledge, stop). Pads are read in turn \
         within a sample set; 4 simulated seconds after 1 s of boot and start-up tare. The \
         converters convert in parallel, so a set costs one conversion cycle (10 ms) as long \
         as reading every pad takes less; beyond that the bus sets the rate.\n"
    );
    let _ = writeln!(
        out,
        "| pads | bus clock | sample sets/s per pad (slowest, fastest pad) | I2C transactions \
         per set |\n|---|---|---|---|"
    );
    for rate in rates {
        let _ = writeln!(
            out,
            "| {}{} | {} kHz | {:.1}, {:.1} | {:.1} |",
            rate.pads,
            if rate.pads == 1 {
                " (no multiplexer)"
            } else {
                ""
            },
            rate.bus_frequency_hz / 1000,
            rate.slowest_pad_sets_per_s,
            rate.fastest_pad_sets_per_s,
            rate.transactions_per_set
        );
    }
    let _ = writeln!(out);
    std::mem::take(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_pads_at_fast_mode_keep_the_converter_rate() {
        let rate = measure_one(2, 400_000).unwrap();
        // 400 conversions/s, four per set: 100 sets/s per pad when the bus keeps up.
        assert!(
            (95.0..=101.0).contains(&rate.slowest_pad_sets_per_s),
            "{rate:?}"
        );
        assert!(rate.transactions_per_set > 10.0, "{rate:?}");
    }
}
