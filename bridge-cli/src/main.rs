//! `taxel-bridge` (also `taxel bridge`): the command line of the `taxel-bridge` library. See
//! `taxel-bridge --help` and docs/BRIDGE.md.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use clap::Parser;
use taxel_args::{LinkArgs, MultiBoardArgs};
use taxel_bridge::commands::DEFAULT_TARE_SAMPLE_SETS;
use taxel_bridge::foxglove::DEFAULT_FOXGLOVE_ADDRESS;
use taxel_bridge::network::Network;
use taxel_bridge::publisher::Naming;
use taxel_bridge::run::{run, BridgeConfig, Devices, Mode, DEFAULT_QUEUE_CAPACITY};
use taxel_host::console::error_message;
use taxel_host::noteln;
use taxel_ros2::pad_messages::{DEFAULT_FRAME_PREFIX, DEFAULT_NAMESPACE};
use taxel_ros2::RosDistro;

/// Long help of `taxel bridge`.
const LONG_ABOUT: &str = "Publish the pads of one or more devices into Zenoh, in the form \
ROS 2's rmw_zenoh uses: CDR-serialised standard messages on key expressions \
<domain>/<topic>/<type>/<type hash>, with liveliness tokens so the publishers appear in the ROS 2 \
graph. Per pad: <namespace>/device<d>/pad<p>/pressure (sensor_msgs/msg/PointCloud2: pressure in Pa \
and flags per taxel), .../wrench (geometry_msgs/msg/WrenchStamped: the force at the centre of \
pressure), .../contact_started and .../contact_ended (std_msgs/msg/Header); per device, its health \
on /diagnostics (diagnostic_msgs/msg/DiagnosticArray). Stamps are the device time mapped onto the \
host clock (a frame or event that waited 3 s for its device's first clock estimate is stamped with \
its arrival); the attachment's sequence number is the device's, extended to 64 bits and counted \
from 1 per topic.\n\n\
Commands: none unless --allow-commands, which serves per device <namespace>/device<d>/tare \
(std_srvs/srv/Trigger: every pad), per pad <namespace>/device<d>/pad<p>/tare \
(std_srvs/srv/Trigger: that pad only) and per device <namespace>/device<d>/set_use_case \
(taxel_msgs/srv/SetUseCase) to anyone who reaches the bridge; calibration writes are never \
served.\n\n\
Network: as an rmw_zenoh node, the bridge connects to the Zenoh router on this machine \
(tcp/localhost:7447; it keeps trying while there is none) and does not scout by multicast; it \
listens on loopback only (tcp/127.0.0.1:7448) for a plain Zenoh subscriber on this machine. \
Nothing outside the machine reaches it unless you say so: --listen on another interface, \
--multicast-scouting, or --zenoh-config. See docs/BRIDGE.md.\n\n\
Foxglove: --foxglove [ADDR] also serves the pads, read-only, over the Foxglove WebSocket \
protocol (default 127.0.0.1:8765, this machine only): per pad <namespace>/device<d>/pad<p>/state \
(JSON), a 3D scene of every pad (<namespace>/scene, <namespace>/transforms) and the devices' \
health (<namespace>/health). In Foxglove: Open connection, Foxglove WebSocket, \
ws://127.0.0.1:8765.\n\n\
Examples:\n  taxel bridge --sim 2\n  taxel bridge /dev/ttyACM0\n  \
taxel bridge --serial 0123ABCD --domain-id 3\n  taxel bridge --sim 1 --listen tcp/0.0.0.0:7448\n  \
taxel bridge --sim 1 --sim-scene glove --foxglove";

/// The ROS 2 distribution of the subscribers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum DistroArg {
    /// Humble: rmw_zenoh 0.1.x, no type hashes in key expressions and tokens; MCAP metadata as
    /// Humble's rosbag2 writes it.
    Humble,
    /// Jazzy and later (Kilted, Rolling): RIHS01 type hashes.
    Jazzy,
}

/// What the bridge publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ModeArg {
    /// rmw_zenoh's form: standard ROS 2 messages in CDR, type-hashed key expressions, liveliness
    /// tokens.
    Ros2,
    /// Fixed little-endian records on `<namespace>/device<d>/pad<p>/sample` (docs/BRIDGE.md).
    Plain,
}

