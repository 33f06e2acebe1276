//! The bridge's run: the devices (or the simulated devices of `--sim N`) read by the host
//! library's worker, their events relayed to the publisher, until the caller's stop flag, the
//! duration, or every device stopped. What the run needs is a [`BridgeConfig`]; the command line
//! that fills one is the `taxel-bridge` program's.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use sim_device::{scene_config, SimulatorThread};
use taxel_host::console::error_message;
use taxel_host::device_link::{open_serial, DeviceLink};
use taxel_host::device_state::pad_geometry;
use taxel_host::host_clock::UnixClock;
use taxel_host::noteln;
use taxel_host::output_file::PendingRename;
use taxel_host::session::{DeviceSession, SessionConfig};
use taxel_host::worker::{EventQueue, Overflow, Worker};
use wire::{Command, PadIndex, PadInfoFrame, ReplyPayload};
use zenoh::Wait;

use crate::commands::CommandSettings;
use crate::fanout::FanOut;
use crate::foxglove::{FoxgloveNaming, FoxglovePublisher};
use crate::health::{DeviceHealth, ReaderState, STOPPED_WORDS};
use crate::network::Network;
use crate::plain::PlainPublisher;
use crate::publisher::{FramePublisher, Naming, RosPublisher, TimingLog};
use crate::reconnect::Reconnector;
use crate::relay::{relay_events, Publication, Relay};

/// How long one read of a device's port waits (the worker's threads read in slices of 20 ms).
const PORT_READ_TIMEOUT: Duration = Duration::from_millis(20);

/// Events the queue between the device readers and the publisher holds by default.
pub const DEFAULT_QUEUE_CAPACITY: usize = 4096;

/// What the bridge publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// rmw_zenoh's form: standard ROS 2 messages in CDR, type-hashed key expressions, liveliness
    /// tokens.
    Ros2,
    /// Fixed little-endian records on `<namespace>/device<d>/pad<p>/sample` (docs/BRIDGE.md).
    Plain,
}

/// Where the devices come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Devices {
    /// These serial ports, in device order.
    Ports(Vec<String>),
    /// Simulated devices, each the firmware's own code on a pseudo-terminal, in real time.
    Simulated {
        /// How many.
        count: u8,
        /// Their scene: a built-in name or a file (`None`: the demo).
        scene: Option<PathBuf>,
        /// Pads on each (`None`: as many as the scene describes).
        pads: Option<u8>,
    },
}

/// Everything a run needs.
#[derive(Debug, Clone)]
pub struct BridgeConfig {
    /// The devices.
    pub devices: Devices,
    /// What to publish.
    pub mode: Mode,
    /// Domain, namespace, frame ids, node and diagnostics topic.
    pub naming: Naming,
    /// The Zenoh session: what it listens on and connects to.
    pub network: Network,
    /// Stop after this many seconds (`None`: at the stop flag).
    pub duration_s: Option<f64>,
    /// Events the queue between the device readers and the publisher holds; beyond it the
    /// oldest sample sets are dropped and counted in the health.
    pub queue_capacity: usize,
    /// Write one line per published sample frame here.
    pub timing_log: Option<PathBuf>,
    /// Also write every published message to this MCAP file.
    pub mcap: Option<PathBuf>,
    /// How long a device has to answer a request.
    pub request_timeout: Duration,
    /// Serve each device's tare and use case, and each pad's tare, to ROS 2
    /// ([`crate::commands`]); ROS 2 form only.
    pub allow_commands: bool,
    /// The sample sets a tare from ROS 2 averages.
    pub tare_sample_sets: u16,
    /// Also serve the pads to Foxglove on this address ([`crate::foxglove`]); either mode.
    pub foxglove: Option<SocketAddr>,
}

