//! [`Simulation`], the handle that steers the shared simulation: clock, scenes, faults,
//! counters and peeks. The methods without a pad in their name act on pad 0, the only pad of
//! the single-pad setup; the `pad` variants act on any pad.

use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard};

use crate::bus::SimI2c;
use crate::clock::{InvalidPacing, Pacing, SimDelay};
use crate::config::{ConfigError, SimulationConfig};
use crate::fault::{Fault, FaultId, FaultTarget, Window};
use crate::physics::{PadEffects, PadPhysics};
use crate::scene::{Scene, ScenePoint};
use crate::simulation::{lock, Counters, State};

/// A pad number that the topology does not have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NoSuchPad {
    /// The refused pad number.
    pub pad: usize,
    /// How many pads there are.
    pub pad_count: usize,
}

impl fmt::Display for NoSuchPad {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            formatter,
            "no pad {} (the simulation has {})",
            self.pad, self.pad_count
        )
    }
}

impl std::error::Error for NoSuchPad {}

/// A handle to a simulation; clones share it. See the crate documentation for the sharing
/// model.
#[derive(Clone)]
pub struct Simulation {
    shared: Arc<Mutex<State>>,
}

impl fmt::Debug for Simulation {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter
            .debug_struct("Simulation")
            .field("now_ns", &self.now_ns())
            .finish_non_exhaustive()
    }
}

impl Default for Simulation {
    /// The default configuration, with an unloaded pad at 25 °C.
    fn default() -> Self {
        Self::from_valid_config(SimulationConfig::default())
    }
}

