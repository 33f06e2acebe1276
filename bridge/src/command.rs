//! `taxel bridge` (the `taxel-bridge` binary): its arguments, and the run that ties the device
//! readers, the simulated devices of `--sim N` and the publisher together.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use sim_device::SimulatedDeviceConfig;
use sim_device::{load_scene, SimulatorThread};
use taxel_args::MultiBoardArgs;
use taxel_host::device_link::open_serial;
use taxel_host::noteln;
use taxel_host::output_file::PendingRename;
use zenoh::Wait;

use crate::device_reader::{lock, read_device, BridgeClock, DeviceHealth, ReaderState};
use crate::plain::PlainPublisher;
use crate::publisher::{publish_loop, FramePublisher, Naming, RosPublisher, TimingLog};

/// Long help of `taxel bridge`.
pub const LONG_ABOUT: &str = "Publish the pads of one or more devices into Zenoh, in the form \
ROS 2's rmw_zenoh uses: CDR-serialised standard messages on key expressions \
<domain>/<topic>/<type>/<type hash>, with liveliness tokens so the publishers appear in the ROS 2 \
graph. Per pad: <namespace>/device<d>/pad<p>/pressure (sensor_msgs/msg/PointCloud2: pressure in Pa \
and flags per taxel), .../wrench (geometry_msgs/msg/WrenchStamped: the force at the centre of \
pressure), .../contact_started and .../contact_ended (std_msgs/msg/Header); per device, its health \
on /diagnostics (diagnostic_msgs/msg/DiagnosticArray). Stamps are the device time mapped onto the \
host clock; the attachment's sequence number is the device's. See docs/BRIDGE.md.\n\n\
Examples:\n  taxel bridge --sim 2\n  taxel bridge /dev/ttyACM0 --connect tcp/localhost:7447\n  \
taxel bridge --serial 0123ABCD --domain-id 3";

/// What the bridge publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// rmw_zenoh's form: standard ROS 2 messages in CDR, type-hashed key expressions, liveliness
    /// tokens.
    Ros2,
    /// Fixed little-endian records on `<namespace>/device<d>/pad<p>/sample` (docs/BRIDGE.md).
    Plain,
}

/// Arguments of `taxel bridge`.
#[derive(Debug, Clone, Parser)]
#[command(name = "taxel-bridge", version, about = "Publish the pads into Zenoh (ROS 2 compatible)", long_about = LONG_ABOUT)]
pub struct BridgeArgs {
    /// The devices (ports and serial numbers; default: the only attached board).
    #[command(flatten)]
    pub board: MultiBoardArgs,
    /// Run N simulated devices instead (no hardware needed).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=16), conflicts_with_all = ["ports", "serial"])]
    pub sim: Option<u8>,
    /// Scene of the simulated devices: a built-in name (default, gripper, glove) or a TOML file.
    #[arg(long, value_name = "NAME|FILE", requires = "sim")]
    pub sim_scene: Option<PathBuf>,
    /// Pads on each simulated device (default: as many as the scene describes).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=8), requires = "sim")]
    pub sim_pads: Option<u8>,
    /// What to publish: ROS 2 messages as rmw_zenoh does (the default), or plain records.
    #[arg(long, value_enum, default_value_t = Mode::Ros2)]
    pub mode: Mode,
    /// ROS_DOMAIN_ID: the first chunk of every key expression (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "ID", env = "ROS_DOMAIN_ID", default_value_t = 0)]
    pub domain_id: u32,
    /// Namespace of the pad topics.
    #[arg(long, value_name = "NAMESPACE", default_value = "/taxel")]
    pub namespace: String,
    /// Start of each pad's frame id, followed by device<d>_pad<p>.
    #[arg(long, value_name = "PREFIX", default_value = "taxel_")]
    pub frame_prefix: String,
    /// The ROS 2 node the publishers belong to.
    #[arg(long, value_name = "NAME", default_value = "taxel_bridge")]
    pub node_name: String,
    /// Topic of the devices' health.
    #[arg(long, value_name = "TOPIC", default_value = "/diagnostics")]
    pub diagnostics_topic: String,
    /// Zenoh endpoint to listen on (e.g. tcp/127.0.0.1:7448); repeatable.
    #[arg(long, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Zenoh endpoint to connect to (rmw_zenoh's router: tcp/localhost:7447); repeatable.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Do not look for other Zenoh sessions by UDP multicast (rmw_zenoh's default).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// A Zenoh configuration file (JSON5); the options above are applied on top of it.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// Frames the queue between the device readers and the publisher holds; beyond it frames
    /// are dropped and counted in the health.
    #[arg(long, value_name = "FRAMES", default_value_t = 4096)]
    pub queue_capacity: usize,
    /// Write one line per published sample frame (device,pad,sequence,arrival_ns,published_ns).
    #[arg(long, value_name = "FILE")]
    pub timing_log: Option<PathBuf>,
    /// Also write every published message to this MCAP file (ROS 2 schemas; Foxglove and
    /// `ros2 bag` open it).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// How long to wait for each reply from a device, ms.
    #[arg(long, value_name = "MS", default_value_t = 2000)]
    pub timeout_ms: u64,
}

