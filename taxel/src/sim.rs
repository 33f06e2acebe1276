//! `taxel sim` and `taxel demo`: the simulated device — the firmware's own acquisition, model,
//! storage and protocol code against the simulated FDC1004 and TMP117 — served on a
//! pseudo-terminal that any serial program opens like the board's /dev/ttyACM*.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;

use anyhow::Context;
use clap::Args;
use sim_device::{board_for, load_scene, SimulatedDeviceConfig, SimulatorThread};

use crate::view;

/// Long help of `taxel sim`.
pub const LONG_ABOUT: &str = "Run the simulated device on a pseudo-terminal.\n\n\
The device runs the firmware's own acquisition loop, pressure model, calibration storage and \
protocol against a register-level simulation of the FDC1004 converter and the TMP117 \
temperature sensor, driven by a scene (pressures per taxel and pad temperature over time, plus \
fault windows). Without --scene it plays the built-in demo: a light press on one taxel, a press \
sliding across the pad, the whole pad pressed to 50 kPa, the pad warming 25 -> 45 degC while \
loaded, and a concentrated-load short on one taxel.\n\n\
Several pads: the simulated board then has a TCA9548A multiplexer with one pad per channel and \
a TMP117 on the main bus, found by the firmware's discovery as a real board's would be. \
--scene gripper (two fingers grasping an object that slips) and --scene glove (five \
fingertips and the palm in a whole-hand grasp, one fingertip shorting) are built in; a scene \
file of several pads ([[pad]] tables) gives the board as many pads, and --pads N makes every \
one of N pads play a scene of one pad.\n\n\
Faults: --scene temperature-fallback (the TMP117 lost and back, temperature jumps, beyond 55 \
degC), --scene converter-faults (shorted, open, saturated and frozen channels, a converter \
that stops answering, stalls or reads zeros, the pad's board unplugged) and --scene \
tare-refused (a taxel left out of the tare at power-on) make the device send every event and \
flag a scene can cause; docs/PROTOCOL.md (sections 5.5 and 7) says which comes \
when.\n\n\
It prints the terminal's path (e.g. /dev/pts/7); open it with `taxel view PATH`, `taxel record \
PATH -o out.csv`, pyserial or a terminal. It answers the same commands as the firmware. \
Scene files are TOML: see sim-device/scenes/default.toml (one pad) and \
sim-device/scenes/glove.toml (several).\n\n\
Examples:\n  taxel sim --speed 20 --duration 40 --path-file port.txt\n  taxel sim --scene glove\n  \
taxel sim --pads 8";

/// Long help of `taxel demo`.
pub const DEMO_LONG_ABOUT: &str = "The simulated device and the live view together: see the \
pad work without hardware.\n\n\
The simulated device (see `taxel sim --help`) plays the built-in demo scene, or --scene \
gripper, glove, temperature-fallback, converter-faults, tare-refused or FILE, and the live view (see `taxel view --help`) shows it: the 2x2 heat map with kPa and flags, the \
pressure of each taxel over the last seconds, the temperature and the rates.\n\n\
Keys: t = tare (keep the pad unloaded), p = pause the display, r = start/stop recording to a \
file, m = drop a marker into the recording, q = quit.\n\n\
Examples:\n  taxel demo\n  taxel demo --scene glove\n  taxel demo --speed 10 --snapshot-after 69   (prints one text snapshot \
at the concentrated-load short and exits)";

/// Arguments of `taxel sim`.
#[derive(Debug, Clone, Args)]
pub struct SimArgs {
    /// Scene: a built-in name (default, gripper, glove, temperature-fallback,
    /// converter-faults, tare-refused) or a TOML file; default: the demo.
    #[arg(long, value_name = "NAME|FILE")]
    pub scene: Option<PathBuf>,
    /// Pads on the simulated board (1-8), each playing the scene; default: as many as the
    /// scene describes (one for a scene of one pad).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=8))]
    pub pads: Option<u8>,
    /// Simulated seconds per wall-clock second (1 = real time).
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0)]
    pub speed: f64,
    /// Run as fast as the host computes (ignores --speed).
    #[arg(long)]
    pub fast: bool,
    /// Stop after this many simulated seconds (default: run until interrupted).
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// Seed of the converter noise (the same seed and scene give the same stream).
    #[arg(long, value_name = "N", default_value_t = sim_device::DEFAULT_SEED)]
    pub seed: u64,
    /// Also make a symbolic link to the terminal at this path (replaced if it exists).
    #[arg(long, value_name = "PATH")]
    pub link: Option<PathBuf>,
    /// Write the terminal's path to this file once it is ready (for scripts).
    #[arg(long, value_name = "FILE")]
    pub path_file: Option<PathBuf>,
}

