//! The simulated device: the firmware's own acquisition loop, model and protocol code (crates
//! `acquisition` and `device`) wired to the simulated FDC1004 and TMP117, a simulated MCU die
//! sensor, and calibration storage on a RAM model of the flash.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use acquisition::discovery::discover;
use acquisition::pad_bus::MuxedBus;
use acquisition::TemperatureSource;
use acquisition::{Clock, ProcessedSample};
use calibration_store::{CalibrationStore, LoadOutcome, PadRecord, RamFlashError, RecordScope};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::mutex::Mutex;

use crate::flash::{SimulatedFlash, FLASH_REGION_LEN};
use device::{
    BoardAcquisition, BoardParts, CalibrationPersistence, Device, DeviceIdentity, HostPort,
    PersistenceFailed, ResetKind, RetainedState, BOARD, RETAINED_LEN,
};
use model_core::CalibrationSpec;
use sensor_sim::{
    MultiplexerConfig, Pacing, Scene, ScenePoint, SharedTmp117Config, SimDelay, SimI2c, Simulation,
    SimulationConfig, Topology, Window,
};

use crate::scene_file::SceneFile;

/// The id of the simulated pad's factory calibration (0 is the built-in default's).
pub const FACTORY_CALIBRATION_ID: u32 = 1;

/// `pads` simulated pads: one directly on the bus (no multiplexer), or 2..=8 behind a TCA9548A
/// at the board's multiplexer address on channels 0.., each without a TMP117 of its own and
/// with a TMP117 on the main bus that every pad shares.
pub fn pads_topology(pads: usize) -> Topology {
    if pads <= 1 {
        return Topology::SinglePad;
    }
    let channels: Vec<u8> = (0..pads.min(acquisition::discovery::MAX_PADS))
        .filter_map(|channel| u8::try_from(channel).ok())
        .collect();
    Topology::Multiplexed(MultiplexerConfig {
        shared_tmp117: Some(SharedTmp117Config::default()),
        ..MultiplexerConfig::with_pads_on_channels(BOARD.multiplexer.seven_bit(), &channels)
    })
}

/// The simulated clock.
pub struct SimulatedClock {
    simulation: Simulation,
    error: ClockError,
}

impl Clock for SimulatedClock {
    fn now_us(&self) -> u64 {
        self.error.device_us(self.simulation.now_us())
    }
}

/// How a simulated board's crystal differs from true (simulated) time: a rate error and the
/// device time at the simulation's start. The default is an exact clock starting at 0.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ClockError {
    /// Rate error, parts per million (positive: the device clock runs fast; crystals are
    /// typically within +-100).
    pub rate_ppm: f64,
    /// Device time when the simulation starts, µs.
    pub offset_us: u64,
}

impl ClockError {
    /// The device clock at simulated time `true_us`.
    pub fn device_us(&self, true_us: u64) -> u64 {
        let scaled_us = true_us as f64 * (1.0 + self.rate_ppm * 1e-6);
        self.offset_us.saturating_add(scaled_us.max(0.0) as u64)
    }
}

/// Stands in for the MCU's die sensor: the pad temperature plus 2 °C of self-heating.
pub struct SimulatedDieTemperature(Simulation);

impl TemperatureSource for SimulatedDieTemperature {
    type Error = ();

    async fn read_temperature_c(&mut self) -> Result<f32, ()> {
        Ok(self.0.scene_point().temperature_c + 2.0)
    }
}

/// Calibration persistence on the simulated flash, through the firmware's storage code.
pub struct SimulatedPersistence(CalibrationStore<SimulatedFlash>);

impl CalibrationPersistence for SimulatedPersistence {
    type Error = RamFlashError;

    fn load(&mut self, pad: u8) -> Option<LoadOutcome<RamFlashError>> {
        // The RAM flash never waits: the future completes on its first poll.
        Some(embassy_futures::block_on(self.0.load(pad)))
    }

    async fn save(
        &mut self,
        scope: RecordScope,
        record: &PadRecord,
    ) -> Result<(), PersistenceFailed> {
        self.0
            .save_for(scope, record)
            .await
            .map_err(|_| PersistenceFailed)
    }
}

impl SimulatedPersistence {
    /// The store (for tests that inspect or corrupt it).
    pub fn store_mut(&mut self) -> &mut CalibrationStore<SimulatedFlash> {
        &mut self.0
    }
}

/// The simulated sensor bus as the pads share it.
pub type SimulatedBus = Arc<Mutex<CriticalSectionRawMutex, MuxedBus<SimI2c>>>;

/// The acquisition loop on the simulated bus.
pub type SimulatedAcquisition =
    BoardAcquisition<SimulatedBus, SimDelay, SimulatedDieTemperature, SimulatedClock>;