fn zenoh_config(args: &BridgeArgs) -> anyhow::Result<zenoh::Config> {
    let error = |error: zenoh::Error| anyhow::anyhow!("zenoh configuration: {error}");
    let mut config = match &args.zenoh_config {
        Some(path) => zenoh::Config::from_file(path).map_err(error)?,
        None => zenoh::Config::default(),
    };
    let list = |endpoints: &[String]| {
        let quoted: Vec<String> = endpoints
            .iter()
            .map(|endpoint| format!("{endpoint:?}"))
            .collect();
        format!("[{}]", quoted.join(","))
    };
    if !args.listen.is_empty() {
        config
            .insert_json5("listen/endpoints", &list(&args.listen))
            .map_err(error)?;
    }
    if !args.connect.is_empty() {
        config
            .insert_json5("connect/endpoints", &list(&args.connect))
            .map_err(error)?;
    }
    if args.no_multicast_scouting {
        config
            .insert_json5("scouting/multicast/enabled", "false")
            .map_err(error)?;
    }
    Ok(config)
}

/// Runs `taxel bridge` until Ctrl-C, `--duration`, or every device stopped.
pub fn run(args: &BridgeArgs) -> anyhow::Result<ExitCode> {
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    let mut simulators = Vec::new();
    let ports = match args.sim {
        Some(count) => {
            let scene = load_scene(args.sim_scene.as_deref())?;
            let pads = args.sim_pads.map_or(scene.pads.len(), usize::from);
            for device in 0..count {
                let simulator = SimulatorThread::start(
                    SimulatedDeviceConfig {
                        scene: scene.clone(),
                        seed: u64::from(device) + 1,
                        speed: Some(1.0),
                        topology: sim_device::pads_topology(pads),
                        bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
                    },
                    None,
                )?;
                simulators.push(simulator);
            }
            simulators
                .iter()
                .map(|simulator| simulator.path().to_string_lossy().into_owned())
                .collect()
        }
        None => args.board.select_ports()?,
    };
    let result = bridge_ports(args, &ports, &stop);
    for simulator in simulators {
        simulator.stop();
    }
    result
}