/// Arguments of `taxel demo`.
#[derive(Debug, Clone, Args)]
pub struct DemoArgs {
    /// Scene: a built-in name (default, gripper, glove, temperature-fallback,
    /// converter-faults, tare-refused) or a TOML file; default: the demo.
    #[arg(long, value_name = "NAME|FILE")]
    pub scene: Option<PathBuf>,
    /// Simulated seconds per wall-clock second.
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0)]
    pub speed: f64,
    /// Print one snapshot of the view after this many simulated seconds and exit (no terminal
    /// needed; shows what the live view shows).
    #[arg(long, value_name = "SECONDS")]
    pub snapshot_after: Option<f64>,
}

/// `taxel sim`.
pub fn run(args: &SimArgs) -> anyhow::Result<ExitCode> {
    let scene = load_scene(args.scene.as_deref())?;
    let name = scene.name.clone();
    let speed = if args.fast { None } else { Some(args.speed) };
    if let Some(speed) = speed {
        anyhow::ensure!(
            speed.is_finite() && speed > 0.0,
            "--speed must be a positive number"
        );
    }
    let topology = board_for(&scene, args.pads)?;
    let simulator = SimulatorThread::start(
        SimulatedDeviceConfig {
            scene,
            seed: args.seed,
            speed,
            topology,
            bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
        },
        args.duration,
    )?;
    if let Some(link) = &args.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(simulator.path(), link)
            .with_context(|| format!("linking {}", link.display()))?;
    }
    if let Some(path_file) = &args.path_file {
        // Through a temporary name: a script polling the file never reads half a path.
        let mut file = taxel_host::output_file::OutputFile::create(path_file)?;
        std::io::Write::write_all(&mut file, simulator.path().to_string_lossy().as_bytes())
            .and_then(|()| std::io::Write::flush(&mut file))
            .with_context(|| format!("writing {}", path_file.display()))?;
        file.commit()?;
    }
    taxel_host::outln!("{}", simulator.path().display()).context("writing the port to stdout")?;
    taxel_host::noteln!(
        "simulated device '{}' on {} ({}); Ctrl-C to stop",
        if name.is_empty() { "scene" } else { &name },
        simulator.path().display(),
        match speed {
            Some(speed) => format!("{speed}x real time"),
            None => "as fast as possible".to_string(),
        }
    );
    let interrupted = Arc::new(AtomicBool::new(false));
    let handler_flag = Arc::clone(&interrupted);
    ctrlc::set_handler(move || handler_flag.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    while !interrupted.load(Ordering::Relaxed) && !simulator.finished() {
        thread::sleep(std::time::Duration::from_millis(50));
    }
    simulator.stop();
    if let Some(link) = &args.link {
        let _ = std::fs::remove_file(link);
    }
    taxel_host::noteln!("simulated device stopped");
    Ok(ExitCode::SUCCESS)
}

/// `taxel demo`: the simulated device and the live view in one command.
pub fn run_demo(args: &DemoArgs) -> anyhow::Result<ExitCode> {
    let scene = load_scene(args.scene.as_deref())?;
    anyhow::ensure!(
        args.speed.is_finite() && args.speed > 0.0,
        "--speed must be a positive number"
    );
    let topology = board_for(&scene, None)?;
    let topology_pads = scene.pads.len();
    let scene_name = args
        .scene
        .as_ref()
        .filter(|scene| !scene.exists())
        .map(|scene| scene.to_string_lossy().into_owned())
        .unwrap_or_default();
    let simulator = SimulatorThread::start(
        SimulatedDeviceConfig {
            scene,
            seed: sim_device::DEFAULT_SEED,
            speed: Some(args.speed),
            topology,
            bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
        },
        None,
    )?;
    let port = simulator.path().to_string_lossy().into_owned();
    if let Some(seconds) = args.snapshot_after {
        anyhow::ensure!(
            seconds.is_finite() && seconds >= 0.0,
            "--snapshot-after must be a non-negative number of seconds"
        );
        thread::sleep(std::time::Duration::from_secs_f64(seconds / args.speed));
    }
    let mut view_args = view_args(port, args.snapshot_after.is_some());
    // A built-in scene of several pads has the built-in layout of the same name (gripper,
    // glove): the view places the pads as the scene names them.
    if topology_pads > 1 && crate::layout::Layout::built_in(&scene_name).is_some() {
        view_args.layout = Some(scene_name);
    }
    let result = view::run(&view_args);
    simulator.stop();
    result
}

/// The view's defaults on one port.
fn view_args(port: String, once: bool) -> view::ViewArgs {
    view::ViewArgs::for_port(port, once)
}
