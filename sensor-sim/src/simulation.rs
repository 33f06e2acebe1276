//! The shared simulation: clock, pads (scene, physics, devices), the multiplexer, faults and
//! counters behind one `Arc<Mutex<..>>`. Transactions are routed in [`crate::routing`];
//! [`crate::Simulation`], the handle that steers it all, is in [`crate::handle`].

use std::sync::{Mutex, MutexGuard, PoisonError};

use crate::clock::{Pacer, PacingAction};
use crate::config::{SimulationConfig, Topology, MAX_PADS};
use crate::fault::{Device, Fault, FaultBook, FaultTarget, TargetFaults};
use crate::fdc1004::Fdc1004Model;
use crate::physics::PhysicsModel;
use crate::scene::{Scene, ScenePoint, ScriptedScene};
use crate::tca9548a::Tca9548aModel;
use crate::tmp117::Tmp117Model;

/// What the simulation counted since it started (or since `Simulation::reset_counters`).
///
/// The totals cover every device on the bus; [`Counters::pads`] splits a few of them per pad.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counters {
    /// Transactions on the bus, whatever their address and outcome.
    pub transactions: u64,
    /// Transactions addressed to an FDC1004 on the bus (connected, answering or not).
    pub fdc1004_transactions: u64,
    /// Transactions addressed to a TMP117 on the bus (connected, answering or not).
    pub tmp117_transactions: u64,
    /// Transactions that failed with a NACK, for any reason.
    pub nacks: u64,
    /// NACKs caused by an injected [`Fault::Nack`].
    pub nacks_injected: u64,
    /// NACKs of a device still powering up.
    pub nacks_powering_up: u64,
    /// NACKs of an address where no device is connected (none there, or behind an open
    /// multiplexer channel).
    pub nacks_unknown_address: u64,
    /// FDC1004 conversions completed (DONE set; the result written unless
    /// [`Fault::FrozenResult`] kept the previous one).
    pub conversions: u64,
    /// FDC1004 conversions completed per measurement 1..4.
    pub conversions_per_measurement: [u64; 4],
    /// FDC1004 conversions stalled by [`Fault::DoneStuck`].
    pub conversions_stalled: u64,
    /// FDC1004 results that are a saturation code (out of range or injected).
    pub saturated_codes: u64,
    /// FDC1004 results forced to saturation by [`Fault::Saturated`].
    pub saturations_injected: u64,
    /// FDC1004 input conversions replaced by [`Fault::Shorted`].
    pub shorted_conversions: u64,
    /// FDC1004 input conversions replaced by [`Fault::OpenLead`].
    pub open_conversions: u64,
    /// FDC1004 conversions that left their result as it was ([`Fault::FrozenResult`]; they
    /// are counted in `conversions` too).
    pub frozen_conversions: u64,
    /// MEASn_MSB reads zeroed by [`Fault::ZeroReads`].
    pub zero_reads_injected: u64,
    /// Software resets (FDC1004 RST and TMP117 Soft_Reset).
    pub software_resets: u64,
    /// Register writes ignored (read-only or unknown registers).
    pub ignored_writes: u64,
    /// TMP117 conversions completed.
    pub temperature_conversions: u64,
    /// TEMP_RESULT reads replaced by [`Fault::TemperatureStuck`].
    pub stuck_temperature_reads: u64,
    /// Transactions addressed to the multiplexer.
    pub multiplexer_transactions: u64,
    /// Transactions answered by more than one device at once (their read bytes were ANDed).
    pub address_conflicts: u64,
    /// NACKs of an address whose only devices sit on an unplugged pad ([`Fault::Unplugged`]).
    pub nacks_unplugged: u64,
    /// Per pad (index = pad number; unused entries stay 0).
    pub pads: [PadCounters; MAX_PADS],
}

/// What the simulation counted for one pad.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PadCounters {
    /// Transactions that reached one of the pad's devices (connected at the address, whatever
    /// the outcome).
    pub transactions: u64,
    /// Of those, the ones that failed with a NACK.
    pub nacks: u64,
    /// Conversions of the pad's FDC1004 completed.
    pub conversions: u64,
    /// Conversions of the pad's own TMP117 completed.
    pub temperature_conversions: u64,
}

