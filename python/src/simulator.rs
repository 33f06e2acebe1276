//! `taxel.Simulator`: the simulated device of `taxel sim` (the firmware's acquisition, model,
//! storage and protocol code against the simulated converter and temperature sensor, playing a
//! scene) on a thread of this process, reached through an in-memory link instead of a
//! pseudo-terminal. It is a `taxel.Device`: the same methods, the same shapes.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use anyhow::Context;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use sim_device::{scene_config, Pacing, SimulatedDevice, Simulation};

use crate::control::Backend;
use crate::device::{queue_sets_checked, timeout_from_s, Device};
use crate::errors::{anyhow_error, ErrorKind};
use crate::memory_link::{memory_link, HostEnd};

/// The read timeout of the in-memory link: one poll waits at most this for bytes.
const LINK_READ_TIMEOUT: Duration = Duration::from_millis(20);

/// The simulated device's thread.
pub struct SimulatorRun {
    stop: Arc<AtomicBool>,
    handle: Option<thread::JoinHandle<()>>,
    host: HostEnd,
    simulation: Simulation,
}

impl Backend for SimulatorRun {
    fn stop(&mut self) {
        self.host.disconnect();
        self.stop.store(true, Ordering::Relaxed);
        // A slow simulation sleeps for a long time per step (a day per simulated second at
        // speed 1e-5): turning the pacing off wakes it, and it sees the stop at once.
        let _ = self.simulation.set_pacing(Pacing::Off);
        if let Some(handle) = self.handle.take() {
            let _ = handle.join();
        }
    }
}

/// A simulated board to start: its scene, speed, seed, pads and link (what
/// :class:`taxel.Simulator` takes, and :class:`taxel.Devices` starts among its devices).
///
/// ``scene``: a built-in scene (``"default"``, ``"gripper"``, ``"glove"``) or a scene TOML
/// file; default: the demo scene of one pad. ``speed``: simulated seconds per wall-clock second
/// (``None``: as fast as the computer goes). ``seed``: converter noise (the same seed and scene
/// give the same samples). ``pads``: pads on the board, each playing a scene of one pad
/// (default: as many as the scene describes). ``link_buffer_bytes``: what the link towards the
/// host holds before the device drops frames.
#[pyclass(frozen, get_all, module = "taxel")]
#[derive(Debug, Clone)]
pub struct SimulatedBoard {
    /// The scene: a built-in name or a TOML file (``None``: the demo scene).
    pub scene: Option<String>,
    /// Simulated seconds per wall-clock second (``None``: as fast as possible).
    pub speed: Option<f64>,
    /// The converter noise's seed.
    pub seed: u64,
    /// Pads on the board (``None``: as many as the scene describes).
    pub pads: Option<u8>,
    /// What the link towards the host holds, bytes.
    pub link_buffer_bytes: usize,
}

#[pymethods]
impl SimulatedBoard {
    #[new]
    #[pyo3(signature = (scene=None, speed=Some(1.0), seed=sim_device::DEFAULT_SEED, pads=None, link_buffer_bytes=262_144))]
    fn new(
        scene: Option<String>,
        speed: Option<f64>,
        seed: u64,
        pads: Option<u8>,
        link_buffer_bytes: usize,
    ) -> PyResult<Self> {
        if let Some(speed) = speed {
            if !(speed.is_finite() && speed > 0.0) {
                return Err(PyValueError::new_err(format!(
                    "speed must be a positive number (got {speed})"
                )));
            }
        }
        if let Some(pads) = pads {
            if !(1..=8).contains(&pads) {
                return Err(PyValueError::new_err(format!(
                    "pads must be 1 to 8 (got {pads})"
                )));
            }
        }
        if link_buffer_bytes < 1024 {
            return Err(PyValueError::new_err(
                "link_buffer_bytes must be at least 1024",
            ));
        }
        Ok(Self {
            scene,
            speed,
            seed,
            pads,
            link_buffer_bytes,
        })
    }