fn bridge_ports(
    args: &BridgeArgs,
    ports: &[String],
    stop: &AtomicBool,
) -> anyhow::Result<ExitCode> {
    let mut opened = Vec::new();
    for port in ports {
        opened.push(open_serial(port, Duration::from_millis(100))?.port);
    }
    let session = zenoh::open(zenoh_config(args)?)
        .wait()
        .map_err(|error| anyhow::anyhow!("opening the Zenoh session: {error}"))?;
    let naming = Naming {
        domain_id: args.domain_id,
        namespace: args.namespace.clone(),
        frame_prefix: args.frame_prefix.clone(),
        node_name: args.node_name.clone(),
        diagnostics_topic: args.diagnostics_topic.clone(),
    };
    noteln!(
        "bridging {} devices ({}) as node {} in domain {}, Zenoh session {}; Ctrl-C to stop",
        ports.len(),
        ports.join(", "),
        naming.node_name,
        naming.domain_id,
        session.zid()
    );
    anyhow::ensure!(
        args.mcap.is_none() || args.mode == Mode::Ros2,
        "--mcap records the ROS 2 messages: it needs --mode ros2"
    );
    // The MCAP file is written under a temporary name and renamed once complete.
    let mut mcap_file = None;
    let recorder = match &args.mcap {
        Some(path) => {
            let pending = PendingRename::beside(path)?;
            let file = std::fs::File::create(pending.path())
                .with_context(|| format!("creating {}", pending.path().display()))?;
            mcap_file = Some(pending);
            Some(taxel_ros2::McapRecorder::new(std::io::BufWriter::new(
                file,
            ))?)
        }
        None => None,
    };
    let mut ros = None;
    let mut plain = None;
    let publisher: &mut dyn FramePublisher = match args.mode {
        Mode::Ros2 => ros.insert(RosPublisher::new(session, naming, recorder)?),
        Mode::Plain => plain.insert(PlainPublisher::new(session, &args.namespace)),
    };
    let timing_log: Option<TimingLog> = match &args.timing_log {
        Some(path) => Some(Box::new(std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        ))),
        None => None,
    };
    let clock = BridgeClock::new();
    let healths: Vec<Arc<Mutex<DeviceHealth>>> = ports
        .iter()
        .map(|port| {
            Arc::new(Mutex::new(DeviceHealth {
                name: port.clone(),
                ..DeviceHealth::default()
            }))
        })
        .collect();
    let (sender, receiver) = sync_channel(args.queue_capacity.max(1));
    let timeout = Duration::from_millis(args.timeout_ms);
    let deadline = args
        .duration
        .map(|seconds| Instant::now() + Duration::from_secs_f64(seconds.max(0.0)));
    let counts = std::thread::scope(|scope| {
        for (device, port) in opened.into_iter().enumerate() {
            let sender = sender.clone();
            let health = Arc::clone(&healths[device]);
            let clock = &clock;
            scope.spawn(move || {
                if let Err(error) = read_device(device, port, clock, sender, &health, stop, timeout)
                {
                    let message = taxel_host::console::error_message(&error);
                    noteln!("device {device}: {message}");
                    lock(&health).state = ReaderState::Stopped(message);
                }
            });
        }
        drop(sender);
        if let Some(deadline) = deadline {
            scope.spawn(move || {
                while !stop.load(Ordering::Relaxed) && Instant::now() < deadline {
                    std::thread::sleep(Duration::from_millis(20));
                }
                stop.store(true, Ordering::Relaxed);
            });
        }
        let counts = publish_loop(
            publisher,
            &receiver,
            &healths,
            stop,
            Duration::from_secs(1),
            timing_log,
        );
        stop.store(true, Ordering::Relaxed);
        counts
    })?;
    if let Some(ros) = ros {
        if let (Some(file), Some(pending)) = (ros.finish()?, mcap_file) {
            pending.commit_file(file)?;
        }
    }
    for (device, health) in healths.iter().enumerate() {
        let health = lock(health);
        noteln!(
            "device {device} ({}): {}; {} dropped by the bridge",
            health.name,
            health.accounting.summary(),
            health.queue_dropped + health.waiting_dropped
        );
    }
    noteln!(
        "published {} sample frames, {} contact events, {} health reports",
        counts.samples,
        counts.contacts,
        counts.diagnostics
    );
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        BridgeArgs::command().debug_assert();
        let args = BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "2"]).unwrap();
        assert_eq!(args.sim, Some(2));
        assert_eq!(args.mode, Mode::Ros2);
        assert!(BridgeArgs::try_parse_from(["taxel-bridge", "/dev/x", "--sim", "2"]).is_err());
    }
}
