//! `taxel bridge` (the `taxel-bridge` binary): its arguments, and the run that ties the device
//! readers, the simulated devices of `--sim N` and the publisher together.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use sim_device::{scene_config, SimulatorThread};
use taxel_args::{LinkArgs, MultiBoardArgs};
use taxel_host::console::error_message;
use taxel_host::device_link::{open_serial, DeviceLink};
use taxel_host::host_clock::UnixClock;
use taxel_host::noteln;
use taxel_host::output_file::PendingRename;
use taxel_host::session::{DeviceSession, SessionConfig};
use taxel_host::worker::{EventQueue, Overflow, Worker};
use taxel_ros2::pad_messages::{DEFAULT_FRAME_PREFIX, DEFAULT_NAMESPACE};
use wire::{Command, PadIndex, PadInfoFrame, ReplyPayload};
use zenoh::Wait;

use crate::health::{DeviceHealth, ReaderState, STOPPED_WORDS};
use crate::plain::PlainPublisher;
use crate::publisher::{FramePublisher, Naming, RosPublisher, TimingLog};
use crate::relay::{relay_events, Publication, Relay};

/// How long one read of a device's port waits (the worker's threads read in slices of 20 ms).
const PORT_READ_TIMEOUT: Duration = Duration::from_millis(20);

/// Long help of `taxel bridge`.
pub const LONG_ABOUT: &str = "Publish the pads of one or more devices into Zenoh, in the form \
ROS 2's rmw_zenoh uses: CDR-serialised standard messages on key expressions \
<domain>/<topic>/<type>/<type hash>, with liveliness tokens so the publishers appear in the ROS 2 \
graph. Per pad: <namespace>/device<d>/pad<p>/pressure (sensor_msgs/msg/PointCloud2: pressure in Pa \
and flags per taxel), .../wrench (geometry_msgs/msg/WrenchStamped: the force at the centre of \
pressure), .../contact_started and .../contact_ended (std_msgs/msg/Header); per device, its health \
on /diagnostics (diagnostic_msgs/msg/DiagnosticArray). Stamps are the device time mapped onto the \
host clock (a frame or event that waited 3 s for its device's first clock estimate is stamped with \
its arrival); the attachment's sequence number is the device's. See docs/BRIDGE.md.\n\n\
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
    #[arg(long, value_name = "NAMESPACE", default_value = DEFAULT_NAMESPACE)]
    pub namespace: String,
    /// Start of each pad's frame id, followed by device<d>_pad<p>.
    #[arg(long, value_name = "PREFIX", default_value = DEFAULT_FRAME_PREFIX)]
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
    /// Events (sample sets, device events) the queue between the device readers and the
    /// publisher holds; beyond it the oldest sample sets are dropped and counted in the health.
    #[arg(long, value_name = "EVENTS", default_value_t = 4096)]
    pub queue_capacity: usize,
    /// Write one line per published sample frame (device,pad,sequence,arrival_ns,published_ns).
    #[arg(long, value_name = "FILE")]
    pub timing_log: Option<PathBuf>,
    /// Also write every published message to this MCAP file (ROS 2 schemas; Foxglove and
    /// `ros2 bag` open it).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// How long to wait for the devices.
    #[command(flatten)]
    pub link: LinkArgs,
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
    // The host clock's origin comes before anything a device does: a stamp before the origin
    // would be the origin. (A simulated device is paced from its boot; its first sets map back
    // to it.)
    let clock = UnixClock::new();
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    let mut simulators = Vec::new();
    let ports = match args.sim {
        Some(count) => {
            for device in 0..count {
                let config = scene_config(
                    args.sim_scene.as_deref(),
                    args.sim_pads,
                    Some(1.0),
                    u64::from(device) + 1,
                )?;
                simulators.push(SimulatorThread::start(config, None)?);
            }
            simulators
                .iter()
                .map(|simulator| simulator.path().to_string_lossy().into_owned())
                .collect()
        }
        None => args.board.select_ports()?,
    };
    let result = bridge_ports(args, &ports, clock, &stop);
    for simulator in simulators {
        simulator.stop();
    }
    result
}

/// A device's session over its serial port.
type PortSession = DeviceSession<Box<dyn serialport::SerialPort>>;

/// A device's port opened, identified and its pads described (its stream not started yet).
fn open_device(port: &str, timeout: Duration) -> anyhow::Result<(PortSession, Vec<PadInfoFrame>)> {
    let opened = open_serial(port, PORT_READ_TIMEOUT)?;
    let config = SessionConfig {
        request_timeout: timeout,
        follow_state: false,
    };
    let mut session = DeviceSession::open(DeviceLink::new(opened.port), config)?;
    let mut pads = Vec::new();
    for pad in 0..session.info().pad_count {
        let Some(pad) = PadIndex::new(pad) else {
            break;
        };
        if let Ok(ReplyPayload::PadInfo(pad_info)) =
            session.request(Command::PadInfo { pad }, timeout)
        {
            pads.push(pad_info);
        }
    }
    Ok((session, pads))
}

/// The devices of a run: each one's health in the bridge's numbering, and the sessions of
/// those that answered, the worker's device n being the bridge's `worker_devices[n]`.
struct OpenedDevices {
    healths: Vec<DeviceHealth>,
    sessions: Vec<PortSession>,
    worker_devices: Vec<usize>,
}