/// How to run the simulated device.
#[derive(Debug, Clone)]
pub struct SimulatedDeviceConfig {
    /// What happens to the pad.
    pub scene: SceneFile,
    /// Noise seed: the same seed, scene and commands give the same stream.
    pub seed: u64,
    /// Simulated seconds per wall-clock second; `None` runs as fast as the host computes.
    pub speed: Option<f64>,
    /// What sits on the simulated bus: one pad (the default), or several behind a multiplexer.
    /// A scene of several pads needs as many ([`SceneFile::pads`], see
    /// [`pads_topology`]); a scene of one pad is played by every pad.
    pub topology: Topology,
    /// The I2C clock the simulated transactions take their time from, Hz (the board's is
    /// [`BUS_FREQUENCY_HZ`]); `None`: transactions take no simulated time.
    pub bus_frequency_hz: Option<u32>,
}

impl SimulatedDeviceConfig {
    /// `scene` on `pads` pads ([`pads_topology`]) with the board's bus clock, the default seed
    /// ([`crate::DEFAULT_SEED`]), as fast as the host computes.
    pub fn new(scene: SceneFile, pads: usize) -> Self {
        Self {
            scene,
            seed: crate::DEFAULT_SEED,
            speed: None,
            topology: pads_topology(pads),
            bus_frequency_hz: BUS_FREQUENCY_HZ,
        }
    }

    /// The same configuration with noise seed `seed`.
    #[must_use]
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The same configuration at `speed` simulated seconds per wall-clock second (`None`: as
    /// fast as the host computes).
    #[must_use]
    pub fn with_speed(mut self, speed: Option<f64>) -> Self {
        self.speed = speed;
        self
    }
}

/// The board's I2C clock ([`device::BoardConfig::i2c_frequency_hz`]).
pub const BUS_FREQUENCY_HZ: Option<u32> = Some(BOARD.i2c_frequency_hz);

/// Why the simulated device could not start.
#[derive(Debug)]
pub enum SimulatedDeviceError {
    /// The simulator refused its configuration.
    Simulation(String),
    /// The flash region does not fit the storage layout.
    Storage,
}

impl std::fmt::Display for SimulatedDeviceError {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimulatedDeviceError::Simulation(message) => {
                write!(formatter, "simulator: {message}")
            }
            SimulatedDeviceError::Storage => formatter.write_str("simulated flash layout"),
        }
    }
}

impl std::error::Error for SimulatedDeviceError {}

/// A scene that starts over after its last keyframe when asked to.
struct RepeatingScene {
    scene: sensor_sim::ScriptedScene,
    period_us: u64,
    repeat: bool,
}

impl Scene for RepeatingScene {
    fn sample(&mut self, time_us: u64) -> ScenePoint {
        let time_us = if self.repeat && self.period_us > 0 {
            time_us % self.period_us
        } else {
            time_us
        };
        self.scene.point_at_s(time_us as f64 / 1e6)
    }
}

/// The simulated device.
pub struct SimulatedDevice {
    device: Device<SimulatedAcquisition, SimulatedPersistence>,
    simulation: Simulation,
    scene: SceneFile,
    seed: u64,
    passes_with_faults: u64,
    // The board's no-init RAM: rewritten after every step, read by the next MCU-only boot.
    retained_ram: [u8; RETAINED_LEN],
    clock_error: ClockError,
    clock_us_per_s: u32,
}

/// How many µs the simulated device's clock counts per second of real time at `speed` (its
/// Info says so, so that a host maps its clock at any speed); 0 when it is not paced.
pub fn clock_us_per_s(speed: Option<f64>) -> u32 {
    speed.map_or(0, |speed| {
        // Saturating float-to-integer cast: a speed beyond 4294 counts as that.
        (speed * f64::from(device::REAL_TIME_CLOCK_US_PER_S)).round() as u32
    })
}

/// The board serial the simulated device reports: "SIMULATED" and the seed's low bytes.
pub fn simulated_board_serial(seed: u64) -> [u8; 12] {
    let mut serial = [0u8; 12];
    serial[..9].copy_from_slice(b"SIMULATED");
    serial[9..].copy_from_slice(&seed.to_be_bytes()[5..]);
    serial
}

impl SimulatedDevice {
    /// Boots the simulated device as it leaves the factory: the simulated pad's factory
    /// calibration (its true curve sampled every 5 kPa, with its parasitic capacitance, as a
    /// careful calibration of a real pad gives; sensor-sim's `matching_calibration`) saved in the
    /// simulated flash through the firmware's storage code, then the firmware's boot: calibration
    /// from flash, converter initialisation and a tare on the first cycles.
    pub fn new(config: SimulatedDeviceConfig) -> Result<Self, SimulatedDeviceError> {
        Self::boot_new(config, true, ClockError::default())
    }

