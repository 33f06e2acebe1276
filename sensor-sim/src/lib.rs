//! A register-level simulation of the pad's I2C bus: the TI FDC1004 capacitance-to-digital
//! converter (0x50) and the TI TMP117 temperature sensor (0x48), optionally several pads behind
//! a TI TCA9548A multiplexer, driven by a scripted physical scene, a simulated clock and
//! injectable faults. Host tests and the desktop simulator run the real drivers against it
//! through `embedded_hal_async::i2c::I2c` ([`SimI2c`]) and `embedded_hal_async::delay::DelayNs`
//! ([`SimDelay`]); a delay advances simulated time instead of sleeping, so minutes of operation
//! run in milliseconds, and every run with the same seed, scene and calls is bit-for-bit the
//! same.
//!
//! Sharing: the whole simulation (clock, scenes, devices, faults, counters) lives behind one
//! `Arc<Mutex<..>>`. [`Simulation`], [`SimI2c`] and [`SimDelay`] are cheap clonable handles to
//! it, so the drivers own their bus and delay while the test or the simulator keeps a
//! [`Simulation`] to steer the scene and inject faults. The lock is held for one call only, never
//! across an `.await` and never while pacing sleeps; the handles are `Send + Sync`.
//!
//! What is modelled, and every assumption the datasheets do not settle, is documented in
//! [`fdc1004`], [`tmp117`], [`tca9548a`], [`physics`] and [`fault`].
//!
//! # Topology
//!
//! By default ([`Topology::SinglePad`]) the bus carries one pad: its FDC1004 at 0x50 and its
//! TMP117 at 0x48. [`Topology::Multiplexed`] puts up to eight pads behind a TCA9548A (at
//! 0x70..=0x77), one per channel, each with its own physics, scene, FDC1004, optional TMP117
//! at 0x48 and faults, plus an optional TMP117 shared on the main bus at 0x48..=0x4B. A device
//! behind channel n is on the bus only while the multiplexer connects channel n; devices that
//! share an address on the connected wires all take a transaction, and a read returns the AND
//! of their bytes, as on an open-drain bus (counted in [`Counters::address_conflicts`]). Every
//! converter keeps its own conversion timing against the shared clock, so the pads convert in
//! parallel. Methods without a pad in their name ([`Simulation::set_scene`],
//! [`Simulation::inject`], ...) act on pad 0; their `pad` variants act on any pad.
//!
//! ```
//! use embedded_hal_async::i2c::I2c;
//! use sensor_sim::{MultiplexerConfig, Simulation, SimulationConfig, Topology};
//!
//! let simulation = Simulation::new(SimulationConfig {
//!     topology: Topology::Multiplexed(MultiplexerConfig::with_pads_on_channels(0x70, &[0, 1])),
//!     ..SimulationConfig::default()
//! })?;
//! simulation.advance_us(10_000);
//! let mut bus = simulation.i2c();
//! let mut device_id = [0u8; 2];
//! // No channel enabled: nobody at 0x50.
//! assert!(embassy_futures::block_on(bus.write_read(0x50, &[0xFF], &mut device_id)).is_err());
//! // Channel 1 (pad 1) on: its FDC1004 answers.
//! embassy_futures::block_on(bus.write(0x70, &[0b10])).unwrap();
//! embassy_futures::block_on(bus.write_read(0x50, &[0xFF], &mut device_id)).unwrap();
//! assert_eq!(u16::from_be_bytes(device_id), 0x1004);
//! assert_eq!(simulation.counters().pads[1].transactions, 1);
//! # Ok::<(), sensor_sim::ConfigError>(())
//! ```
//!
//! ```
//! use embedded_hal_async::i2c::I2c;
//! use sensor_sim::{ScenePoint, ScriptedScene, Simulation};
//!
//! let simulation = Simulation::default();
//! simulation.set_scene(ScriptedScene::constant(ScenePoint::new([10.0, 0.0, 0.0, 0.0], 25.0)));
//! simulation.advance_us(10_000);
//! let mut bus = simulation.i2c();
//! let mut device_id = [0u8; 2];
//! embassy_futures::block_on(bus.write_read(0x50, &[0xFF], &mut device_id)).unwrap();
//! assert_eq!(u16::from_be_bytes(device_id), 0x1004);
//! ```

pub mod bus;
pub mod clock;
mod config;
pub mod fault;
pub mod fdc1004;
mod handle;
pub mod physics;
mod routing;
pub mod scene;
mod simulation;
pub mod tca9548a;
pub mod tmp117;

pub use bus::{SimI2c, SimI2cError, FDC1004_ADDRESS, TMP117_ADDRESS};
pub use clock::{InvalidPacing, Pacing, PacingCallback, SimDelay};
pub use config::{
    ConfigError, MultiplexerConfig, PadConfig, SharedTmp117Config, SimulationConfig, Topology,
    DEFAULT_SEED, MAX_PADS, TMP117_ADDRESS_FIRST, TMP117_ADDRESS_LAST,
};
pub use fault::{Device, Fault, FaultId, Window};
pub use fdc1004::Fdc1004Config;
pub use handle::{NoSuchPad, Simulation};
pub use physics::{Dielectric, PadEffects, PadPhysics, TaxelPhysics};
pub use scene::{Keyframe, Scene, SceneError, ScenePoint, ScriptedScene};
pub use simulation::{Counters, PadCounters};
pub use tmp117::Tmp117Config;