/// What a device model needs from the rest of the simulation while it works.
pub(crate) struct Environment<'a> {
    pub(crate) scene: &'a mut dyn Scene,
    pub(crate) physics: &'a mut PhysicsModel,
    pub(crate) faults: TargetFaults<'a>,
    pub(crate) counters: &'a mut Counters,
    /// The pad the device belongs to (`None`: upstream of the multiplexer).
    pub(crate) pad: Option<usize>,
}

impl Environment<'_> {
    /// The counters of the device's pad, if it belongs to one.
    pub(crate) fn pad_counters(&mut self) -> Option<&mut PadCounters> {
        self.pad.and_then(|pad| self.counters.pads.get_mut(pad))
    }
}

/// One pad: its scene, physics and devices.
pub(crate) struct Pad {
    /// The multiplexer channel it hangs on (`None`: directly on the main bus).
    pub(crate) channel: Option<u8>,
    pub(crate) scene: Box<dyn Scene>,
    pub(crate) physics: PhysicsModel,
    pub(crate) fdc1004: Fdc1004Model,
    pub(crate) tmp117: Option<Tmp117Model>,
    /// Unplugged by [`Fault::Unplugged`]: no power, no answer, no conversion.
    pub(crate) unplugged: bool,
}

/// The multiplexer and its address.
pub(crate) struct Multiplexer {
    pub(crate) address: u8,
    pub(crate) model: Tca9548aModel,
}

/// The TMP117 on the main bus and its address.
pub(crate) struct SharedTmp117 {
    pub(crate) address: u8,
    pub(crate) model: Tmp117Model,
}

/// A device on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DeviceRef {
    PadFdc1004(usize),
    PadTmp117(usize),
    SharedTmp117,
    Multiplexer,
}