    /// [`SimulatedDevice::new`] on a board whose clock differs from true time by `clock_error`
    /// (several boards on one host, each with its own crystal).
    pub fn with_clock_error(
        config: SimulatedDeviceConfig,
        clock_error: ClockError,
    ) -> Result<Self, SimulatedDeviceError> {
        Self::boot_new(config, true, clock_error)
    }

    /// Boots the simulated device on erased flash, as a board that was never calibrated: it
    /// runs on the built-in default calibration, exactly as the firmware does.
    pub fn with_blank_flash(config: SimulatedDeviceConfig) -> Result<Self, SimulatedDeviceError> {
        Self::boot_new(config, false, ClockError::default())
    }

    fn boot_new(
        config: SimulatedDeviceConfig,
        factory_calibrated: bool,
        clock_error: ClockError,
    ) -> Result<Self, SimulatedDeviceError> {
        let simulation = Simulation::new(SimulationConfig {
            seed: config.seed,
            topology: config.topology.clone(),
            bus_frequency_hz: config.bus_frequency_hz,
            ..SimulationConfig::default()
        })
        .map_err(|error| SimulatedDeviceError::Simulation(format!("{error:?}")))?;
        let period_us = (config.scene.period_s() * 1e6) as u64;
        let scene_pads = config.scene.pads.len();
        if scene_pads > 1 && scene_pads != simulation.pad_count() {
            return Err(SimulatedDeviceError::Simulation(format!(
                "the scene describes {scene_pads} pads and the simulated board has {}",
                simulation.pad_count()
            )));
        }
        for pad in 0..simulation.pad_count() {
            let Some(pad_scene) = config.scene.pad(pad) else {
                continue;
            };
            simulation
                .set_pad_scene(
                    pad,
                    RepeatingScene {
                        scene: pad_scene.scene.clone(),
                        period_us,
                        repeat: config.scene.repeat,
                    },
                )
                .map_err(|error| SimulatedDeviceError::Simulation(format!("{error:?}")))?;
        }
        let mut store = CalibrationStore::new(SimulatedFlash::new(), 0..FLASH_REGION_LEN as u32)
            .map_err(|_| SimulatedDeviceError::Storage)?;
        if factory_calibrated {
            let factory = simulation
                .physics()
                .matching_calibration()
                .map_err(|error| SimulatedDeviceError::Simulation(format!("{error:?}")))?;
            let spec = CalibrationSpec {
                id: FACTORY_CALIBRATION_ID,
                ..factory.to_spec()
            };
            // The factory saves each pad's calibration with the role and geometry its scene
            // gives it, under the pad's multiplexer channel (channel n holds pad n), as
            // SetPadGeometry and SaveCalibration would.
            let pads = simulation.pad_count();
            for pad in 0..pads {
                let Some(pad_scene) = config.scene.pad(pad) else {
                    continue;
                };
                let record = PadRecord {
                    calibration: spec.clone(),
                    role: pad_scene.role,
                    geometry: pad_scene.geometry,
                };
                let scope = match (pads, u8::try_from(pad)) {
                    (1, _) => RecordScope::EveryPad,
                    (_, Ok(channel)) => RecordScope::Pad(channel),
                    (_, Err(_)) => continue,
                };
                embassy_futures::block_on(store.save_for(scope, &record))
                    .map_err(|_| SimulatedDeviceError::Storage)?;
            }
        }
        let device = boot_simulated(
            &simulation,
            SimulatedPersistence(store),
            config.seed,
            ResetKind::PowerOn,
            None,
            clock_error,
            clock_us_per_s(config.speed),
        );
        // Paced from the end of the boot: the boot itself is not played in real time, so that a
        // slow simulation (speed 1e-4) is constructed at once and answers as soon as its pace
        // allows.
        if let Some(speed) = config.speed {
            simulation
                .set_pacing(Pacing::RealTime { speed })
                .map_err(|error| SimulatedDeviceError::Simulation(error.to_string()))?;
        }
        Ok(Self {
            device,
            simulation,
            scene: config.scene,
            seed: config.seed,
            passes_with_faults: 0,
            retained_ram: [0; RETAINED_LEN],
            clock_error,
            clock_us_per_s: clock_us_per_s(config.speed),
        })
    }