impl Simulation {
    /// A simulation at time 0, every device just powered on, every pad unloaded at 25 °C
    /// (replace the scenes with [`Simulation::set_scene`] and [`Simulation::set_pad_scene`]),
    /// every multiplexer channel off.
    pub fn new(config: SimulationConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self::from_valid_config(config))
    }

    fn from_valid_config(config: SimulationConfig) -> Self {
        Self {
            shared: Arc::new(Mutex::new(State::new(config))),
        }
    }

    fn state(&self) -> MutexGuard<'_, State> {
        lock(&self.shared)
    }

    fn no_such_pad(state: &State, pad: usize) -> NoSuchPad {
        NoSuchPad {
            pad,
            pad_count: state.pads.len(),
        }
    }

    /// A handle to the bus, for a driver.
    pub fn i2c(&self) -> SimI2c {
        SimI2c {
            shared: Arc::clone(&self.shared),
        }
    }

    /// A delay on simulated time, for a driver.
    pub fn delay(&self) -> SimDelay {
        SimDelay {
            shared: Arc::clone(&self.shared),
        }
    }

    /// Simulated time, ns.
    pub fn now_ns(&self) -> u64 {
        self.state().now_ns
    }

    /// Simulated time, µs (rounded down).
    pub fn now_us(&self) -> u64 {
        self.now_ns() / 1_000
    }

    /// Advances simulated time, completing every conversion due on the way, then paces.
    pub fn advance_us(&self, duration_us: u64) {
        self.advance_ns(duration_us.saturating_mul(1_000));
    }

    /// Advances simulated time by nanoseconds (see [`Simulation::advance_us`]).
    pub fn advance_ns(&self, duration_ns: u64) {
        let action = {
            let mut state = self.state();
            state.advance_by_ns(duration_ns);
            state.pacing_action()
        };
        action.run();
    }

    /// How many pads the topology has (1 without a multiplexer).
    pub fn pad_count(&self) -> usize {
        self.state().pads.len()
    }

    /// Replaces pad 0's scene from now on.
    pub fn set_scene(&self, scene: impl Scene + 'static) {
        if let Some(pad) = self.state().pad_mut(0) {
            pad.scene = Box::new(scene);
        }
    }

    /// Replaces a pad's scene from now on.
    pub fn set_pad_scene(&self, pad: usize, scene: impl Scene + 'static) -> Result<(), NoSuchPad> {
        let mut state = self.state();
        let error = Self::no_such_pad(&state, pad);
        let target = state.pad_mut(pad).ok_or(error)?;
        target.scene = Box::new(scene);
        Ok(())
    }

    /// Samples pad 0's scene at the current time.
    pub fn scene_point(&self) -> ScenePoint {
        self.scene_point_of(0).unwrap_or_default()
    }

    /// Samples a pad's scene at the current time (`None`: no such pad).
    pub fn scene_point_of(&self, pad: usize) -> Option<ScenePoint> {
        let mut state = self.state();
        let now_us = state.now_ns / 1_000;
        state.pad_mut(pad).map(|pad| pad.sample(now_us))
    }

    /// Sets how simulated time relates to wall-clock time (anchored at this call). A real-time
    /// sleep in progress on another thread ends at once, so `Pacing::Off` stops a slow
    /// simulation from waiting out its sleeps.
    pub fn set_pacing(&self, pacing: Pacing) -> Result<(), InvalidPacing> {
        let mut state = self.state();
        let now_ns = state.now_ns;
        state.pacer.set(pacing, now_ns)
    }

    /// Injects a fault on pad 0 (a multiplexer fault acts on the multiplexer; see
    /// [`crate::fault`]).
    pub fn inject(&self, fault: Fault, window: Window) -> FaultId {
        self.inject_on(FaultTarget::Pad(0), fault, window)
    }

    /// Injects a fault on a pad's devices (a multiplexer fault acts on the multiplexer).
    pub fn inject_on_pad(
        &self,
        pad: usize,
        fault: Fault,
        window: Window,
    ) -> Result<FaultId, NoSuchPad> {
        {
            let state = self.state();
            if state.pad(pad).is_none() {
                return Err(Self::no_such_pad(&state, pad));
            }
        }
        Ok(self.inject_on(FaultTarget::Pad(pad), fault, window))
    }

    /// Injects a fault on the devices upstream of the multiplexer: the shared TMP117 (and the
    /// multiplexer itself). Pad faults (the FDC1004's, [`Fault::Unplugged`]) injected here act
    /// on nothing; in the single-pad setup the devices on the bus are pad 0's (use
    /// [`Simulation::inject`]).
    pub fn inject_upstream(&self, fault: Fault, window: Window) -> FaultId {
        self.inject_on(FaultTarget::Upstream, fault, window)
    }

    fn inject_on(&self, target: FaultTarget, fault: Fault, window: Window) -> FaultId {
        let mut state = self.state();
        let id = state.faults.inject(target, fault, window);
        let now_ns = state.now_ns;
        state.sync_plugs(now_ns);
        id
    }

    /// Removes an injected fault; false if it had already ended. Removing an unplug plugs the
    /// pad back in now.
    pub fn remove_fault(&self, id: FaultId) -> bool {
        let mut state = self.state();
        let removed = state.faults.remove(id);
        let now_ns = state.now_ns;
        state.sync_plugs(now_ns);
        removed
    }

    /// Removes every injected fault (the channel shift, a device state, stays); unplugged pads
    /// are plugged back in now.
    pub fn clear_faults(&self) {
        let mut state = self.state();
        state.faults.clear();
        let now_ns = state.now_ns;
        state.sync_plugs(now_ns);
    }

    /// Whether a pad is unplugged now (`None`: no such pad).
    pub fn pad_unplugged(&self, pad: usize) -> Option<bool> {
        self.state().pad(pad).map(|pad| pad.unplugged)
    }

    /// The MCU was reset but the FDC1004s were not: from now until a software reset (RST)
    /// each FDC1004 keeps its configuration but each measurement converts the next input
    /// (see [`crate::fdc1004`]). Every pad's converter is affected (they share the MCU).
    pub fn simulate_mcu_only_reset(&self) {
        for pad in self.state().pads.iter_mut().filter(|pad| !pad.unplugged) {
            pad.fdc1004.simulate_mcu_only_reset();
        }
    }

    /// Whether pad 0's FDC1004 has the channel shift in effect.
    pub fn channel_shift_active(&self) -> bool {
        self.state()
            .pad(0)
            .is_some_and(|pad| pad.fdc1004.channel_shift_active())
    }

    /// Every device loses power and gets it back now: registers at reset (the multiplexer's
    /// channels all off), NACK until each one's power-up time has passed, faults lasting until
    /// a reset end (an unplug with [`Window::UntilSoftwareReset`] included). Time goes on.
    pub fn power_cycle(&self) {
        self.state().power_cycle();
    }

    /// Pulses the multiplexer's RESET pin: every channel off (no effect without a
    /// multiplexer).
    pub fn reset_multiplexer(&self) {
        if let Some(multiplexer) = self.state().multiplexer.as_mut() {
            multiplexer.model.reset();
        }
    }

    /// The multiplexer's control register, without a transaction (`None`: no multiplexer).
    pub fn multiplexer_control(&self) -> Option<u8> {
        self.state()
            .multiplexer
            .as_ref()
            .map(|multiplexer| multiplexer.model.control())
    }

    /// The counters.
    pub fn counters(&self) -> Counters {
        self.state().counters
    }

    /// Zeroes the counters.
    pub fn reset_counters(&self) {
        self.state().counters = Counters::default();
    }

    /// Pad 0's physics (with the history effects in force).
    pub fn physics(&self) -> PadPhysics {
        self.pad_physics(0).unwrap_or_default()
    }

    /// A pad's physics (with the history effects in force; `None`: no such pad).
    pub fn pad_physics(&self, pad: usize) -> Option<PadPhysics> {
        self.state()
            .pad(pad)
            .map(|pad| pad.physics.physics().clone())
    }

    /// Turns pad 0's history effects (hysteresis, baseline loss with cycling) on or off from
    /// now on; the history so far (peaks, cycles counted) is kept. Refused, changing nothing,
    /// when a value is out of range.
    pub fn set_pad_effects(&self, effects: PadEffects) -> Result<(), ConfigError> {
        if !effects.is_valid() {
            return Err(ConfigError::Pad);
        }
        if let Some(pad) = self.state().pad_mut(0) {
            pad.physics.set_effects(effects);
        }
        Ok(())
    }

    /// Load cycles each taxel of pad 0 has felt so far (see
    /// [`PadEffects::cycle_threshold_kpa`]); they are counted whether or not the baseline loss
    /// is on.
    pub fn load_cycles(&self) -> [u64; 4] {
        self.state()
            .pad(0)
            .map_or([0; 4], |pad| pad.physics.cycles())
    }

    /// The capacitance of one of pad 0's inputs under the current scene point, without noise
    /// or faults, pF (`None` for a taxel outside 0..4): the ground truth the converter
    /// measures, history effects included (evaluating it does not move the history on).
    pub fn true_capacitance_pf(&self, taxel: usize) -> Option<f64> {
        self.pad_true_capacitance_pf(0, taxel)
    }

    /// [`Simulation::true_capacitance_pf`] of a pad's input (`None`: no such pad or taxel).
    pub fn pad_true_capacitance_pf(&self, pad: usize, taxel: usize) -> Option<f64> {
        let mut state = self.state();
        if taxel >= 4 {
            return None;
        }
        let now_us = state.now_ns / 1_000;
        let pad = state.pad_mut(pad)?;
        let point = pad.sample(now_us);
        Some(
            pad.physics
                .peek(taxel, point.pressure_kpa[taxel], point.temperature_c),
        )
    }

    /// A register of pad 0's FDC1004 as a read would return it now, without the read's side
    /// effects (no latch, DONE untouched, no fault consumed).
    pub fn peek_fdc1004_register(&self, pointer: u8) -> u16 {
        self.peek_pad_fdc1004_register(0, pointer).unwrap_or(0)
    }

    /// [`Simulation::peek_fdc1004_register`] on a pad's FDC1004 (`None`: no such pad).
    pub fn peek_pad_fdc1004_register(&self, pad: usize, pointer: u8) -> Option<u16> {
        let state = self.state();
        let now_ns = state.now_ns;
        state
            .pad(pad)
            .map(|pad| pad.fdc1004.peek_register(pointer, now_ns))
    }

    /// A TMP117 register as a read would return it now, without the read's side effects: pad
    /// 0's own TMP117, else the shared one (0 when there is neither).
    pub fn peek_tmp117_register(&self, pointer: u8) -> u16 {
        self.peek_pad_tmp117_register(0, pointer)
            .or_else(|| self.peek_shared_tmp117_register(pointer))
            .unwrap_or(0)
    }

    /// A register of a pad's own TMP117, without a read's side effects (`None`: no such pad,
    /// or it has no TMP117).
    pub fn peek_pad_tmp117_register(&self, pad: usize, pointer: u8) -> Option<u16> {
        self.state()
            .pad(pad)
            .and_then(|pad| pad.tmp117.as_ref())
            .map(|tmp117| tmp117.peek_register(pointer))
    }

    /// A register of the TMP117 shared on the main bus, without a read's side effects
    /// (`None`: there is none).
    pub fn peek_shared_tmp117_register(&self, pointer: u8) -> Option<u16> {
        self.state()
            .shared_tmp117
            .as_ref()
            .map(|shared| shared.model.peek_register(pointer))
    }
}