/// A converter or temperature model to work on.
pub(crate) enum ModelMut<'a> {
    Fdc1004(&'a mut Fdc1004Model),
    Tmp117(&'a mut Tmp117Model),
}

/// The whole simulation.
pub(crate) struct State {
    pub(crate) now_ns: u64,
    /// At least one (the configuration is validated).
    pub(crate) pads: Vec<Pad>,
    pub(crate) multiplexer: Option<Multiplexer>,
    pub(crate) shared_tmp117: Option<SharedTmp117>,
    pub(crate) faults: FaultBook,
    pub(crate) counters: Counters,
    pub(crate) bus_frequency_hz: Option<u32>,
    pub(crate) pacer: Pacer,
}

/// Locks the simulation. A panic while it was locked (only possible in a test's own code, e.g.
/// a scene closure) leaves the state consistent between calls, so poisoning is ignored.
pub(crate) fn lock(shared: &Mutex<State>) -> MutexGuard<'_, State> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Mixed into the seed per pad index (odd, so every pad gets another stream; pad 0 keeps the
/// seed itself, as in the single-pad setup).
const PAD_SEED_STEP: u64 = 0xD1B5_4A32_D192_ED03;
/// Separates a pad's TMP117 stream from its FDC1004's.
const TMP117_SEED_MIX: u64 = 0x9E37_79B9_7F4A_7C15;
/// Separates the shared TMP117's stream from the pads'.
const SHARED_TMP117_SEED_MIX: u64 = 0xC2B2_AE3D_27D4_EB4F;

fn pad_seed(seed: u64, pad: usize) -> u64 {
    seed.wrapping_add((pad as u64).wrapping_mul(PAD_SEED_STEP))
}

fn is_unplugged(fault: &Fault) -> bool {
    matches!(fault, Fault::Unplugged)
}

impl Pad {
    fn new(
        channel: Option<u8>,
        physics: PhysicsModel,
        fdc1004: Fdc1004Model,
        tmp117: Option<Tmp117Model>,
    ) -> Self {
        Self {
            channel,
            scene: Box::new(ScriptedScene::constant(ScenePoint::UNLOADED)),
            physics,
            fdc1004,
            tmp117,
            unplugged: false,
        }
    }

    /// The pad's scene point at `time_us`.
    pub(crate) fn sample(&mut self, time_us: u64) -> ScenePoint {
        self.scene.sample(time_us)
    }
}

impl State {
    /// A simulation at time 0 from a validated configuration.
    pub(crate) fn new(config: SimulationConfig) -> Self {
        // Separate streams so that the converter's noise does not depend on how often the
        // temperature is read, and the reverse.
        let (pads, multiplexer, shared_tmp117) = match config.topology {
            Topology::SinglePad => {
                let pad = Pad::new(
                    None,
                    PhysicsModel::new(config.physics),
                    Fdc1004Model::new(config.fdc1004, config.seed, 0),
                    Some(Tmp117Model::new(
                        config.tmp117,
                        config.seed ^ TMP117_SEED_MIX,
                        0,
                    )),
                );
                (vec![pad], None, None)
            }
            Topology::Multiplexed(multiplexer) => {
                let pads = multiplexer
                    .pads
                    .into_iter()
                    .enumerate()
                    .map(|(index, pad)| {
                        let seed = pad_seed(config.seed, index);
                        Pad::new(
                            Some(pad.channel),
                            PhysicsModel::new(pad.physics),
                            Fdc1004Model::new(pad.fdc1004, seed, 0),
                            pad.tmp117
                                .map(|tmp117| Tmp117Model::new(tmp117, seed ^ TMP117_SEED_MIX, 0)),
                        )
                    })
                    .collect();
                let shared = multiplexer.shared_tmp117.map(|shared| SharedTmp117 {
                    address: shared.address,
                    model: Tmp117Model::new(shared.tmp117, config.seed ^ SHARED_TMP117_SEED_MIX, 0),
                });
                let mux = Multiplexer {
                    address: multiplexer.address,
                    model: Tca9548aModel::default(),
                };
                (pads, Some(mux), shared)
            }
        };
        Self {
            now_ns: 0,
            pads,
            multiplexer,
            shared_tmp117,
            faults: FaultBook::default(),
            counters: Counters::default(),
            bus_frequency_hz: config.bus_frequency_hz,
            pacer: Pacer::new(),
        }
    }

    /// Runs `action` on a converter or temperature model with its environment; `None` for the
    /// multiplexer or a device that does not exist.
    pub(crate) fn with_model<R>(
        &mut self,
        device: DeviceRef,
        action: impl FnOnce(ModelMut<'_>, &mut Environment<'_>) -> R,
    ) -> Option<R> {
        match device {
            DeviceRef::PadFdc1004(index) | DeviceRef::PadTmp117(index) => {
                let pad = self.pads.get_mut(index)?;
                let model = match device {
                    DeviceRef::PadFdc1004(_) => ModelMut::Fdc1004(&mut pad.fdc1004),
                    _ => ModelMut::Tmp117(pad.tmp117.as_mut()?),
                };
                let mut environment = Environment {
                    scene: pad.scene.as_mut(),
                    physics: &mut pad.physics,
                    faults: TargetFaults {
                        book: &mut self.faults,
                        target: FaultTarget::Pad(index),
                    },
                    counters: &mut self.counters,
                    pad: Some(index),
                };
                Some(action(model, &mut environment))
            }
            DeviceRef::SharedTmp117 => {
                let shared = self.shared_tmp117.as_mut()?;
                // The shared sensor feels pad 0's temperature.
                let pad = self.pads.first_mut()?;
                let mut environment = Environment {
                    scene: pad.scene.as_mut(),
                    physics: &mut pad.physics,
                    faults: TargetFaults {
                        book: &mut self.faults,
                        target: FaultTarget::Upstream,
                    },
                    counters: &mut self.counters,
                    pad: None,
                };
                Some(action(
                    ModelMut::Tmp117(&mut shared.model),
                    &mut environment,
                ))
            }
            DeviceRef::Multiplexer => None,
        }
    }

    /// The device event due first (ties: in pad order, each pad's FDC1004 before its TMP117,
    /// the shared TMP117 last).
    fn next_device_event(&self) -> Option<(u64, DeviceRef)> {
        let mut earliest: Option<(u64, DeviceRef)> = None;
        let mut consider = |time_ns: Option<u64>, device: DeviceRef| {
            if let Some(time_ns) = time_ns {
                if earliest.is_none_or(|(first_ns, _)| time_ns < first_ns) {
                    earliest = Some((time_ns, device));
                }
            }
        };
        for (index, pad) in self.pads.iter().enumerate() {
            consider(pad.fdc1004.next_event_ns(), DeviceRef::PadFdc1004(index));
            if let Some(tmp117) = &pad.tmp117 {
                consider(tmp117.next_event_ns(), DeviceRef::PadTmp117(index));
            }
        }
        if let Some(shared) = &self.shared_tmp117 {
            consider(shared.model.next_event_ns(), DeviceRef::SharedTmp117);
        }
        earliest
    }

    /// The next instant after `after_ns` at which a pad may be unplugged or plugged back by a
    /// time window.
    fn next_plug_change_ns(&self, after_ns: u64) -> Option<u64> {
        if !self.faults.contains(is_unplugged) {
            return None;
        }
        (0..self.pads.len())
            .filter_map(|index| {
                self.faults.next_boundary_us(
                    after_ns / 1_000,
                    FaultTarget::Pad(index),
                    is_unplugged,
                )
            })
            .min()
            .map(|boundary_us| boundary_us.saturating_mul(1_000))
    }

    /// Brings every pad's plugged state in line with its [`Fault::Unplugged`] faults at
    /// `time_ns`: an unplugged pad loses power, a pad plugged back powers on afresh.
    pub(crate) fn sync_plugs(&mut self, time_ns: u64) {
        if !self.pads.iter().any(|pad| pad.unplugged) && !self.faults.contains(is_unplugged) {
            return;
        }
        for index in 0..self.pads.len() {
            let unplugged =
                self.faults
                    .any_active(time_ns / 1_000, FaultTarget::Pad(index), is_unplugged);
            let Some(pad) = self.pads.get_mut(index) else {
                continue;
            };
            if unplugged == pad.unplugged {
                continue;
            }
            pad.unplugged = unplugged;
            if unplugged {
                pad.fdc1004.power_off();
                if let Some(tmp117) = pad.tmp117.as_mut() {
                    tmp117.power_off();
                }
            } else {
                pad.fdc1004.power_cycle(time_ns);
                if let Some(tmp117) = pad.tmp117.as_mut() {
                    tmp117.power_cycle(time_ns);
                }
                let target = FaultTarget::Pad(index);
                self.faults.end_until_reset(target, Device::Fdc1004);
                self.faults.end_until_reset(target, Device::Tmp117);
            }
        }
    }

    /// Completes every device event and plug change due up to `target_ns`, in time order (a
    /// plug change first when they coincide), then sets the clock.
    fn advance_to(&mut self, target_ns: u64) {
        let mut cursor_ns = self.now_ns;
        loop {
            let plug_change = self
                .next_plug_change_ns(cursor_ns)
                .filter(|&time_ns| time_ns <= target_ns);
            let device_event = self
                .next_device_event()
                .filter(|&(time_ns, _)| time_ns <= target_ns);
            match (plug_change, device_event) {
                (Some(change_ns), event)
                    if event.is_none_or(|(event_ns, _)| change_ns <= event_ns) =>
                {
                    self.sync_plugs(change_ns);
                    cursor_ns = cursor_ns.max(change_ns);
                }
                (_, Some((event_ns, device))) => {
                    self.with_model(device, |model, environment| match model {
                        ModelMut::Fdc1004(fdc1004) => fdc1004.complete_conversion(environment),
                        ModelMut::Tmp117(tmp117) => tmp117.complete_conversion(environment),
                    });
                    cursor_ns = cursor_ns.max(event_ns);
                }
                (_, None) => break,
            }
        }
        self.now_ns = self.now_ns.max(target_ns);
    }

    pub(crate) fn advance_by_ns(&mut self, duration_ns: u64) {
        self.advance_to(self.now_ns.saturating_add(duration_ns));
    }

    pub(crate) fn pacing_action(&self) -> PacingAction {
        self.pacer.action(self.now_ns)
    }

    /// Pad `index`, if it exists.
    pub(crate) fn pad(&self, index: usize) -> Option<&Pad> {
        self.pads.get(index)
    }

    /// Pad `index`, if it exists.
    pub(crate) fn pad_mut(&mut self, index: usize) -> Option<&mut Pad> {
        self.pads.get_mut(index)
    }

    /// The whole board loses power and gets it back now (see `Simulation::power_cycle`).
    pub(crate) fn power_cycle(&mut self) {
        let now_ns = self.now_ns;
        for pad in self.pads.iter_mut().filter(|pad| !pad.unplugged) {
            pad.fdc1004.power_cycle(now_ns);
            if let Some(tmp117) = pad.tmp117.as_mut() {
                tmp117.power_cycle(now_ns);
            }
        }
        if let Some(shared) = self.shared_tmp117.as_mut() {
            shared.model.power_cycle(now_ns);
        }
        if let Some(multiplexer) = self.multiplexer.as_mut() {
            multiplexer.model.reset();
        }
        self.faults.end_all_until_reset();
        self.sync_plugs(now_ns);
    }
}