    /// Resets the MCU alone, as a watchdog reset or a debugger would: the firmware boots again
    /// (calibration from the simulated flash, baselines and tier from the retained RAM when it
    /// is intact, no tare of a pad that may be loaded) while the converter and the temperature
    /// sensor keep running with the state they had.
    pub fn restart_mcu(&mut self) -> Result<(), SimulatedDeviceError> {
        self.simulation.simulate_mcu_only_reset();
        let flash = std::mem::take(self.device.persistence_mut().store_mut().flash());
        let store = CalibrationStore::new(flash, 0..FLASH_REGION_LEN as u32)
            .map_err(|_| SimulatedDeviceError::Storage)?;
        self.device = boot_simulated(
            &self.simulation,
            SimulatedPersistence(store),
            self.seed,
            ResetKind::McuOnly,
            RetainedState::decode(&self.retained_ram),
            self.clock_error,
            self.clock_us_per_s,
        );
        Ok(())
    }

    /// The simulator (scene, faults, clock).
    pub fn simulation(&self) -> &Simulation {
        &self.simulation
    }

    /// The device application.
    pub fn device_mut(&mut self) -> &mut Device<SimulatedAcquisition, SimulatedPersistence> {
        &mut self.device
    }

    /// One sample set with its requests and frames; returns the first pad's sample (`None`
    /// when no pad was found).
    pub fn step<H: HostPort>(&mut self, host: &mut H) -> Option<ProcessedSample> {
        let mut first = None;
        self.step_observed(host, |sample| first = first.or(Some(*sample)));
        first
    }

    /// One sample set with its requests and frames; `observe` sees every pad's sample.
    pub fn step_observed<H: HostPort>(
        &mut self,
        host: &mut H,
        observe: impl FnMut(&ProcessedSample),
    ) {
        self.schedule_scene_faults();
        embassy_futures::block_on(self.device.step_observed(host, observe));
        self.retained_ram = self.device.retained_record();
    }

    /// Steps until `stop` is set or the scene's simulated time passes `until_s`.
    pub fn run<H: HostPort>(&mut self, host: &mut H, until_s: Option<f64>, stop: &AtomicBool) {
        while !stop.load(Ordering::Relaxed) {
            if until_s.is_some_and(|until_s| self.simulation.now_us() as f64 / 1e6 >= until_s) {
                break;
            }
            self.step(host);
        }
    }

    /// Injects the scene's faults for the current pass (and the next, so that a window that
    /// starts right at the wrap is not missed).
    fn schedule_scene_faults(&mut self) {
        let period_us = (self.scene.period_s() * 1e6) as u64;
        let now_us = self.simulation.now_us();
        let pass = if self.scene.repeat && period_us > 0 {
            now_us / period_us
        } else {
            0
        };
        let passes_needed = if self.scene.repeat { pass + 2 } else { 1 };
        while self.passes_with_faults < passes_needed {
            let offset_us = self.passes_with_faults * period_us;
            for pad in 0..self.simulation.pad_count() {
                let Some(pad_scene) = self.scene.pad(pad) else {
                    continue;
                };
                for fault in &pad_scene.faults {
                    // The pad exists: the loop runs over the simulation's own pads.
                    let _ = self.simulation.inject_on_pad(
                        pad,
                        fault.fault(),
                        Window::Between {
                            start_us: offset_us + (fault.start_s * 1e6) as u64,
                            end_us: offset_us + (fault.end_s * 1e6) as u64,
                        },
                    );
                }
            }
            self.passes_with_faults += 1;
        }
    }
}

/// The firmware's boot (`device::boot`, with the board's configuration `device::BOARD`) on the
/// simulated board's parts: its I2C bus, clock, die sensor and flash.
fn boot_simulated(
    simulation: &Simulation,
    persistence: SimulatedPersistence,
    seed: u64,
    reset: ResetKind,
    retained: Option<RetainedState>,
    clock_error: ClockError,
    clock_us_per_s: u32,
) -> Device<SimulatedAcquisition, SimulatedPersistence> {
    let mut bus = simulation.i2c();
    let topology = embassy_futures::block_on(discover(
        &mut bus,
        &mut simulation.delay(),
        BOARD.multiplexer,
    ));
    let parts = BoardParts {
        bus: Arc::new(Mutex::new(MuxedBus::new(bus, topology.mux))),
        topology,
        delay: simulation.delay(),
        fallback_temperature: SimulatedDieTemperature(simulation.clone()),
        clock: SimulatedClock {
            simulation: simulation.clone(),
            error: clock_error,
        },
        persistence,
        identity: DeviceIdentity {
            firmware_version: device::FIRMWARE_VERSION,
            board_serial: simulated_board_serial(seed),
            clock_us_per_s,
        },
    };
    let (device, _) = device::boot(parts, &BOARD, reset, retained);
    device
}
