//! Fault injection end to end: the simulated device (the firmware's own acquisition, model and
//! protocol code) streams through an in-memory link into the host's frame decoder, faults are
//! injected into the simulated sensors or into the link, and every decoded frame is checked
//! against the scene: a reported pressure must be right or absent, a missing sample set must be
//! counted by the device, and the time to the first clean set after the fault is measured in
//! simulated time.
//!
//! The scene is the simulator's ground truth: sensor-sim's physics turns it into capacitances
//! without the pressure model (its own compression law, parasitic capacitance and permittivity
//! law), and the device converts them with the simulated pad's factory calibration (the true
//! curve every 5 kPa). So a pressure error here is a real model or pipeline error.

use std::fmt::Write as _;

use model_core::TaxelFlags;
use sensor_sim::{Device as SimDevice, Fault, Keyframe, ScriptedScene, Window};
use sim_device::{MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{CountersFrame, DeviceFrame, DeviceFrameDecoder, SampleFrame, TemperatureSource};

/// Largest difference between a reported pressure and the scene that still counts as right, kPa:
/// converter noise at 400 S/s is 0.1 kPa rms at the flat top of the curve, the factory
/// calibration's cubic between points 5 kPa apart up to 0.065 kPa off the true curve.
pub const PRESSURE_TOLERANCE_KPA: f32 = 0.5;

/// Simulated length of one run, s.
const RUN_S: f64 = 12.0;
/// Fault window: start and end, s into a run (shifted a little per repetition).
const FAULT_START_S: f64 = 4.0;
const FAULT_END_S: f64 = 6.0;
/// Sets skipped around a scene change (the four channels convert 2.5 ms apart).
const SETTLE_US: u64 = 30_000;
/// Bytes the link holds for a host that reads slowly before the device's queue counts as full.
const LINK_CAPACITY_BYTES: usize = 4096;

/// Where a fault is injected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// I2C NACK burst from the converter.
    ConverterNack,
    /// The converter's DONE bits never set.
    DoneStuck,
    /// The converter's results read all zero.
    ZeroReads,
    /// One channel's codes are saturated.
    Saturated,
    /// The MCU resets alone and the converter's channel order is shifted by one.
    ChannelShift,
    /// One taxel's electrodes conduct (negative capacitance).
    Shorted,
    /// One taxel's lead is open.
    OpenLead,
    /// The temperature sensor stops answering.
    TemperatureSensorGone,
    /// The host reads far slower than the device sends.
    SlowHost,
    /// The cable is pulled in the middle of a frame and plugged back in.
    UnplugMidFrame,
    /// Random bytes on the line, both ways.
    Garbage,
}

impl FaultKind {
    /// Every fault the report covers.
    pub const ALL: [FaultKind; 11] = [
        FaultKind::ConverterNack,
        FaultKind::DoneStuck,
        FaultKind::ZeroReads,
        FaultKind::Saturated,
        FaultKind::ChannelShift,
        FaultKind::Shorted,
        FaultKind::OpenLead,
        FaultKind::TemperatureSensorGone,
        FaultKind::SlowHost,
        FaultKind::UnplugMidFrame,
        FaultKind::Garbage,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::ConverterNack => "I2C NACK burst (converter)",
            FaultKind::DoneStuck => "DONE stuck",
            FaultKind::ZeroReads => "all-zero reads",
            FaultKind::Saturated => "saturated codes (one channel)",
            FaultKind::ChannelShift => "channel order shifted (MCU-only reset)",
            FaultKind::Shorted => "electrodes shorted (one taxel)",
            FaultKind::OpenLead => "open lead (one taxel)",
            FaultKind::TemperatureSensorGone => "temperature sensor gone",
            FaultKind::SlowHost => "host reading too slowly",
            FaultKind::UnplugMidFrame => "USB unplug in the middle of a frame",
            FaultKind::Garbage => "garbage on the line",
        }
    }

    /// How it is injected.
    pub fn how(self) -> &'static str {
        match self {
            FaultKind::ConverterNack => "simulated FDC1004 NACKs every transfer for 2 s",
            FaultKind::DoneStuck => "simulated FDC1004 conversions stall, DONE never sets, for 2 s",
            FaultKind::ZeroReads => "simulated FDC1004 result registers read 0 for 2 s",
            FaultKind::Saturated => "CIN3 converts to 0x7FFFFF for 2 s",
            FaultKind::ChannelShift => "MCU rebooted alone at 4 s; the converter keeps running, its sequence rotated by one until a software reset",
            FaultKind::Shorted => "C12 reads -0.5 pF (conduction under a concentrated load) for 2 s",
            FaultKind::OpenLead => "C21 reads only its cable capacitance for 2 s",
            FaultKind::TemperatureSensorGone => "simulated TMP117 NACKs for 2 s",
            FaultKind::SlowHost => "host reads 200 bytes per set (a set's frame is 44-76 bytes, but the link is capped at 4 KiB and the host stalls for 2 s)",
            FaultKind::UnplugMidFrame => "link cut after 20 bytes of a frame, the rest lost; 1 s unplugged; then plugged back",
            FaultKind::Garbage => "64 random bytes injected into the device-to-host stream every 50 ms for 2 s, and 64 into the host-to-device stream",
        }
    }
}

