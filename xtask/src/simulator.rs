//! Throughput and latency of the simulated device (`sim_device::SimulatedDevice`: the firmware's
//! acquisition, model and protocol code on the simulated FDC1004 and TMP117), stepped as fast as
//! the host computes on one thread, every outgoing frame encoded as the firmware's USB task
//! would encode it.
//!
//! Two passes over the same steps (same scene, same seed):
//!
//! 1. **Live**: `SimulatedDevice::step` in a loop; sample sets per second over wall-clock and
//!    thread CPU time. Per step, the time from the device's last host-side call before the
//!    converter cycle (`HostPort::try_receive`, which returns nothing here) to the end of
//!    `device::encode_outgoing` of that step's sample frame: the whole cycle on the simulated
//!    bus (converter and temperature reads), the model, the frame and its encoding.
//! 2. **Replay**: before each step a copy of the pad model is taken; after it, the step's
//!    readings (as the converter and temperature sensor delivered them) go through the copy
//!    again (`PadModel::process`), then `device::sample_frame` and `device::encode_outgoing`,
//!    timed: the part after the bus reads. The replayed frame must equal the step's byte for
//!    byte, which proves it is the same work.
//!
//! Run in release mode only: `cargo xtask sim-bench` re-runs itself through
//! `cargo run --release` when it was built without optimisation.

use std::path::Path;
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use device::{HostInputEvent, HostPort, Outgoing, QueueFull, MAX_OUTGOING_LEN};
use sim_device::{SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::DeviceFrame;

use crate::bench_output::Line;
use crate::m4;

/// Steps measured by default.
pub const DEFAULT_STEPS: u32 = 200_000;
/// Steps run before the measured ones (boot, converter initialisation, the start-up tare).
pub const WARM_UP_STEPS: u32 = 1_000;
/// Noise seed of the simulated converter.
pub const SEED: u64 = 1;

/// Percentiles of one measured interval, ns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latency {
    /// Intervals measured.
    pub count: usize,
    /// Mean.
    pub mean_ns: f64,
    /// Median.
    pub p50_ns: f64,
    /// 99th percentile.
    pub p99_ns: f64,
    /// Largest.
    pub max_ns: f64,
}

impl Latency {
    /// The statistics of a set of intervals (sorted in place); None when it is empty.
    pub fn of(intervals_ns: &mut [u64]) -> Option<Self> {
        if intervals_ns.is_empty() {
            return None;
        }
        intervals_ns.sort_unstable();
        let count = intervals_ns.len();
        let percentile = |fraction: f64| {
            let rank = (fraction * count as f64).ceil() as usize;
            intervals_ns[rank.clamp(1, count) - 1] as f64
        };
        Some(Self {
            count,
            mean_ns: intervals_ns.iter().map(|value| *value as f64).sum::<f64>() / count as f64,
            p50_ns: percentile(0.50),
            p99_ns: percentile(0.99),
            max_ns: intervals_ns[count - 1] as f64,
        })
    }

    fn line(&self, interval: &str) -> String {
        format!(
            "latency interval={interval} count={} mean_ns={:.1} p50_ns={:.0} p99_ns={:.0} max_ns={:.0}",
            self.count, self.mean_ns, self.p50_ns, self.p99_ns, self.max_ns
        )
    }

    fn parse(line: &Line) -> Result<Self> {
        Ok(Self {
            count: line.number("count")? as usize,
            mean_ns: line.number("mean_ns")?,
            p50_ns: line.number("p50_ns")?,
            p99_ns: line.number("p99_ns")?,
            max_ns: line.number("max_ns")?,
        })
    }
}

/// What the measurement found.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatorFigures {
    /// Steps (sample sets) measured.
    pub steps: u32,
    /// Wall-clock time of the live pass, s.
    pub wall_seconds: f64,
    /// The thread's CPU time over the same, s.
    pub cpu_seconds: f64,
    /// Simulated time the live pass covered, s.
    pub simulated_seconds: f64,
    /// Frames encoded in the live pass (samples, counters, events).
    pub frames: u64,
    /// Sample frames among them.
    pub sample_frames: u64,
    /// Bytes encoded.
    pub bytes: u64,
    /// Simulated I2C transactions per step.
    pub transactions_per_step: f64,
    /// Live: last host-side call before the cycle to the end of the sample frame's encoding.
    pub cycle_to_frame: Latency,
    /// Replay: model, frame and encoding after the bus reads.
    pub model_to_frame: Latency,
    /// Replayed frames that differed from the step's (must be 0).
    pub replay_mismatches: u64,
}

