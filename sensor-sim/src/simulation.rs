//! The shared simulation: clock, scene, physics, both devices, faults and counters behind one
//! `Arc<Mutex<..>>`, and [`Simulation`], the handle that steers it.

use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use embedded_hal_async::i2c::Operation;

use crate::bus::{transaction_bits, SimI2c, SimI2cError, FDC1004_ADDRESS, TMP117_ADDRESS};
use crate::clock::{InvalidPacing, Pacer, Pacing, PacingAction, SimDelay};
use crate::fault::{Device, Fault, FaultBook, FaultId, Window};
use crate::fdc1004::{Fdc1004Config, Fdc1004Model};
use crate::physics::{PadEffects, PadPhysics, PhysicsModel};
use crate::scene::{Scene, ScenePoint, ScriptedScene};
use crate::tmp117::{Tmp117Config, Tmp117Model};

/// Seed of the default configuration.
pub const DEFAULT_SEED: u64 = 0x7A_5E_15_11;

/// Everything a simulation starts from.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulationConfig {
    /// Seed of the noise generators (the FDC1004 and the TMP117 draw from separate streams).
    pub seed: u64,
    /// The pad.
    pub physics: PadPhysics,
    /// The FDC1004 model's settings.
    pub fdc1004: Fdc1004Config,
    /// The TMP117 model's settings.
    pub tmp117: Tmp117Config,
    /// I2C clock for the duration of transactions, Hz (default 400 kHz); `None`: transactions
    /// take no simulated time.
    pub bus_frequency_hz: Option<u32>,
}

impl Default for SimulationConfig {
    fn default() -> Self {
        Self {
            seed: DEFAULT_SEED,
            physics: PadPhysics::default(),
            fdc1004: Fdc1004Config::default(),
            tmp117: Tmp117Config::default(),
            bus_frequency_hz: Some(400_000),
        }
    }
}

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigError {
    /// A taxel's C0 or modulus is not finite and positive, or its Cp not finite and
    /// non-negative.
    Taxel {
        /// Index of the taxel.
        taxel: usize,
    },
    /// The dielectric's densification or the history effects are out of their ranges (see
    /// [`crate::physics`]).
    Pad,
    /// A noise level is negative or not finite.
    Noise,
    /// The bus frequency is zero.
    BusFrequency,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Taxel { taxel } => write!(
                formatter,
                "taxel {taxel}: C0 and the modulus must be finite and positive, Cp finite and non-negative"
            ),
            ConfigError::Pad => formatter.write_str(
                "the dielectric's densification or the pad's history effects are out of range",
            ),
            ConfigError::Noise => formatter.write_str("noise levels must be finite and >= 0"),
            ConfigError::BusFrequency => formatter.write_str("the bus frequency must not be 0"),
        }
    }
}

impl std::error::Error for ConfigError {}

/// What the simulation counted since it started (or since [`Simulation::reset_counters`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counters {
    /// Transactions on the bus, whatever their address and outcome.
    pub transactions: u64,
    /// Transactions addressed to the FDC1004.
    pub fdc1004_transactions: u64,
    /// Transactions addressed to the TMP117.
    pub tmp117_transactions: u64,
    /// Transactions that failed with a NACK, for any reason.
    pub nacks: u64,
    /// NACKs caused by an injected [`Fault::Nack`].
    pub nacks_injected: u64,
    /// NACKs of a device still powering up.
    pub nacks_powering_up: u64,
    /// NACKs of an address where no device sits.
    pub nacks_unknown_address: u64,
    /// FDC1004 conversions completed (result written, DONE set).
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
}

/// What a device model needs from the rest of the simulation while it works.
pub(crate) struct Environment<'a> {
    pub(crate) scene: &'a mut dyn Scene,
    pub(crate) physics: &'a mut PhysicsModel,
    pub(crate) faults: &'a mut FaultBook,
    pub(crate) counters: &'a mut Counters,
}

/// The whole simulation.
pub(crate) struct State {
    now_ns: u64,
    scene: Box<dyn Scene>,
    physics: PhysicsModel,
    fdc1004: Fdc1004Model,
    tmp117: Tmp117Model,
    faults: FaultBook,
    counters: Counters,
    bus_frequency_hz: Option<u32>,
    pacer: Pacer,
}

/// Locks the simulation. A panic while it was locked (only possible in a test's own code, e.g.
/// a scene closure) leaves the state consistent between calls, so poisoning is ignored.
pub(crate) fn lock(shared: &Mutex<State>) -> MutexGuard<'_, State> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

impl State {
    fn environment(&mut self) -> (Environment<'_>, &mut Fdc1004Model, &mut Tmp117Model) {
        (
            Environment {
                scene: self.scene.as_mut(),
                physics: &mut self.physics,
                faults: &mut self.faults,
                counters: &mut self.counters,
            },
            &mut self.fdc1004,
            &mut self.tmp117,
        )
    }