/// What the host made of one run.
#[derive(Debug, Default, Clone)]
struct RunResult {
    sets_sent: u64,
    sets_received: u64,
    sets_with_a_fault_flag: u64,
    wrong_pressures: u64,
    pressures_checked: u64,
    squared_error_sum_kpa2: f64,
    max_error_kpa: f32,
    frames_rejected: u64,
    sets_missing: u64,
    sets_missing_in_damaged_gaps: u64,
    device_drops: u64,
    recovery_us: Option<u64>,
    flags_seen: u16,
    temperature_sources: Vec<TemperatureSource>,
    last_counters: Option<CountersFrame>,
}

/// One fault's totals over its repetitions.
#[derive(Debug, Clone)]
pub struct FaultOutcome {
    /// The fault.
    pub kind: FaultKind,
    /// Independent runs (different seeds and fault times).
    pub repetitions: u32,
    /// Sample sets the device produced.
    pub sets_sent: u64,
    /// Sample sets the host decoded.
    pub sets_received: u64,
    /// Decoded sets with at least one fault flag.
    pub sets_flagged: u64,
    /// Reported pressures that were wrong by more than the tolerance (must be 0).
    pub wrong_pressures: u64,
    /// Reported pressures checked against the scene.
    pub pressures_checked: u64,
    /// Sum of the squared differences between the checked pressures and the scene, kPa².
    pub squared_error_sum_kpa2: f64,
    /// Largest difference between a checked pressure and the scene, kPa.
    pub max_error_kpa: f32,
    /// Frames the host's decoder rejected (CRC, COBS, truncation).
    pub frames_rejected: u64,
    /// Sample sets missing at the host (sequence gaps).
    pub sets_missing: u64,
    /// Missing sets accounted for: sample sets the device counted as not sent (full queue or no
    /// host), and at most one set per frame the host rejected as damaged within the same
    /// sequence gap.
    pub sets_missing_accounted: u64,
    /// Sample sets the device counted as not sent (no host or a full queue).
    pub sets_dropped_by_device: u64,
    /// Missing sets explained by a damaged frame in their own sequence gap.
    pub sets_damaged_in_transit: u64,
    /// Flags seen during the runs.
    pub flags_seen: TaxelFlags,
    /// Recovery time after the fault ends, per repetition, µs of simulated time.
    pub recovery_us: Vec<u64>,
    /// What else was observed (temperature sources, counters).
    pub notes: String,
}

impl FaultOutcome {
    /// Sets missing that nobody accounted for (must be 0).
    pub fn sets_lost_silently(&self) -> u64 {
        self.sets_missing
            .saturating_sub(self.sets_missing_accounted)
    }

    /// Root mean square of the differences between the checked pressures and the scene, kPa.
    pub fn rms_error_kpa(&self) -> f64 {
        (self.squared_error_sum_kpa2 / self.pressures_checked.max(1) as f64).sqrt()
    }

    /// Worst recovery, ms.
    pub fn worst_recovery_ms(&self) -> Option<f64> {
        self.recovery_us.iter().max().map(|us| *us as f64 / 1000.0)
    }
}