impl SimulatorFigures {
    /// Sample sets per second of wall-clock time.
    pub fn sets_per_second_wall(&self) -> f64 {
        f64::from(self.steps) / self.wall_seconds
    }

    /// Sample sets per second of the thread's CPU time.
    pub fn sets_per_second_cpu(&self) -> f64 {
        f64::from(self.steps) / self.cpu_seconds
    }

    /// The `key=value` lines `sim-bench` prints.
    pub fn lines(&self) -> String {
        format!(
            "simulator steps={} wall_s={:.6} cpu_s={:.6} simulated_s={:.6} frames={} sample_frames={} bytes={} transactions_per_step={:.3} replay_mismatches={}\n{}\n{}\n",
            self.steps,
            self.wall_seconds,
            self.cpu_seconds,
            self.simulated_seconds,
            self.frames,
            self.sample_frames,
            self.bytes,
            self.transactions_per_step,
            self.replay_mismatches,
            self.cycle_to_frame.line("cycle-to-frame"),
            self.model_to_frame.line("model-to-frame"),
        )
    }

    /// Parses what [`SimulatorFigures::lines`] printed.
    pub fn parse(output: &str) -> Result<Self> {
        let lines: Vec<Line> = output.lines().filter_map(Line::parse).collect();
        let summary = lines
            .iter()
            .find(|line| line.kind == "simulator")
            .ok_or_else(|| anyhow!("sim-bench printed no `simulator` line:\n{output}"))?;
        let latency = |interval: &str| -> Result<Latency> {
            let line = lines
                .iter()
                .find(|line| line.kind == "latency" && line.text("interval").ok() == Some(interval))
                .ok_or_else(|| anyhow!("sim-bench printed no `{interval}` latency"))?;
            Latency::parse(line)
        };
        Ok(Self {
            steps: summary.number("steps")? as u32,
            wall_seconds: summary.number("wall_s")?,
            cpu_seconds: summary.number("cpu_s")?,
            simulated_seconds: summary.number("simulated_s")?,
            frames: summary.number("frames")? as u64,
            sample_frames: summary.number("sample_frames")? as u64,
            bytes: summary.number("bytes")? as u64,
            transactions_per_step: summary.number("transactions_per_step")?,
            replay_mismatches: summary.number("replay_mismatches")? as u64,
            cycle_to_frame: latency("cycle-to-frame")?,
            model_to_frame: latency("model-to-frame")?,
        })
    }
}

/// A host that always has the port open, sends nothing, and encodes every outgoing frame.
struct EncodingPort {
    buffer: [u8; MAX_OUTGOING_LEN],
    cycle_started: Option<Instant>,
    cycle_to_frame_ns: Vec<u64>,
    last_sample_frame: Vec<u8>,
    frames: u64,
    sample_frames: u64,
    bytes: u64,
    encoding_failures: u64,
}

impl EncodingPort {
    fn new(capacity: usize) -> Self {
        Self {
            buffer: [0; MAX_OUTGOING_LEN],
            cycle_started: None,
            cycle_to_frame_ns: Vec::with_capacity(capacity),
            last_sample_frame: Vec::with_capacity(MAX_OUTGOING_LEN),
            frames: 0,
            sample_frames: 0,
            bytes: 0,
            encoding_failures: 0,
        }
    }
}

impl HostPort for EncodingPort {
    fn host_connected(&mut self) -> bool {
        true
    }

