//! Serving the simulated device: a scene by name or file, the board it needs, and the device on
//! its own thread behind a pseudo-terminal (what `taxel sim`, `taxel demo`, the bridge's
//! `--sim` and the tests start).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;

use anyhow::Context;

use crate::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};

/// The scene `--scene` names: a file when one exists at that path, else a built-in scene.
pub fn load_scene(path: Option<&Path>) -> anyhow::Result<SceneFile> {
    match path {
        Some(path) if path.exists() => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading scene {}", path.display()))?;
            SceneFile::parse(&text).with_context(|| format!("scene {}", path.display()))
        }
        Some(name) => SceneFile::built_in(&name.to_string_lossy())
            .with_context(|| format!("no scene file {}", name.display())),
        None => Ok(SceneFile::default_scene()?),
    }
}

/// The simulated board for a scene: `pads` pads (each playing a scene of one pad), or as many as
/// the scene describes.
pub fn board_for(scene: &SceneFile, pads: Option<u8>) -> anyhow::Result<crate::Topology> {
    let described = scene.pads.len();
    let pads = match pads {
        Some(pads) if described > 1 && usize::from(pads) != described => anyhow::bail!(
            "the scene describes {described} pads; --pads {pads} would leave pads without one"
        ),
        Some(pads) => usize::from(pads),
        None => described,
    };
    Ok(crate::pads_topology(pads))
}

/// A running simulated device on its own thread.
pub struct SimulatorThread {
    path: PathBuf,
    stop: Arc<AtomicBool>,
    handle: Option<thread::JoinHandle<()>>,
}

impl SimulatorThread {
    /// Starts the simulated device on a new pseudo-terminal.
    pub fn start(config: SimulatedDeviceConfig, until_s: Option<f64>) -> anyhow::Result<Self> {
        let mut device = SimulatedDevice::new(config)?;
        let mut port = PtyPort::open().context("opening a pseudo-terminal")?;
        let path = port.path().to_path_buf();
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let handle = thread::Builder::new()
            .name("simulated-device".into())
            .spawn(move || {
                device.run(&mut port, until_s, &thread_stop);
                thread_stop.store(true, Ordering::Relaxed);
            })
            .context("starting the simulated device")?;
        Ok(Self {
            path,
            stop,
            handle: Some(handle),
        })
    }

    /// The terminal to open.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the device stopped (duration reached or asked to stop).
    pub fn finished(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Stops the device and waits for its thread.
    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.handle.take() {
            let _ = handle.join();
        }
    }
}

/// The noise seed of a simulated device unless one is given (`taxel sim`, the bridge's `--sim`
/// and the Python `Simulator` alike, so the same scene gives the same stream everywhere).
pub const DEFAULT_SEED: u64 = 1;

/// The configuration of a simulated board playing `scene` (a built-in name or a file; `None`:
/// the demo) with `pads` pads (default: as many as the scene describes), at `speed` simulated
/// seconds per wall-clock second (`None`: as fast as the host computes), with the board's bus
/// clock: what `taxel sim`, the bridge's `--sim`, the Python `Simulator` and the tests start.
pub fn scene_config(
    scene: Option<&Path>,
    pads: Option<u8>,
    speed: Option<f64>,
    seed: u64,
) -> anyhow::Result<SimulatedDeviceConfig> {
    let scene = load_scene(scene)?;
    let topology = board_for(&scene, pads)?;
    Ok(SimulatedDeviceConfig {
        scene,
        seed,
        speed,
        topology,
        bus_frequency_hz: crate::BUS_FREQUENCY_HZ,
    })
}
