//! A register-level simulation of the pad's I2C bus: the TI FDC1004 capacitance-to-digital
//! converter (0x50) and the TI TMP117 temperature sensor (0x48), driven by a scripted physical
//! scene, a simulated clock and injectable faults. Host tests and the desktop simulator run the
//! real drivers against it through `embedded_hal_async::i2c::I2c` ([`SimI2c`]) and
//! `embedded_hal_async::delay::DelayNs` ([`SimDelay`]); a delay advances simulated time instead of
//! sleeping, so minutes of operation run in milliseconds, and every run with the same seed, scene
//! and calls is bit-for-bit the same.
//!
//! Sharing: the whole simulation (clock, scene, both devices, faults, counters) lives behind one
//! `Arc<Mutex<..>>`. [`Simulation`], [`SimI2c`] and [`SimDelay`] are cheap clonable handles to
//! it, so the drivers own their bus and delay while the test or the simulator keeps a
//! [`Simulation`] to steer the scene and inject faults. The lock is held for one call only, never
//! across an `.await` and never while pacing sleeps; the handles are `Send + Sync`.
//!
//! What is modelled, and every assumption the datasheets do not settle, is documented in
//! [`fdc1004`], [`tmp117`], [`physics`] and [`fault`].
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
pub mod fault;
pub mod fdc1004;
pub mod physics;
pub mod scene;
mod simulation;
pub mod tmp117;

pub use bus::{SimI2c, SimI2cError, FDC1004_ADDRESS, TMP117_ADDRESS};
pub use clock::{InvalidPacing, Pacing, PacingCallback, SimDelay};
pub use fault::{Device, Fault, FaultId, Window};
pub use fdc1004::Fdc1004Config;
pub use physics::{Dielectric, PadEffects, PadPhysics, TaxelPhysics};
pub use scene::{Keyframe, Scene, SceneError, ScenePoint, ScriptedScene};
pub use simulation::{ConfigError, Counters, Simulation, SimulationConfig};
pub use tmp117::Tmp117Config;