/// Arguments of `taxel bridge`.
#[derive(Debug, Clone, Parser)]
#[command(name = "taxel-bridge", version, about = "Publish the pads into Zenoh (ROS 2 compatible)", long_about = LONG_ABOUT)]
struct BridgeArgs {
    /// The devices (ports and serial numbers; default: the only attached board).
    #[command(flatten)]
    board: MultiBoardArgs,
    /// Run N simulated devices instead (no hardware needed).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=16), conflicts_with_all = ["ports", "serial"])]
    sim: Option<u8>,
    /// Scene of the simulated devices: a built-in name (default, gripper, glove,
    /// temperature-fallback, converter-faults, tare-refused) or a TOML file.
    #[arg(long, value_name = "NAME|FILE", requires = "sim")]
    sim_scene: Option<PathBuf>,
    /// Pads on each simulated device (default: as many as the scene describes).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=8), requires = "sim")]
    sim_pads: Option<u8>,
    /// What to publish: ROS 2 messages as rmw_zenoh does (the default), or plain records.
    #[arg(long, value_enum, default_value_t = ModeArg::Ros2)]
    mode: ModeArg,
    /// The ROS 2 distribution of the subscribers: humble (no type hashes in key expressions) or
    /// jazzy (also Kilted and Rolling).
    #[arg(long, value_enum, default_value_t = DistroArg::Jazzy)]
    ros_distro: DistroArg,
    /// ROS_DOMAIN_ID: the first chunk of every key expression (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "ID", env = "ROS_DOMAIN_ID", default_value_t = 0)]
    domain_id: u32,
    /// Namespace of the pad topics.
    #[arg(long, value_name = "NAMESPACE", default_value = DEFAULT_NAMESPACE)]
    namespace: String,
    /// Start of each pad's frame id, followed by device<d>_pad<p>.
    #[arg(long, value_name = "PREFIX", default_value = DEFAULT_FRAME_PREFIX)]
    frame_prefix: String,
    /// The ROS 2 node the publishers belong to.
    #[arg(long, value_name = "NAME", default_value = "taxel_bridge")]
    node_name: String,
    /// Topic of the devices' health.
    #[arg(long, value_name = "TOPIC", default_value = "/diagnostics")]
    diagnostics_topic: String,
    /// Zenoh endpoint to listen on, replacing the default (loopback only,
    /// tcp/127.0.0.1:7448); repeatable. tcp/0.0.0.0:PORT opens the bridge to the network.
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// Do not listen at all (only connect).
    #[arg(long, conflicts_with = "listen")]
    no_listen: bool,
    /// Zenoh endpoint to connect to, replacing the default (rmw_zenoh's router on this machine,
    /// tcp/localhost:7447); repeatable; retried until it answers.
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// Do not connect anywhere (only listen).
    #[arg(long, conflicts_with = "connect")]
    no_connect: bool,
    /// Find and be found by other Zenoh sessions on the local network by UDP multicast (off by
    /// default, as in rmw_zenoh): anyone on the network can then find the bridge.
    #[arg(long)]
    multicast_scouting: bool,
    /// A Zenoh configuration file (JSON5): its network settings replace the defaults above;
    /// the options given are applied on top of it.
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long, value_name = "SECONDS")]
    duration: Option<f64>,
    /// Events (sample sets, device events) the queue between the device readers and the
    /// publisher holds; beyond it the oldest sample sets are dropped and counted in the health.
    #[arg(long, value_name = "EVENTS", default_value_t = DEFAULT_QUEUE_CAPACITY)]
    queue_capacity: usize,
    /// Write one line per published sample frame (device,pad,sequence,arrival_ns,published_ns).
    #[arg(long, value_name = "FILE")]
    timing_log: Option<PathBuf>,
    /// Also write every published message to this MCAP file (ROS 2 schemas; Foxglove and
    /// `ros2 bag` open it).
    #[arg(long, value_name = "FILE")]
    mcap: Option<PathBuf>,
    /// Serve each device's tare (<namespace>/device<d>/tare, std_srvs/srv/Trigger), each pad's
    /// tare (<namespace>/device<d>/pad<p>/tare) and each device's use case
    /// (<namespace>/device<d>/set_use_case, taxel_msgs/srv/SetUseCase) to ROS 2. Anyone who
    /// reaches the bridge can then call them: see docs/BRIDGE.md to restrict callers.
    #[arg(long)]
    allow_commands: bool,
    /// Sample sets a tare from ROS 2 averages (keep the pads unloaded meanwhile); at most 128,
    /// so that the reply comes within rmw_zenoh clients' 10 s query timeout.
    #[arg(long, value_name = "SETS", default_value_t = DEFAULT_TARE_SAMPLE_SETS, value_parser = clap::value_parser!(u16).range(1..=128), requires = "allow_commands")]
    tare_sets: u16,
    /// Also serve the pads to the Foxglove app over the Foxglove WebSocket protocol, read-only,
    /// on ADDR (default 127.0.0.1:8765: this machine only; 0.0.0.0:PORT opens it to the
    /// network). Give ADDR as --foxglove=ADDR, or put --foxglove after the ports.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_FOXGLOVE_ADDRESS)]
    foxglove: Option<SocketAddr>,
    /// How long to wait for the devices.
    #[command(flatten)]
    link: LinkArgs,
}