/// Runs the bridge until `stop` is set, the duration has passed, or every device stopped.
pub fn run(config: &BridgeConfig, stop: &AtomicBool) -> anyhow::Result<()> {
    // The host clock's origin comes before anything a device does: a stamp before the origin
    // would be the origin. (A simulated device is paced from its boot; its first sets map back
    // to it.)
    let clock = UnixClock::new();
    let mut simulators = Vec::new();
    let ports = match &config.devices {
        Devices::Simulated { count, scene, pads } => {
            for device in 0..*count {
                let config =
                    scene_config(scene.as_deref(), *pads, Some(1.0), u64::from(device) + 1)?;
                simulators.push(SimulatorThread::start(config, None)?);
            }
            simulators
                .iter()
                .map(|simulator| simulator.path().to_string_lossy().into_owned())
                .collect()
        }
        Devices::Ports(ports) => ports.clone(),
    };
    let result = bridge_ports(config, &ports, clock, stop);
    for simulator in simulators {
        simulator.stop();
    }
    result
}

/// A device's session over its serial port.
pub(crate) type PortSession = DeviceSession<Box<dyn serialport::SerialPort>>;

/// A device's port opened, identified and its pads described (its stream not started yet).
pub(crate) fn open_device(
    port: &str,
    timeout: Duration,
) -> anyhow::Result<(PortSession, Vec<PadInfoFrame>)> {
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

/// The Foxglove view's server on `address`, with every pad of `healths` described, its
/// address said on the console.
fn start_foxglove(
    address: SocketAddr,
    config: &BridgeConfig,
    healths: &[DeviceHealth],
) -> anyhow::Result<FoxglovePublisher> {
    let naming = FoxgloveNaming {
        namespace: config.naming.namespace.clone(),
        frame_prefix: config.naming.frame_prefix.clone(),
    };
    let mut view = FoxglovePublisher::start(address, naming)?;
    for (device, health) in healths.iter().enumerate() {
        for pad_info in &health.pads {
            view.set_geometry(device, pad_info.pad.get(), pad_geometry(pad_info)?)?;
        }
    }
    let reach = if view.address().ip().is_loopback() {
        "this machine only"
    } else {
        "anyone who reaches this address (read-only)"
    };
    noteln!(
        "Foxglove: ws://{} (Open connection, Foxglove WebSocket), reachable from {reach}",
        view.address()
    );
    Ok(view)
}

fn bridge_ports(
    config: &BridgeConfig,
    ports: &[String],
    clock: UnixClock,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        config.mcap.is_none() || config.mode == Mode::Ros2,
        "--mcap records the ROS 2 messages: it needs --mode ros2"
    );
    anyhow::ensure!(
        !config.allow_commands || config.mode == Mode::Ros2,
        "--allow-commands serves ROS 2 services: it needs --mode ros2"
    );
    let mut devices = open_devices(ports, config.request_timeout)?;
    let session = zenoh::open(config.network.zenoh_config()?)
        .wait()
        .map_err(|error| anyhow::anyhow!("opening the Zenoh session: {error}"))?;
    let naming = config.naming.clone();
    let commands_words = if config.allow_commands {
        "commands accepted from ROS 2 (--allow-commands): tare and set_use_case of each device, tare of each pad, from anyone who reaches the bridge"
    } else {
        "no commands accepted"
    };
    noteln!(
        "bridging {} devices ({}) as node {} in domain {} for ROS 2 {}, Zenoh session {}; {}; {commands_words}; Ctrl-C to stop",
        ports.len(),
        ports.join(", "),
        naming.node_name,
        naming.domain_id,
        naming.ros_distro,
        session.zid(),
        config.network.describe()
    );
    // The MCAP file is written under a temporary name and renamed once complete.
    let mut mcap_file = None;
    let recorder = match &config.mcap {
        Some(path) => {
            let pending = PendingRename::beside(path)?;
            let file = std::fs::File::create(pending.path())
                .with_context(|| format!("creating {}", pending.path().display()))?;
            mcap_file = Some(pending);
            let mut recorder = taxel_ros2::McapRecorder::with_distro(
                std::io::BufWriter::new(file),
                naming.ros_distro,
            )?;
            if let Some(name) = path.file_name() {
                recorder.set_file_name(&name.to_string_lossy());
            }
            Some(recorder)
        }
        None => None,
    };
    let mut ros = None;
    let mut plain = None;
    let mut commands = None;
    let publisher: &mut dyn FramePublisher = match config.mode {
        Mode::Ros2 => {
            let publisher = ros.insert(RosPublisher::new(session, naming, recorder)?);
            for (device, health) in devices.healths.iter().enumerate() {
                for pad_info in &health.pads {
                    publisher.set_geometry(device, pad_info.pad.get(), pad_geometry(pad_info)?);
                }
            }
            if config.allow_commands {
                let settings = CommandSettings {
                    tare_sample_sets: config.tare_sample_sets,
                    request_timeout: config.request_timeout,
                };
                // A device that did not answer has no pads known, and so no per-pad tare.
                let pad_counts: Vec<u8> = devices
                    .healths
                    .iter()
                    .map(|health| health.info.map_or(0, |info| info.pad_count))
                    .collect();
                commands = Some(publisher.declare_commands(&pad_counts, settings)?);
            }
            publisher
        }
        Mode::Plain => plain.insert(PlainPublisher::new(session, &config.naming.namespace)),
    };
    let mut foxglove = match config.foxglove {
        Some(address) => Some(start_foxglove(address, config, &devices.healths)?),
        None => None,
    };
    let mut fan_out;
    let publisher: &mut dyn FramePublisher = match foxglove.as_mut() {
        Some(view) => {
            fan_out = FanOut::new(vec![publisher, view]);
            &mut fan_out
        }
        None => publisher,
    };
    // Written under a temporary name and renamed when the bridge ends cleanly, as every file.
    let (timing_log, timing_pending): (Option<TimingLog>, _) = match &config.timing_log {
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
        config.queue_capacity,
        Overflow::DropOldestSet,
    ));
    let mut worker = Worker::start(devices.sessions, Arc::clone(&queue), Arc::new(clock))
        .context("starting the devices' reader threads")?;
    let mut relay = Relay::new(clock, devices.healths, devices.worker_devices);
    // A board unplugged is looked for again on its port; a simulated device's port goes with
    // it, so those stop.
    let mut reconnector = match &config.devices {
        Devices::Ports(ports) => {
            relay.reconnect_devices();
            Some(Reconnector::new(ports.clone(), config.request_timeout))
        }
        Devices::Simulated { .. } => None,
    };
    let mut reconnect = |worker: &mut Worker<Box<dyn serialport::SerialPort>>,
                         relay: &mut Relay| {
        if let Some(reconnector) = reconnector.as_mut() {
            reconnector.poll(worker, relay);
        }
    };
    let mut publication = Publication::new(publisher, timing_log);
    let deadline = config
        .duration_s
        .map(|seconds| Instant::now() + Duration::from_secs_f64(seconds.max(0.0)));
    let result = relay_events(
        &mut worker,
        &mut relay,
        &mut publication,
        commands.as_mut(),
        Some(&mut reconnect),
        stop,
        deadline,
        Duration::from_secs(1),
    );
    if let Some(commands) = commands {
        commands.finish(&relay);
    }
    // Every device's last set and its end are in the queue once the worker has finished.
    drop(worker.finish());
    let published = (|| {
        result?;
        for arrived in queue.drain() {
            let messages = relay.take(arrived);
            publication.send(messages, &relay)?;
        }
        let messages = relay.finish();
        publication.send(messages, &relay)?;
        publication.health(&relay, &queue)?;
        // Flushes and closes the timing log, which can then take its name.
        publication.finish()
    })();
    drop(foxglove);
    // The MCAP file keeps what was published, also when the run failed: a recording is
    // never lost to a later error.
    let recorded = match ros {
        Some(ros) => ros.finish().and_then(|file| match (file, mcap_file) {
            (Some(file), Some(pending)) => pending.commit_file(file),
            _ => Ok(()),
        }),
        None => Ok(()),
    };
    let counts = match (published, &config.mcap) {
        (Ok(counts), _) => counts,
        (Err(error), Some(path)) if recorded.is_ok() => {
            return Err(error.context(format!(
                "the bridge stopped; {} holds the messages published until then",
                path.display()
            )))
        }
        (Err(error), _) => return Err(error),
    };
    recorded?;
    if let Some(pending) = timing_pending {
        pending.commit()?;
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
    Ok(())
}