fn keyframe(time_s: f64, pressure_kpa: [f32; 4], temperature_c: f32) -> Keyframe {
    Keyframe {
        time_s,
        pressure_kpa,
        temperature_c,
    }
}

/// Holds of different pressures with a step at 2 s, so faults hit a loaded pad.
fn scene(repetition: u32) -> Result<ScriptedScene, String> {
    let offset = repetition as f32 * 0.7;
    ScriptedScene::new(vec![
        keyframe(0.0, [0.0; 4], 28.0),
        keyframe(1.5, [0.0; 4], 28.0),
        keyframe(2.0, [8.0 + offset, 22.0, 3.0 + offset, 41.0], 28.0),
        keyframe(RUN_S, [8.0 + offset, 22.0, 3.0 + offset, 41.0], 28.0),
    ])
    .map_err(|error| format!("{error:?}"))
}

fn sample_is_clean(sample: &SampleFrame) -> bool {
    sample
        .taxels
        .iter()
        .all(|taxel| taxel.flags & TaxelFlags::FAULTS.bits() == 0 && taxel.pressure_kpa.is_some())
}

/// Runs one fault once.
fn run_once(kind: FaultKind, repetition: u32) -> Result<RunResult, String> {
    let scene = scene(repetition)?;
    let truth = scene.clone();
    let scene_file = SceneFile::single_pad(kind.name().to_string(), false, scene, Vec::new());
    let mut simulated = SimulatedDevice::new(
        SimulatedDeviceConfig::new(scene_file, 1).with_seed(1000 + u64::from(repetition)),
    )
    .map_err(|error| error.to_string())?;
    let shift_us = u64::from(repetition) * 37_000;
    let start_us = (FAULT_START_S * 1e6) as u64 + shift_us;
    let end_us = (FAULT_END_S * 1e6) as u64 + shift_us;
    let window = Window::Between { start_us, end_us };
    let simulation = simulated.simulation().clone();
    let sensor_fault = match kind {
        FaultKind::ConverterNack => Some(Fault::Nack(SimDevice::Fdc1004)),
        FaultKind::DoneStuck => Some(Fault::DoneStuck),
        FaultKind::ZeroReads => Some(Fault::ZeroReads),
        FaultKind::Saturated => Some(Fault::Saturated {
            taxel: 2,
            high: true,
        }),
        FaultKind::Shorted => Some(Fault::shorted(1)),
        FaultKind::OpenLead => Some(Fault::open_lead(2)),
        FaultKind::TemperatureSensorGone => Some(Fault::Nack(SimDevice::Tmp117)),
        FaultKind::ChannelShift
        | FaultKind::SlowHost
        | FaultKind::UnplugMidFrame
        | FaultKind::Garbage => None,
    };
    if let Some(fault) = sensor_fault {
        simulation.inject(fault, window);
    }
    let mut link = MemoryPort::new(LINK_CAPACITY_BYTES);
    let mut decoder = DeviceFrameDecoder::new();
    let mut result = RunResult::default();
    let mut previous_sequence: Option<u32> = None;
    let mut rebooted = false;
    let mut unplugged_at_us: Option<u64> = None;
    let mut noise_state = 0x9E37_79B9_7F4A_7C15u64 ^ u64::from(repetition);
    let mut next_noise_us = start_us;
    let mut drops_at_start: Option<u64> = None;
    let mut sequence_base = 0u64;
    let mut rejected_since_sample = 0u64;
    let end_of_run_us = (RUN_S * 1e6) as u64;
    while simulation.now_us() < end_of_run_us {
        let now_us = simulation.now_us();
        let in_window = now_us >= start_us && now_us < end_us;
        if kind == FaultKind::ChannelShift && !rebooted && now_us >= start_us {
            simulated.restart_mcu().map_err(|error| error.to_string())?;
            rebooted = true;
            // The reboot restarts the sequence numbers: count the old run's sets apart.
            if let Some(previous) = previous_sequence.take() {
                sequence_base += u64::from(previous) + 1;
            }
        }
        if kind == FaultKind::Garbage && in_window && now_us >= next_noise_us {
            for _ in 0..64 {
                noise_state ^= noise_state << 13;
                noise_state ^= noise_state >> 7;
                noise_state ^= noise_state << 17;
                link.to_host.push_back(noise_state as u8);
                link.to_device.push_back((noise_state >> 8) as u8);
            }
            next_noise_us = now_us + 50_000;
        }
        if kind == FaultKind::UnplugMidFrame {
            if unplugged_at_us.is_none() && now_us >= start_us {
                // Cut in the middle of whatever frame is on the wire: the host has 20 bytes of it.
                let keep = link.to_host.len().min(20);
                link.to_host.truncate(keep);
                link.connected = false;
                unplugged_at_us = Some(now_us);
            }
            if let Some(at_us) = unplugged_at_us {
                if !link.connected && now_us >= at_us + 1_000_000 {
                    link.connected = true;
                }
            }
        }
        let sample = simulated.step(&mut link);
        result.sets_sent += 1;
        if drops_at_start.is_none() && now_us >= 1_000_000 {
            let counters = simulated.device_mut().host_counters();
            drops_at_start = Some(u64::from(counters.sample_frames_dropped));
        }
        let _ = sample;
        // The host side: read what a host of this kind reads in one set's time.
        let read_budget = match kind {
            FaultKind::SlowHost if in_window => 0,
            FaultKind::SlowHost => 200,
            _ => usize::MAX,
        };
        if !link.connected {
            continue;
        }
        let bytes = link.take_for_host(read_budget);
        for decoded in decoder.feed(&bytes) {
            match decoded {
                Ok(DeviceFrame::Sample(frame)) => {
                    result.sets_received += 1;
                    let gap = if let Some(previous) = previous_sequence {
                        u64::from(frame.sequence.wrapping_sub(previous).saturating_sub(1))
                    } else if sequence_base > 0 {
                        u64::from(frame.sequence)
                    } else {
                        0
                    };
                    result.sets_missing += gap;
                    // A damaged frame explains at most one set, and only a set missing from
                    // the gap it arrived in: damage elsewhere in the run explains nothing here.
                    result.sets_missing_in_damaged_gaps += gap.min(rejected_since_sample);
                    rejected_since_sample = 0;
                    previous_sequence = Some(frame.sequence);
                    check_sample(&frame, &truth, &mut result);
                    if frame.timestamp_us >= end_us
                        && result.recovery_us.is_none()
                        && sample_is_clean(&frame)
                    {
                        let recovered = match kind {
                            FaultKind::TemperatureSensorGone => {
                                frame.temperature_source == TemperatureSource::Tmp117
                            }
                            _ => true,
                        };
                        if recovered {
                            result.recovery_us = Some(frame.timestamp_us.saturating_sub(end_us));
                        }
                    }
                    if !result
                        .temperature_sources
                        .contains(&frame.temperature_source)
                    {
                        result.temperature_sources.push(frame.temperature_source);
                    }
                }
                Ok(DeviceFrame::Counters(counters)) => result.last_counters = Some(counters),
                Ok(_) => {}
                Err(_) => {
                    result.frames_rejected += 1;
                    rejected_since_sample += 1;
                }
            }
        }
    }
    let counters = simulated.device_mut().host_counters();
    // Sample sets only: a dropped event or counters frame never explains a missing sample set.
    result.device_drops =
        u64::from(counters.sample_frames_dropped).saturating_sub(drops_at_start.unwrap_or(0));
    Ok(result)
}