    /// A short description.
    fn __repr__(&self) -> String {
        format!(
            "SimulatedBoard(scene={:?}, speed={:?}, seed={}, pads={:?})",
            self.scene, self.speed, self.seed, self.pads
        )
    }
}

impl SimulatedBoard {
    /// Starts the simulated device on a thread of its own: its run (to stop it), the host's
    /// end of its link, and its scene's name.
    pub fn start(&self, py: Python<'_>) -> PyResult<(SimulatorRun, HostEnd, String)> {
        let board = self.clone();
        let started =
            py.allow_threads(move || -> anyhow::Result<(SimulatorRun, HostEnd, String)> {
                let config = scene_config(
                    board.scene.as_deref().map(Path::new),
                    board.pads,
                    board.speed,
                    board.seed,
                )?;
                let scene_name = config.scene.name.clone();
                let mut device = SimulatedDevice::new(config)?;
                let simulation = device.simulation().clone();
                let (mut device_end, host_end) =
                    memory_link(board.link_buffer_bytes, LINK_READ_TIMEOUT);
                let stop = Arc::new(AtomicBool::new(false));
                let thread_stop = Arc::clone(&stop);
                let handle = thread::Builder::new()
                    .name("taxel-simulated-device".into())
                    .spawn(move || device.run(&mut device_end, None, &thread_stop))
                    .context("starting the simulated device")?;
                let run = SimulatorRun {
                    stop,
                    handle: Some(handle),
                    host: host_end.clone(),
                    simulation,
                };
                Ok((run, host_end, scene_name))
            });
        started.map_err(|error| anyhow_error(&error, ErrorKind::Other))
    }

    /// What a timeout message adds for a slow simulation.
    pub fn slow_hint(&self) -> String {
        self.speed
            .filter(|speed| *speed < 1.0)
            .map_or(String::new(), |speed| {
                format!(" (the simulator runs at speed {speed}: give a longer timeout)")
            })
    }
}

/// The simulated device in this process, with the interface of :class:`taxel.Device`.
///
/// ``scene``: a built-in scene (``"default"``, ``"gripper"``, ``"glove"``) or a scene TOML
/// file; default: the demo scene of one pad. ``speed``: simulated seconds per wall-clock second
/// (``None``: as fast as the computer goes). ``seed``: converter noise (the same seed and scene
/// give the same samples). ``pads``: pads on the board, each playing a scene of one pad
/// (default: as many as the scene describes). ``link_buffer_bytes``: what the link towards the
/// host holds before the device drops frames, as a USB host's buffers would.
#[pyclass(extends = Device, frozen, module = "taxel")]
pub struct Simulator {
    scene_name: String,
}

#[pymethods]
impl Simulator {
    #[new]
    #[pyo3(signature = (scene=None, speed=Some(1.0), seed=sim_device::DEFAULT_SEED, pads=None, timeout=2.0, link_buffer_bytes=262_144, queue_sets=crate::stream::QUEUE_SETS))]
    // Python's keyword arguments, one per option.
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: Option<String>,
        speed: Option<f64>,
        seed: u64,
        pads: Option<u8>,
        timeout: f64,
        link_buffer_bytes: usize,
        queue_sets: usize,
    ) -> PyResult<PyClassInitializer<Self>> {
        let timeout = timeout_from_s(timeout)?;
        let queue_sets = queue_sets_checked(queue_sets)?;
        let board = SimulatedBoard::new(scene, speed, seed, pads, link_buffer_bytes)?;
        let (run, host_end, scene_name) = board.start(py)?;
        let device = Device::connect(
            py,
            Box::new(host_end),
            "simulated".to_owned(),
            timeout,
            Some(Box::new(run)),
            queue_sets,
            &board.slow_hint(),
        )?;
        Ok(PyClassInitializer::from(device).add_subclass(Simulator { scene_name }))
    }

    /// The scene's name (empty for a scene file without one).
    #[getter]
    fn scene(&self) -> String {
        self.scene_name.clone()
    }
}