    fn try_receive(&mut self) -> Option<HostInputEvent> {
        self.cycle_started = Some(Instant::now());
        None
    }

    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull> {
        let Some(length) = device::encode_outgoing(&outgoing, &mut self.buffer) else {
            self.encoding_failures += 1;
            return Ok(());
        };
        let encoded = Instant::now();
        self.frames += 1;
        self.bytes += length as u64;
        if let Outgoing::Frame(DeviceFrame::Sample(_)) = outgoing {
            self.sample_frames += 1;
            if let Some(started) = self.cycle_started.take() {
                self.cycle_to_frame_ns
                    .push(encoded.duration_since(started).as_nanos() as u64);
            }
            self.last_sample_frame.clear();
            self.last_sample_frame
                .extend_from_slice(&self.buffer[..length]);
        }
        Ok(())
    }
}

fn simulated_device() -> Result<SimulatedDevice> {
    let scene = SceneFile::default_scene().map_err(|error| anyhow!("default scene: {error:?}"))?;
    SimulatedDevice::new(SimulatedDeviceConfig::new(scene, 1).with_seed(SEED))
        .map_err(|error| anyhow!("starting the simulated device: {error}"))
}

/// Runs both passes in this process (meaningful in a release build only).
pub fn measure(steps: u32) -> Result<SimulatorFigures> {
    if steps == 0 {
        bail!("no steps to measure");
    }
    let capacity = steps as usize;

    let mut device = simulated_device()?;
    let mut port = EncodingPort::new(capacity + WARM_UP_STEPS as usize);
    for _ in 0..WARM_UP_STEPS {
        device.step(&mut port);
    }
    let frames_before = (port.frames, port.sample_frames, port.bytes);
    let transactions_before = device.simulation().counters().transactions;
    let simulated_before_us = device.simulation().now_us();
    port.cycle_to_frame_ns.clear();
    let cpu_started = cpu_time::ThreadTime::try_now().context("reading the thread CPU clock")?;
    let wall_started = Instant::now();
    for _ in 0..steps {
        device.step(&mut port);
    }
    let wall_seconds = wall_started.elapsed().as_secs_f64();
    let cpu_seconds = cpu_started
        .try_elapsed()
        .context("reading the thread CPU clock")?
        .as_secs_f64();
    if port.encoding_failures > 0 {
        bail!("{} frames did not encode", port.encoding_failures);
    }
    let simulated_seconds = (device.simulation().now_us() - simulated_before_us) as f64 / 1e6;
    let transactions = device.simulation().counters().transactions - transactions_before;
    let cycle_to_frame = Latency::of(&mut port.cycle_to_frame_ns)
        .ok_or_else(|| anyhow!("no sample frame in {steps} steps: is streaming on?"))?;

    let (model_to_frame, replay_mismatches) = replay(steps)?;
    Ok(SimulatorFigures {
        steps,
        wall_seconds,
        cpu_seconds,
        simulated_seconds,
        frames: port.frames - frames_before.0,
        sample_frames: port.sample_frames - frames_before.1,
        bytes: port.bytes - frames_before.2,
        transactions_per_step: transactions as f64 / f64::from(steps),
        cycle_to_frame,
        model_to_frame,
        replay_mismatches,
    })
}

/// The replay pass: (statistics of the model-to-frame time, frames that differed).
fn replay(steps: u32) -> Result<(Latency, u64)> {
    let mut device = simulated_device()?;
    let mut port = EncodingPort::new(0);
    let mut buffer = [0u8; MAX_OUTGOING_LEN];
    let mut model_to_frame_ns = Vec::with_capacity(steps as usize);
    let mut mismatches = 0;
    let config = device::BOARD.device;
    let mut force_and_contact = model_core::ForceAndContact::new(
        model_core::PadRole::Unspecified,
        config.geometry,
        config.contact,
    );
    for step in 0..WARM_UP_STEPS + steps {
        let mut pad = device
            .device_mut()
            .control()
            .pad(0)
            .cloned()
            .ok_or_else(|| anyhow!("the simulated device found no pad"))?;
        let sets_before = port.sample_frames;
        let sample = device
            .step(&mut port)
            .ok_or_else(|| anyhow!("the simulated device read no pad"))?;
        let started = Instant::now();
        let mut replayed = sample;
        replayed.output = pad.process(&sample.input);
        let contact = force_and_contact.update(&replayed.output.taxels, replayed.timestamp_us);
        let summary = device::pad_summary(&contact);
        let frame = device::sample_frame(&replayed, &pad, wire::PadIndex::default(), summary);
        let length =
            device::encode_outgoing(&Outgoing::Frame(DeviceFrame::Sample(frame)), &mut buffer);
        let elapsed_ns = started.elapsed().as_nanos() as u64;
        if step < WARM_UP_STEPS || port.sample_frames == sets_before {
            continue;
        }
        model_to_frame_ns.push(elapsed_ns);
        if length.and_then(|length| buffer.get(..length)) != Some(port.last_sample_frame.as_slice())
        {
            mismatches += 1;
        }
    }
    let latency = Latency::of(&mut model_to_frame_ns)
        .ok_or_else(|| anyhow!("no sample frame to replay in {steps} steps"))?;
    Ok((latency, mismatches))
}