    /// Completes every device event due up to `target_ns`, in time order, then sets the clock.
    fn advance_to(&mut self, target_ns: u64) {
        loop {
            let fdc1004_next = self
                .fdc1004
                .next_event_ns()
                .filter(|&time| time <= target_ns);
            let tmp117_next = self
                .tmp117
                .next_event_ns()
                .filter(|&time| time <= target_ns);
            let (mut environment, fdc1004, tmp117) = self.environment();
            match (fdc1004_next, tmp117_next) {
                (Some(fdc1004_ns), Some(tmp117_ns)) if tmp117_ns < fdc1004_ns => {
                    tmp117.complete_conversion(&mut environment);
                }
                (Some(_), _) => fdc1004.complete_conversion(&mut environment),
                (None, Some(_)) => tmp117.complete_conversion(&mut environment),
                (None, None) => break,
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

    pub(crate) fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), SimI2cError> {
        self.counters.transactions += 1;
        let now_ns = self.now_ns;
        let now_us = now_ns / 1_000;
        let device = match address {
            FDC1004_ADDRESS => Some(Device::Fdc1004),
            TMP117_ADDRESS => Some(Device::Tmp117),
            _ => None,
        };
        let result = match device {
            None => {
                self.counters.nacks_unknown_address += 1;
                Err(SimI2cError::ADDRESS_NACK)
            }
            Some(device) => {
                let answers = match device {
                    Device::Fdc1004 => {
                        self.counters.fdc1004_transactions += 1;
                        self.fdc1004.answers(now_ns)
                    }
                    Device::Tmp117 => {
                        self.counters.tmp117_transactions += 1;
                        self.tmp117.answers(now_ns)
                    }
                };
                let injected = answers
                    && self
                        .faults
                        .take(now_us, |fault| {
                            (*fault == Fault::Nack(device)).then_some(())
                        })
                        .is_some();
                if !answers {
                    self.counters.nacks_powering_up += 1;
                    Err(SimI2cError::ADDRESS_NACK)
                } else if injected {
                    self.counters.nacks_injected += 1;
                    Err(SimI2cError::ADDRESS_NACK)
                } else {
                    self.run_operations(device, operations, now_ns);
                    Ok(())
                }
            }
        };
        if result.is_err() {
            self.counters.nacks += 1;
        }
        if let Some(frequency_hz) = self.bus_frequency_hz {
            let bits = transaction_bits(operations, result.is_ok());
            self.advance_by_ns((bits * 1_000_000_000).div_ceil(frequency_hz as u64));
        }
        result
    }

    fn run_operations(&mut self, device: Device, operations: &mut [Operation<'_>], now_ns: u64) {
        let (mut environment, fdc1004, tmp117) = self.environment();
        for operation in operations.iter_mut() {
            match (device, operation) {
                (Device::Fdc1004, Operation::Write(bytes)) => {
                    fdc1004.write(bytes, now_ns, &mut environment);
                }
                (Device::Fdc1004, Operation::Read(buffer)) => {
                    fdc1004.read(buffer, now_ns, &mut environment);
                }
                (Device::Tmp117, Operation::Write(bytes)) => {
                    tmp117.write(bytes, now_ns, &mut environment);
                }
                (Device::Tmp117, Operation::Read(buffer)) => {
                    tmp117.read(buffer, now_ns, &mut environment);
                }
            }
        }
    }
}

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
    /// A simulation at time 0, both devices just powered on, the pad unloaded at 25 °C (replace
    /// the scene with [`Simulation::set_scene`]).
    pub fn new(config: SimulationConfig) -> Result<Self, ConfigError> {
        if let Some(taxel) = config.physics.first_invalid_taxel() {
            return Err(ConfigError::Taxel { taxel });
        }
        if !config.physics.pad_is_valid() {
            return Err(ConfigError::Pad);
        }
        let noise_ok = |value: f64| value.is_finite() && value >= 0.0;
        if !noise_ok(config.fdc1004.noise_rms_pf_at_100_sps) || !noise_ok(config.tmp117.noise_rms_c)
        {
            return Err(ConfigError::Noise);
        }
        if config.bus_frequency_hz == Some(0) {
            return Err(ConfigError::BusFrequency);
        }
        Ok(Self::from_valid_config(config))
    }

    fn from_valid_config(config: SimulationConfig) -> Self {
        // Separate streams so that the converter's noise does not depend on how often the
        // temperature is read, and the reverse.
        let tmp117_seed = config.seed ^ 0x9E37_79B9_7F4A_7C15;
        let state = State {
            now_ns: 0,
            scene: Box::new(ScriptedScene::constant(ScenePoint::UNLOADED)),
            physics: PhysicsModel::new(config.physics),
            fdc1004: Fdc1004Model::new(config.fdc1004, config.seed, 0),
            tmp117: Tmp117Model::new(config.tmp117, tmp117_seed, 0),
            faults: FaultBook::default(),
            counters: Counters::default(),
            bus_frequency_hz: config.bus_frequency_hz,
            pacer: Pacer::new(),
        };
        Self {
            shared: Arc::new(Mutex::new(state)),
        }
    }

    fn state(&self) -> MutexGuard<'_, State> {
        lock(&self.shared)
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

    /// Replaces the scene from now on.
    pub fn set_scene(&self, scene: impl Scene + 'static) {
        self.state().scene = Box::new(scene);
    }

    /// Samples the scene at the current time.
    pub fn scene_point(&self) -> ScenePoint {
        let mut state = self.state();
        let now_us = state.now_ns / 1_000;
        state.scene.sample(now_us)
    }

    /// Sets how simulated time relates to wall-clock time (anchored at this call).
    pub fn set_pacing(&self, pacing: Pacing) -> Result<(), InvalidPacing> {
        let mut state = self.state();
        let now_ns = state.now_ns;
        state.pacer.set(pacing, now_ns)
    }

    /// Injects a fault.
    pub fn inject(&self, fault: Fault, window: Window) -> FaultId {
        self.state().faults.inject(fault, window)
    }

    /// Removes an injected fault; false if it had already ended.
    pub fn remove_fault(&self, id: FaultId) -> bool {
        self.state().faults.remove(id)
    }

    /// Removes every injected fault (the channel shift, a device state, stays).
    pub fn clear_faults(&self) {
        self.state().faults.clear();
    }

    /// The MCU was reset but the FDC1004 was not: from now until a software reset (RST) the
    /// FDC1004 keeps its configuration but each measurement converts the next input
    /// (see [`crate::fdc1004`]).
    pub fn simulate_mcu_only_reset(&self) {
        self.state().fdc1004.simulate_mcu_only_reset();
    }

    /// Whether the FDC1004's channel shift is in effect.
    pub fn channel_shift_active(&self) -> bool {
        self.state().fdc1004.channel_shift_active()
    }

    /// Both devices lose power and get it back now: registers at reset, NACK until each one's
    /// power-up time has passed, faults lasting until a reset end. Time goes on.
    pub fn power_cycle(&self) {
        let mut state = self.state();
        let now_ns = state.now_ns;
        state.fdc1004.power_cycle(now_ns);
        state.tmp117.power_cycle(now_ns);
        state.faults.end_until_reset(Device::Fdc1004);
        state.faults.end_until_reset(Device::Tmp117);
    }

    /// The counters.
    pub fn counters(&self) -> Counters {
        self.state().counters
    }

    /// Zeroes the counters.
    pub fn reset_counters(&self) {
        self.state().counters = Counters::default();
    }

    /// The simulated pad's physics (with the history effects in force).
    pub fn physics(&self) -> PadPhysics {
        self.state().physics.physics().clone()
    }

    /// Turns the pad's history effects (hysteresis, baseline loss with cycling) on or off from
    /// now on; the history so far (peaks, cycles counted) is kept. Refused, changing nothing,
    /// when a value is out of range.
    pub fn set_pad_effects(&self, effects: PadEffects) -> Result<(), ConfigError> {
        if !effects.is_valid() {
            return Err(ConfigError::Pad);
        }
        self.state().physics.set_effects(effects);
        Ok(())
    }

    /// Load cycles each taxel has felt so far (see [`PadEffects::cycle_threshold_kpa`]); they
    /// are counted whether or not the baseline loss is on.
    pub fn load_cycles(&self) -> [u64; 4] {
        self.state().physics.cycles()
    }

    /// The capacitance of a taxel's input under the current scene point, without noise or
    /// faults, pF (`None` for a taxel outside 0..4): the ground truth the converter measures,
    /// history effects included (evaluating it does not move the history on).
    pub fn true_capacitance_pf(&self, taxel: usize) -> Option<f64> {
        let mut state = self.state();
        if taxel >= 4 {
            return None;
        }
        let now_us = state.now_ns / 1_000;
        let point = state.scene.sample(now_us);
        Some(
            state
                .physics
                .peek(taxel, point.pressure_kpa[taxel], point.temperature_c),
        )
    }

    /// An FDC1004 register as a read would return it now, without the read's side effects
    /// (no latch, DONE untouched, no fault consumed).
    pub fn peek_fdc1004_register(&self, pointer: u8) -> u16 {
        let state = self.state();
        state.fdc1004.peek_register(pointer, state.now_ns)
    }

    /// A TMP117 register as a read would return it now, without the read's side effects.
    pub fn peek_tmp117_register(&self, pointer: u8) -> u16 {
        self.state().tmp117.peek_register(pointer)
    }
}