/// Opens every device; one that does not answer is reported and stays stopped in its health.
/// Fails when none answers.
fn open_devices(ports: &[String], timeout: Duration) -> anyhow::Result<OpenedDevices> {
    let mut devices = OpenedDevices {
        healths: Vec::new(),
        sessions: Vec::new(),
        worker_devices: Vec::new(),
    };
    for (device, port) in ports.iter().enumerate() {
        let mut health = DeviceHealth {
            name: port.clone(),
            ..DeviceHealth::default()
        };
        match open_device(port, timeout) {
            Ok((session, pads)) => {
                health.info = Some(*session.info());
                health.pads = pads;
                health.temperature_sources = vec![None; usize::from(session.info().pad_count)];
                health.state = ReaderState::Streaming;
                devices.sessions.push(session);
                devices.worker_devices.push(device);
            }
            Err(error) => {
                let message = error_message(&error);
                noteln!("device {device} ({port}): {message}");
                health.state = ReaderState::Stopped(message);
            }
        }
        devices.healths.push(health);
    }
    anyhow::ensure!(!devices.sessions.is_empty(), "no device could be read");
    Ok(devices)
}

impl OpenedDevices {
    /// Starts every stream; a device that refuses is reported and dropped from the sessions.
    /// Fails when none starts.
    fn start(&mut self) -> anyhow::Result<()> {
        let sessions = std::mem::take(&mut self.sessions);
        let worker_devices = std::mem::take(&mut self.worker_devices);
        for (mut session, device) in sessions.into_iter().zip(worker_devices) {
            match session.start() {
                Ok(()) => {
                    self.sessions.push(session);
                    self.worker_devices.push(device);
                }
                Err(error) => {
                    let message = error_message(&error);
                    if let Some(health) = self.healths.get_mut(device) {
                        noteln!("device {device} ({}): {message}", health.name);
                        health.state = ReaderState::Stopped(message);
                    }
                }
            }
        }
        anyhow::ensure!(!self.sessions.is_empty(), "no device could be read");
        Ok(())
    }
}

/// A device's closing line, after its name.
fn closing_words(health: &DeviceHealth) -> String {
    let mut words = format!(
        "{}; {} frames published",
        health.accounting.summary(),
        health.frames_published
    );
    if health.stamped_at_arrival > 0 {
        words.push_str(&format!(
            "; {} frames or events stamped with their arrival (no clock estimate)",
            health.stamped_at_arrival
        ));
    }
    if let ReaderState::Stopped(reason) = &health.state {
        if *reason != STOPPED_WORDS {
            words.push_str(&format!("; {reason}"));
        }
    }
    words
}

fn bridge_ports(
    args: &BridgeArgs,
    ports: &[String],
    clock: UnixClock,
    stop: &AtomicBool,
) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.mcap.is_none() || args.mode == Mode::Ros2,
        "--mcap records the ROS 2 messages: it needs --mode ros2"
    );
    let mut devices = open_devices(ports, args.link.timeout())?;
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
    // Written under a temporary name and renamed when the bridge ends cleanly, as every file.
    let (timing_log, timing_pending): (Option<TimingLog>, _) = match &args.timing_log {
        Some(path) => {
            let (writer, pending) = taxel_host::output_file::OutputFile::create(path)?.into_parts();
            (Some(Box::new(writer)), Some(pending))
        }
        None => (None, None),
    };
    // The streams start last, just before their threads read them, so that few sets wait in
    // a port.
    devices.start()?;
    let queue = Arc::new(EventQueue::new(
        args.queue_capacity,
        Overflow::DropOldestSet,
    ));
    let worker = Worker::start(devices.sessions, Arc::clone(&queue), Arc::new(clock))
        .context("starting the devices' reader threads")?;
    let mut relay = Relay::new(clock, devices.healths, devices.worker_devices);
    let mut publication = Publication::new(publisher, timing_log);
    let deadline = args
        .duration
        .map(|seconds| Instant::now() + Duration::from_secs_f64(seconds.max(0.0)));
    let result = relay_events(
        &worker,
        &mut relay,
        &mut publication,
        stop,
        deadline,
        Duration::from_secs(1),
    );
    // Every device's last set and its end are in the queue once the worker has finished.
    drop(worker.finish());
    result?;
    for arrived in queue.drain() {
        let messages = relay.take(arrived);
        publication.send(messages, &relay)?;
    }
    let messages = relay.finish();
    publication.send(messages, &relay)?;
    publication.health(&relay, &queue)?;
    // Flushes and closes the timing log, which can then take its name.
    let counts = publication.finish()?;
    if let Some(pending) = timing_pending {
        pending.commit()?;
    }
    if let Some(ros) = ros {
        if let (Some(file), Some(pending)) = (ros.finish()?, mcap_file) {
            pending.commit_file(file)?;
        }
    }
    for (device, health) in relay.healths(queue.dropped_sets()).iter().enumerate() {
        noteln!(
            "device {device} ({}): {}",
            health.name,
            closing_words(health)
        );
    }
    noteln!(
        "published {} sample frames, {} contact events, {} health reports; {} sample sets dropped by the bridge (queue full)",
        counts.samples,
        counts.contacts,
        counts.diagnostics,
        queue.dropped_sets()
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
