//! One pad of several fails, end to end: a simulated board with [`PADS`] pads behind the
//! simulated TCA9548A streams through an in-memory link into the host's frame decoder while one
//! pad's board is unplugged, its converter NACKs or stalls, or its multiplexer channel sticks
//! open. Every decoded frame is checked against its pad's scene (the simulator's ground truth);
//! the failing pad must be flagged and recover on its own, and every other pad must keep its
//! rate, its values and its flags.

use std::fmt::Write as _;

use model_core::TaxelFlags;
use sensor_sim::{Device as SimDevice, Fault, Keyframe, ScriptedScene, Simulation, Window};
use sim_device::{MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{DeviceFrame, DeviceFrameDecoder, SampleFrame};

use crate::reliability::{recovery_words, PRESSURE_TOLERANCE_KPA};

/// Pads on the board.
pub const PADS: usize = 4;
/// The pad that fails.
pub const FAILING_PAD: usize = 2;
/// Simulated length of one run, s.
const RUN_S: f64 = 9.0;
/// Fault window, s into a run (shifted a little per repetition).
const FAULT_START_S: f64 = 3.0;
const FAULT_END_S: f64 = 5.0;
/// Pressures are checked from here on (after the tare at boot and the press's ramp).
const CHECK_FROM_US: u64 = 1_300_000;
/// A fault shows from the first read after it began: a stalled converter's last results (from
/// before the stall) are still read once, and a read waits out at most the DONE timeout (25 ms
/// at 400 S/s). Frames this long after the start of the fault count as during it.
const FAULT_SHOWS_AFTER_US: u64 = 30_000;

/// How one pad fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PadFaultKind {
    /// The pad's board is unplugged and plugged back in.
    Unplugged,
    /// The pad's converter NACKs every transfer.
    ConverterNack,
    /// The pad's converter stalls: DONE never sets.
    DoneStuck,
    /// The pad's multiplexer channel stays open whatever the control register says.
    ChannelStuckOpen,
}

impl PadFaultKind {
    /// Every pad fault the report covers.
    pub const ALL: [PadFaultKind; 4] = [
        PadFaultKind::Unplugged,
        PadFaultKind::ConverterNack,
        PadFaultKind::DoneStuck,
        PadFaultKind::ChannelStuckOpen,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            PadFaultKind::Unplugged => "pad unplugged",
            PadFaultKind::ConverterNack => "pad's converter NACKs",
            PadFaultKind::DoneStuck => "pad's converter stalls (DONE stuck)",
            PadFaultKind::ChannelStuckOpen => "pad's multiplexer channel stuck open",
        }
    }

    fn inject(self, simulation: &Simulation, window: Window) -> Result<(), String> {
        let on_pad = |fault| {
            simulation
                .inject_on_pad(FAILING_PAD, fault, window)
                .map(|_| ())
                .map_err(|error| format!("{error:?}"))
        };
        match self {
            PadFaultKind::Unplugged => on_pad(Fault::Unplugged),
            PadFaultKind::ConverterNack => on_pad(Fault::Nack(SimDevice::Fdc1004)),
            PadFaultKind::DoneStuck => on_pad(Fault::DoneStuck),
            PadFaultKind::ChannelStuckOpen => {
                simulation.inject_upstream(
                    Fault::MuxChannelStuck {
                        channel: FAILING_PAD as u8,
                        closed: false,
                    },
                    window,
                );
                Ok(())
            }
        }
    }
}

/// One pad fault's totals over its repetitions.
#[derive(Debug, Clone, PartialEq)]
pub struct PadFaultOutcome {
    /// The fault.
    pub kind: PadFaultKind,
    /// Independent runs.
    pub repetitions: u32,
    /// Frames of the failing pad received during its fault, and how many of them were flagged.
    pub failing_frames_during: u64,
    /// Of those, frames carrying a fault flag on every taxel and no force.
    pub failing_frames_flagged: u64,
    /// Recovery of the failing pad after its fault ended, per run, µs of simulated time.
    pub recovery_us: Vec<u64>,
    /// Frames of the other pads during the fault.
    pub other_frames_during: u64,
    /// Frames of the other pads in as long a time before the fault.
    pub other_frames_before: u64,
    /// Frames of the other pads with a fault flag (must be 0).
    pub other_frames_flagged: u64,
    /// Reported pressures, any pad, more than the tolerance from its scene (must be 0).
    pub wrong_pressures: u64,
    /// Reported pressures checked.
    pub pressures_checked: u64,
    /// Sample frames missing at the host, any pad (sequence gaps per pad; the link never drops
    /// here, so this must be 0).
    pub frames_missing: u64,
}