fn check_sample(frame: &SampleFrame, truth: &ScriptedScene, result: &mut RunResult) {
    let time_us = frame.timestamp_us;
    let mut flagged = false;
    for (taxel, sample) in frame.taxels.iter().enumerate() {
        result.flags_seen |= sample.flags;
        if sample.flags & TaxelFlags::FAULTS.bits() != 0 {
            flagged = true;
        }
        let Some(pressure_kpa) = sample.pressure_kpa else {
            continue;
        };
        // Around the scene's step the four channels see different pressures by design.
        let near_step =
            (1_500_000u64.saturating_sub(SETTLE_US)..2_000_000 + SETTLE_US).contains(&time_us);
        if near_step || time_us < 300_000 {
            continue;
        }
        let expected = truth.point_at_s(time_us as f64 / 1e6).pressure_kpa[taxel];
        result.pressures_checked += 1;
        let error_kpa = (pressure_kpa - expected).abs();
        result.squared_error_sum_kpa2 += f64::from(error_kpa) * f64::from(error_kpa);
        result.max_error_kpa = result.max_error_kpa.max(error_kpa);
        if error_kpa > PRESSURE_TOLERANCE_KPA {
            result.wrong_pressures += 1;
        }
    }
    if flagged {
        result.sets_with_a_fault_flag += 1;
    }
}