impl BridgeArgs {
    /// The run's configuration (the boards looked up now).
    fn config(&self) -> anyhow::Result<BridgeConfig> {
        let devices = match self.sim {
            Some(count) => Devices::Simulated {
                count,
                scene: self.sim_scene.clone(),
                pads: self.sim_pads,
            },
            None => Devices::Ports(self.board.select_ports()?),
        };
        let given = |endpoints: &[String]| (!endpoints.is_empty()).then(|| endpoints.to_vec());
        Ok(BridgeConfig {
            devices,
            mode: match self.mode {
                ModeArg::Ros2 => Mode::Ros2,
                ModeArg::Plain => Mode::Plain,
            },
            naming: Naming {
                ros_distro: match self.ros_distro {
                    DistroArg::Humble => RosDistro::Humble,
                    DistroArg::Jazzy => RosDistro::Jazzy,
                },
                domain_id: self.domain_id,
                namespace: self.namespace.clone(),
                frame_prefix: self.frame_prefix.clone(),
                node_name: self.node_name.clone(),
                diagnostics_topic: self.diagnostics_topic.clone(),
            },
            network: Network {
                listen: if self.no_listen {
                    Some(Vec::new())
                } else {
                    given(&self.listen)
                },
                connect: if self.no_connect {
                    Some(Vec::new())
                } else {
                    given(&self.connect)
                },
                multicast_scouting: self.multicast_scouting.then_some(true),
                config_file: self.zenoh_config.clone(),
            },
            duration_s: self.duration,
            queue_capacity: self.queue_capacity,
            timing_log: self.timing_log.clone(),
            mcap: self.mcap.clone(),
            request_timeout: self.link.timeout(),
            allow_commands: self.allow_commands,
            tare_sample_sets: self.tare_sets,
            foxglove: self.foxglove,
        })
    }
}

fn bridge(args: &BridgeArgs) -> anyhow::Result<()> {
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    run(&args.config()?, &stop)
}

fn main() -> ExitCode {
    let args = BridgeArgs::parse();
    match bridge(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            noteln!("error: {}", error_message(&error));
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;
    use taxel_bridge::network::{DEFAULT_LISTEN, DEFAULT_ROUTER};

    #[test]
    fn command_line_definition_is_consistent() {
        BridgeArgs::command().debug_assert();
        let args = BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "2"]).unwrap();
        assert_eq!(args.sim, Some(2));
        assert_eq!(args.mode, ModeArg::Ros2);
        assert!(BridgeArgs::try_parse_from(["taxel-bridge", "/dev/x", "--sim", "2"]).is_err());
    }

    #[test]
    fn no_network_option_is_the_library_default() {
        let args = BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "1"]).unwrap();
        let network = args.config().unwrap().network;
        assert_eq!(network, Network::default());
        assert_eq!(
            network.describe(),
            format!(
                "listening on {DEFAULT_LISTEN}, connecting to {DEFAULT_ROUTER} (retried), multicast scouting off"
            )
        );
        let args =
            BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "1", "--no-listen"]).unwrap();
        assert_eq!(args.config().unwrap().network.listen, Some(Vec::new()));
    }

    #[test]
    fn commands_are_off_and_jazzy_is_the_distribution_unless_asked() {
        let config = BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "1"])
            .unwrap()
            .config()
            .unwrap();
        assert!(!config.allow_commands);
        assert_eq!(config.naming.ros_distro, RosDistro::Jazzy);
        let config = BridgeArgs::try_parse_from([
            "taxel-bridge",
            "--sim",
            "1",
            "--allow-commands",
            "--tare-sets",
            "8",
            "--ros-distro",
            "humble",
        ])
        .unwrap()
        .config()
        .unwrap();
        assert!(config.allow_commands);
        assert_eq!(config.tare_sample_sets, 8);
        assert_eq!(config.naming.ros_distro, RosDistro::Humble);
        assert!(
            BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "1", "--tare-sets", "8"]).is_err()
        );
    }

    #[test]
    fn foxglove_is_off_unless_asked_and_on_loopback_when_no_address_is_given() {
        let config = |args: &[&str]| {
            BridgeArgs::try_parse_from(["taxel-bridge", "--sim", "1"].iter().chain(args))
                .unwrap()
                .config()
                .unwrap()
                .foxglove
        };
        assert_eq!(config(&[]), None);
        let default = config(&["--foxglove"]).unwrap();
        assert!(default.ip().is_loopback());
        assert_eq!(default.port(), 8765);
        assert_eq!(
            config(&["--foxglove", "0.0.0.0:9000"]),
            Some("0.0.0.0:9000".parse().unwrap())
        );
        assert_eq!(
            config(&["--foxglove=127.0.0.1:0", "--duration", "1"]),
            Some("127.0.0.1:0".parse().unwrap())
        );
        assert!(
            BridgeArgs::try_parse_from(["taxel-bridge", "--foxglove", "/dev/ttyACM0"]).is_err()
        );
    }
}