impl PadFaultOutcome {
    /// The other pads' rate during the fault, as a share of their rate before it.
    pub fn other_rate_share(&self) -> f64 {
        self.other_frames_during as f64 / self.other_frames_before.max(1) as f64
    }

    /// Worst recovery, ms.
    pub fn worst_recovery_ms(&self) -> Option<f64> {
        self.recovery_us.iter().max().map(|us| *us as f64 / 1000.0)
    }
}

fn keyframe(time_s: f64, pressure_kpa: f32) -> Keyframe {
    Keyframe {
        time_s,
        pressure_kpa: [pressure_kpa; 4],
        temperature_c: 27.0,
    }
}

/// Pad k holds 6 + 7k kPa (+ a little per repetition) on every taxel after the tare.
fn scene(pad: usize, repetition: u32) -> Result<ScriptedScene, String> {
    let pressure_kpa = 6.0 + 7.0 * pad as f32 + 0.3 * repetition as f32;
    ScriptedScene::new(vec![
        keyframe(0.0, 0.0),
        keyframe(0.8, 0.0),
        keyframe(1.2, pressure_kpa),
        keyframe(RUN_S, pressure_kpa),
    ])
    .map_err(|error| format!("{error:?}"))
}

fn is_clean(frame: &SampleFrame) -> bool {
    frame.summary.force_n.is_some()
        && frame.taxels.iter().all(|taxel| {
            taxel.flags & TaxelFlags::FAULTS.bits() == 0 && taxel.pressure_kpa.is_some()
        })
}

/// Runs one pad fault once; adds what came out to `outcome`.
fn run_once(
    kind: PadFaultKind,
    repetition: u32,
    outcome: &mut PadFaultOutcome,
) -> Result<(), String> {
    let scenes: Vec<ScriptedScene> = (0..PADS)
        .map(|pad| scene(pad, repetition))
        .collect::<Result<_, _>>()?;
    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(
            SceneFile::single_pad(kind.name(), false, scenes[0].clone(), Vec::new()),
            PADS,
        )
        .with_seed(2000 + u64::from(repetition)),
    )
    .map_err(|error| error.to_string())?;
    let simulation = device.simulation().clone();
    for (pad, scene) in scenes.iter().enumerate() {
        let scene = scene.clone();
        simulation
            .set_pad_scene(pad, move |time_us: u64| {
                scene.point_at_s(time_us as f64 / 1e6)
            })
            .map_err(|error| format!("{error:?}"))?;
    }
    let shift_us = u64::from(repetition) * 37_000;
    let start_us = (FAULT_START_S * 1e6) as u64 + shift_us;
    let end_us = (FAULT_END_S * 1e6) as u64 + shift_us;
    kind.inject(&simulation, Window::Between { start_us, end_us })?;
    let fault_len_us = end_us - start_us;
    let mut link = MemoryPort::new(usize::MAX);
    let mut decoder = DeviceFrameDecoder::new();
    let mut previous_sequence = [None::<u32>; PADS];
    let mut recovered = false;
    while simulation.now_us() < (RUN_S * 1e6) as u64 {
        device.step(&mut link);
        for decoded in decoder.feed(&link.take_for_host(usize::MAX)) {
            let Ok(DeviceFrame::Sample(frame)) = decoded else {
                continue;
            };
            let pad = usize::from(frame.pad.get());
            let Some(previous) = previous_sequence.get_mut(pad) else {
                return Err(format!("a frame of pad {pad} from a board of {PADS}"));
            };
            if let Some(previous) = *previous {
                outcome.frames_missing +=
                    u64::from(frame.sequence.wrapping_sub(previous).saturating_sub(1));
            }
            *previous = Some(frame.sequence);
            let time_us = frame.timestamp_us;
            let during = (start_us..end_us).contains(&time_us);
            let before = (start_us - fault_len_us..start_us).contains(&time_us);
            if pad == FAILING_PAD {
                if during && time_us >= start_us + FAULT_SHOWS_AFTER_US {
                    outcome.failing_frames_during += 1;
                    let all_faulted = frame.summary.force_n.is_none()
                        && frame
                            .taxels
                            .iter()
                            .all(|taxel| taxel.flags & TaxelFlags::FAULTS.bits() != 0);
                    if all_faulted {
                        outcome.failing_frames_flagged += 1;
                    }
                }
                if time_us >= end_us && !recovered && is_clean(&frame) {
                    recovered = true;
                    outcome.recovery_us.push(time_us - end_us);
                }
            } else {
                if during {
                    outcome.other_frames_during += 1;
                }
                if before {
                    outcome.other_frames_before += 1;
                }
                if time_us >= CHECK_FROM_US && !is_clean(&frame) {
                    outcome.other_frames_flagged += 1;
                }
            }
            if time_us < CHECK_FROM_US {
                continue;
            }
            let Some(scene) = scenes.get(pad) else {
                continue;
            };
            let truth = scene.point_at_s(time_us as f64 / 1e6).pressure_kpa;
            for (taxel, expected) in frame.taxels.iter().zip(truth) {
                if let Some(pressure_kpa) = taxel.pressure_kpa {
                    outcome.pressures_checked += 1;
                    if (pressure_kpa - expected).abs() > PRESSURE_TOLERANCE_KPA {
                        outcome.wrong_pressures += 1;
                    }
                }
            }
        }
    }
    Ok(())
}