/// Runs one fault `repetitions` times and adds up what came out.
pub fn run_fault(kind: FaultKind, repetitions: u32) -> Result<FaultOutcome, String> {
    let mut outcome = FaultOutcome {
        kind,
        repetitions,
        sets_sent: 0,
        sets_received: 0,
        sets_flagged: 0,
        wrong_pressures: 0,
        pressures_checked: 0,
        squared_error_sum_kpa2: 0.0,
        max_error_kpa: 0.0,
        frames_rejected: 0,
        sets_missing: 0,
        sets_missing_accounted: 0,
        sets_dropped_by_device: 0,
        sets_damaged_in_transit: 0,
        flags_seen: TaxelFlags::empty(),
        recovery_us: Vec::new(),
        notes: String::new(),
    };
    let mut sources: Vec<TemperatureSource> = Vec::new();
    let mut last_counters = None;
    for repetition in 0..repetitions {
        let run = run_once(kind, repetition)?;
        outcome.sets_sent += run.sets_sent;
        outcome.sets_received += run.sets_received;
        outcome.sets_flagged += run.sets_with_a_fault_flag;
        outcome.wrong_pressures += run.wrong_pressures;
        outcome.pressures_checked += run.pressures_checked;
        outcome.squared_error_sum_kpa2 += run.squared_error_sum_kpa2;
        outcome.max_error_kpa = outcome.max_error_kpa.max(run.max_error_kpa);
        outcome.frames_rejected += run.frames_rejected;
        outcome.sets_missing += run.sets_missing;
        // A set the device could not send it counted as a sample set dropped; a set lost in
        // transit left a damaged frame in its own sequence gap.
        outcome.sets_missing_accounted += run
            .sets_missing
            .min(run.device_drops + run.sets_missing_in_damaged_gaps);
        outcome.sets_dropped_by_device += run.device_drops;
        outcome.sets_damaged_in_transit += run.sets_missing_in_damaged_gaps;
        outcome.flags_seen |= TaxelFlags::from_bits_truncate(run.flags_seen);
        if let Some(recovery_us) = run.recovery_us {
            outcome.recovery_us.push(recovery_us);
        }
        for source in run.temperature_sources {
            if !sources.contains(&source) {
                sources.push(source);
            }
        }
        if run.last_counters.is_some() {
            last_counters = run.last_counters;
        }
    }
    let _ = write!(outcome.notes, "temperature sources seen: {sources:?}");
    if let Some(counters) = last_counters {
        let _ = write!(
            outcome.notes,
            "; last counters: re-inits {}, I2C errors {}, temperature errors {}, frames dropped (no host or full) {}, host frames rejected {}",
            counters.converter_reinits,
            counters.i2c_errors,
            counters.temperature_sensor_errors,
            counters.frames_dropped_no_host,
            counters.host_frames_rejected
        );
    }
    Ok(outcome)
}

/// The worst recovery of the runs, µs each, and how many of `repetitions` runs did not recover
/// at all (a worst figure of the runs that did would hide them).
pub fn recovery_words(recovery_us: &[u64], repetitions: u32) -> String {
    let unrecovered = (repetitions as usize).saturating_sub(recovery_us.len());
    match (recovery_us.iter().max(), unrecovered) {
        (Some(us), 0) => format!("{:.1} ms", *us as f64 / 1000.0),
        (Some(us), runs) => format!(
            "{:.1} ms; **{runs} of {repetitions} runs not recovered**",
            *us as f64 / 1000.0
        ),
        (None, _) => "not recovered".to_string(),
    }
}

