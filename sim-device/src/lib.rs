//! The simulated device on the desktop: the firmware's own acquisition, model, storage and
//! protocol code running against the simulated FDC1004 and TMP117, driven by a scene file, and
//! served on a pseudo-terminal so that any serial program connects to it as to the board.
#![deny(missing_docs)]

pub mod flash;
pub mod memory_port;
pub mod pty;
pub mod scene_file;
pub mod serve;
pub mod simulated_device;
#[cfg(feature = "testing")]
pub mod testing;

pub use flash::{SimulatedFlash, FLASH_REGION_LEN, FLASH_SECTOR_LEN};
pub use memory_port::MemoryPort;
pub use pty::PtyPort;
pub use scene_file::{
    FaultKind, PadScene, SceneFault, SceneFile, SceneFileError, BUILT_IN_SCENES, DEFAULT_SCENE_TOML,
};
pub use sensor_sim::{Pacing, Simulation, Topology};
pub use serve::{board_for, load_scene, scene_config, SimulatorThread, DEFAULT_SEED};
pub use simulated_device::{
    pads_topology, simulated_board_serial, ClockError, SimulatedDevice, SimulatedDeviceConfig,
    SimulatedDeviceError, BUS_FREQUENCY_HZ, FACTORY_CALIBRATION_ID,
};