/// Runs one pad fault `repetitions` times.
pub fn run_pad_fault(kind: PadFaultKind, repetitions: u32) -> Result<PadFaultOutcome, String> {
    let mut outcome = PadFaultOutcome {
        kind,
        repetitions,
        failing_frames_during: 0,
        failing_frames_flagged: 0,
        recovery_us: Vec::new(),
        other_frames_during: 0,
        other_frames_before: 0,
        other_frames_flagged: 0,
        wrong_pressures: 0,
        pressures_checked: 0,
        frames_missing: 0,
    };
    for repetition in 0..repetitions {
        run_once(kind, repetition, &mut outcome)?;
    }
    Ok(outcome)
}

/// The report's section as Markdown.
pub fn render_markdown(outcomes: &[PadFaultOutcome]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "## Several pads: one pad fails\n");
    let _ = writeln!(
        out,
        "A simulated board with {PADS} pads behind the simulated TCA9548A (a TMP117 on the main \
bus), each pad holding its own load after the tare (6 to 27 kPa); pad {FAILING_PAD} fails for \
{} s in runs of {RUN_S} s of simulated time. Every frame the host decodes is checked against \
its pad's scene. *Flagged* = every taxel of the failing pad's frame carries a fault flag and the \
frame has no force (counted from {} ms into the fault: a stalled converter's last results, \
converted before the stall, are read once); *rate kept* = the other pads' frames during the fault over as long a time \
just before it; *recovery* = from the end of the fault to the failing pad's first frame with \
no fault flag. A converter that does not answer is looked for with one register read every \
20 ms; one that answers but stalls is retried at intervals doubling from 20 ms to 320 ms, each \
retry waiting out its DONE timeout (25 ms), which is what the other pads lose.\n",
        FAULT_END_S - FAULT_START_S,
        FAULT_SHOWS_AFTER_US / 1000
    );
    let _ = writeln!(
        out,
        "| fault | runs | failing pad: frames flagged / during the fault | worst recovery | other pads: rate kept | other pads: frames flagged | wrong pressures (any pad) | frames missing |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
    for outcome in outcomes {
        let _ = writeln!(
            out,
            "| {} | {} | {} / {} | {} | {:.1} % | **{}** | **{}** of {} | {} |",
            outcome.kind.name(),
            outcome.repetitions,
            outcome.failing_frames_flagged,
            outcome.failing_frames_during,
            recovery_words(&outcome.recovery_us, outcome.repetitions),
            100.0 * outcome.other_rate_share(),
            outcome.other_frames_flagged,
            outcome.wrong_pressures,
            outcome.pressures_checked,
            outcome.frames_missing
        );
    }
    out
}