/// Flag names joined with `|`, escaped so that they stay in one Markdown table cell.
fn flag_names(flags: TaxelFlags) -> String {
    let names: Vec<&str> = TaxelFlags::NAMES
        .iter()
        .filter(|(flag, _)| flags.contains(*flag))
        .map(|(_, name)| *name)
        .collect();
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(" \\| ")
    }
}

/// The report as Markdown; `more_sections` (Markdown, e.g. the several-pads section) goes
/// after the single-pad faults.
pub fn render_markdown(outcomes: &[FaultOutcome], more_sections: &str, command: &str) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "# Reliability: fault injection end to end\n");
    let _ = writeln!(
        out,
        "<!-- Generated by `{command}`: do not edit by hand, run it again. -->\n"
    );
    let _ = writeln!(
        out,
        "**Generated** by `{command}`; never edited by hand. Each fault is injected into the \
simulated device — the firmware's own acquisition loop, pressure model and protocol code over a \
register-level simulation of the FDC1004 and TMP117 — or into the link between it and the host, \
in independent runs of {RUN_S} s of simulated time (different noise seeds, the fault window \
shifted by 37 ms per run, the pad loaded at 3–41 kPa). Every frame the host decodes is checked \
against the scene, which is the simulator's ground truth: its physics (a parallel plate over a \
densifying elastomer, Eq. 4 of the article, fitted to Table 1; parasitic capacitance; its own \
permittivity law) does not use the pressure model, and the device converts with the simulated \
pad's factory calibration (that true curve sampled every 5 kPa). A reported pressure more than \
{PRESSURE_TOLERANCE_KPA} kPa from the scene is a *wrong pressure*; the RMS and largest \
difference of all the pressures checked are given too; a sample set missing at the host (sequence gap) must be counted by the device \
as a sample set it did not send (no host or a full queue; dropped event and counters frames do \
not count), or fall in a sequence gap in which the host rejected a damaged frame (one set per \
damaged frame, only in its own gap); recovery is \
the simulated time from the end of the fault to the first set with no fault flag (for the \
temperature sensor: back on the TMP117).\n"
    );
    let _ = writeln!(
        out,
        "| fault | how injected | runs | sets sent / received | sets flagged | wrong pressures | pressure error vs truth: RMS / max | sets lost unflagged | frames rejected by the host | worst recovery | flags seen |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|");
    for outcome in outcomes {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} / {} | {} | **{}** of {} | {:.3} / {:.3} kPa | **{}** ({} missing; accounted: {} counted by the device, {} damaged in transit) | {} | {} | {} |",
            outcome.kind.name(),
            outcome.kind.how(),
            outcome.repetitions,
            outcome.sets_sent,
            outcome.sets_received,
            outcome.sets_flagged,
            outcome.wrong_pressures,
            outcome.pressures_checked,
            outcome.rms_error_kpa(),
            outcome.max_error_kpa,
            outcome.sets_lost_silently(),
            outcome.sets_missing,
            outcome.sets_dropped_by_device,
            outcome.sets_damaged_in_transit,
            outcome.frames_rejected,
            recovery_words(&outcome.recovery_us, outcome.repetitions),
            flag_names(outcome.flags_seen)
        );
    }
    let _ = writeln!(out, "\n## Notes per fault\n");
    for outcome in outcomes {
        let _ = writeln!(out, "- **{}**: {}.", outcome.kind.name(), outcome.notes);
    }
    let _ = writeln!(out, "\n{more_sections}");
    let _ = writeln!(
        out,
        "## What is covered elsewhere\n\n\
- Flash: bit flips, truncation and power loss at every write and erase of a save, on a RAM model \
of the flash (`cargo test -p taxel-calibration-store`: always the old or the new calibration, or \
defaults with a flag; see that crate's tests for the counts).\n\
- Host: `taxel record` closes both files with everything received on Ctrl-C or unplug, and \
reports a full disk; `taxel convert` keeps every good row of a damaged file and reports the bad \
ones by line number (`cargo test -p taxel`).\n\
- Fuzzing: the frame decoder, the command parser, the calibration-file parser, the flash record \
parser and model-core over arbitrary input bits (`fuzz/`, cargo-fuzz; CI runs each for a bounded \
time).\n"
    );
    out
}