/// `cargo xtask sim-bench [steps]`: measures in this process when optimised, otherwise runs
/// the release build of the xtask and passes its output on.
pub fn command(root: &Path, steps: u32) -> Result<()> {
    if cfg!(debug_assertions) {
        let figures = run_release(root, steps)?;
        print!("{}", figures.lines());
        return Ok(());
    }
    print!("{}", measure(steps)?.lines());
    Ok(())
}

/// Builds the xtask in release mode, runs `sim-bench` in it and parses its output.
pub fn run_release(root: &Path, steps: u32) -> Result<SimulatorFigures> {
    println!("measuring the simulator (cargo run --release -p xtask -- sim-bench {steps})");
    let output = m4::cargo()
        .current_dir(root)
        .args([
            "run",
            "--release",
            "--quiet",
            "--package",
            "xtask",
            "--",
            "sim-bench",
        ])
        .arg(steps.to_string())
        .output()
        .context("starting cargo run --release -p xtask")?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        bail!(
            "sim-bench failed with {}:\n{stdout}{}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
    }
    SimulatorFigures::parse(&stdout)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_ranks_of_the_sorted_intervals() {
        let mut intervals: Vec<u64> = (1..=200).rev().collect();
        let latency = Latency::of(&mut intervals).unwrap();
        assert_eq!(latency.count, 200);
        assert_eq!(latency.p50_ns, 100.0);
        assert_eq!(latency.p99_ns, 198.0);
        assert_eq!(latency.max_ns, 200.0);
        assert!((latency.mean_ns - 100.5).abs() < 1e-9);
        assert!(Latency::of(&mut []).is_none());
        let mut one = [7];
        assert_eq!(Latency::of(&mut one).unwrap().p99_ns, 7.0);
    }

    #[test]
    fn the_printed_figures_parse_back() {
        let latency = Latency {
            count: 3,
            mean_ns: 1500.5,
            p50_ns: 1400.0,
            p99_ns: 2000.0,
            max_ns: 2100.0,
        };
        let figures = SimulatorFigures {
            steps: 3,
            wall_seconds: 0.25,
            cpu_seconds: 0.2,
            simulated_seconds: 0.03,
            frames: 4,
            sample_frames: 3,
            bytes: 400,
            transactions_per_step: 9.0,
            cycle_to_frame: latency,
            model_to_frame: Latency {
                mean_ns: 300.0,
                ..latency
            },
            replay_mismatches: 0,
        };
        assert_eq!(SimulatorFigures::parse(&figures.lines()).unwrap(), figures);
        assert!((figures.sets_per_second_wall() - 12.0).abs() < 1e-9);
        assert!(SimulatorFigures::parse("nothing").is_err());
    }

    #[test]
    fn a_short_live_run_streams_every_step_and_the_replay_matches() {
        let figures = measure(50).unwrap();
        assert_eq!(figures.steps, 50);
        assert_eq!(figures.sample_frames, 50);
        assert_eq!(figures.cycle_to_frame.count, 50);
        assert_eq!(figures.model_to_frame.count, 50);
        assert_eq!(figures.replay_mismatches, 0);
        assert!(figures.transactions_per_step > 0.0);
        assert!(figures.simulated_seconds > 0.0);
        assert!(figures.bytes >= 50);
    }
}
