//! The Zenoh side in the ROS 2 form: one session, the node's and every publisher's liveliness
//! token, one Zenoh publisher per topic (declared when the topic's first message comes), and
//! each device's health on the diagnostics topic; with `--mcap`, every message put is also
//! written, with the same bytes and sequence number, to an MCAP file. Each publisher's GID is
//! rmw_zenoh's (XXH3-128 of its token, [`crate::names::gid`]); its sequence numbers start at 1
//! and are 64 bits wide ([`crate::sequence`]).
//!
//! Publishers wait when the network is congested (`CongestionControl::Block`, as rmw_zenoh's
//! reliable keep-all publishers do) rather than drop silently: Zenoh does not tell a publisher
//! what it dropped, so the one place sample sets are dropped is the worker's bounded queue in
//! front of the publishing loop ([`crate::relay`]), where each drop is counted and reported in
//! the health. The device readers never wait for this loop, so a slow subscriber never slows
//! the devices. (Zenoh closes a link that stays blocked longer than its `wait_before_close`, so
//! one stuck subscriber cannot hold the loop for ever.) Messages are not `express`: Zenoh's
//! automatic batching sends at once when the link is idle and packs a burst into few writes.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Write};

use model_core::PadGeometry;
use taxel_ros2::mcap_file::TopicId;
use taxel_ros2::pad_messages::{
    pad_wrench, pressure_cloud, PadTopics, DEFAULT_FRAME_PREFIX, DEFAULT_NAMESPACE,
};
use taxel_ros2::types::{
    DIAGNOSTIC_ARRAY_MESSAGE, HEADER_MESSAGE, POINT_CLOUD2_MESSAGE, WRENCH_STAMPED_MESSAGE,
};
use taxel_ros2::{DiagnosticArray, Header, McapRecorder, MessageType, RosDistro, RosMessage, Time};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

use crate::commands::{CommandSettings, DeviceCommands};
use crate::health::{device_status, DeviceHealth};
use crate::names::{attachment, gid, key_expression, GraphNode};
use crate::sequence::SequenceExtender;

/// What a message says, ready for a publisher: its content, its stamp and its arrival.
#[derive(Debug, Clone, PartialEq)]
pub enum Outgoing {
    /// One pad's sample frame.
    Sample {
        /// The device's index.
        device: usize,
        /// The frame as received.
        sample: wire::SampleFrame,
        /// Its device time on the host clock (or its arrival, see the module documentation),
        /// ns since the Unix epoch.
        stamp_ns: u64,
        /// When its sample set arrived, ns since the Unix epoch.
        arrival_ns: u64,
    },
    /// A pad came into contact or left it.
    Contact {
        /// The device's index.
        device: usize,
        /// The pad.
        pad: u8,
        /// True when the contact started, false when it ended.
        started: bool,
        /// When it happened on the host clock, ns since the Unix epoch.
        stamp_ns: u64,
        /// When it arrived, ns since the Unix epoch.
        arrival_ns: u64,
    },
}

/// How the bridge names things.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Naming {
    /// The ROS 2 distribution of the subscribers (Humble's rmw_zenoh has no type hashes in
    /// its key expressions and tokens), and the form of the MCAP file's rosbag2 metadata.
    pub ros_distro: RosDistro,
    /// `ROS_DOMAIN_ID`: the first chunk of every key expression.
    pub domain_id: u32,
    /// The namespace of the pad topics (`/taxel`).
    pub namespace: String,
    /// The start of every pad's frame id (`taxel_`).
    pub frame_prefix: String,
    /// The ROS 2 node name the publishers belong to.
    pub node_name: String,
    /// The diagnostics topic (`/diagnostics`, where ROS 2's diagnostic aggregator listens).
    pub diagnostics_topic: String,
}

impl Default for Naming {
    fn default() -> Self {
        Self {
            ros_distro: RosDistro::Jazzy,
            domain_id: 0,
            namespace: DEFAULT_NAMESPACE.to_owned(),
            frame_prefix: DEFAULT_FRAME_PREFIX.to_owned(),
            node_name: "taxel_bridge".to_owned(),
            diagnostics_topic: "/diagnostics".to_owned(),
        }
    }
}

/// The MCAP file `--mcap` writes the published messages to.
pub type Recorder = McapRecorder<BufWriter<File>>;

/// One topic's Zenoh publisher and liveliness token (and its channel in the MCAP file).
struct TopicPublisher {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    /// The last sequence number put (0 before the first).
    sequence: u64,
    recorded_as: Option<TopicId>,
}

impl TopicPublisher {
    /// Puts one message: the publication's `sequence` (the next of this topic's own when
    /// `None`), stamped `stamp_ns`, received at `log_ns` (for the MCAP file).
    fn put(
        &mut self,
        recorder: &mut Option<Recorder>,
        sequence: Option<u64>,
        stamp_ns: u64,
        log_ns: u64,
        cdr: Vec<u8>,
    ) -> anyhow::Result<()> {
        self.sequence = sequence.unwrap_or(self.sequence.saturating_add(1));
        let stamp = i64::try_from(stamp_ns).unwrap_or(i64::MAX);
        if let (Some(recorder), Some(topic)) = (recorder.as_mut(), self.recorded_as) {
            // MCAP's sequence is 32 bits: the low 32 bits of the publication's.
            let sequence = u32::try_from(self.sequence & u64::from(u32::MAX)).unwrap_or(0);
            recorder.write_cdr(topic, sequence, log_ns, stamp_ns, &cdr)?;
        }
        let sequence = i64::try_from(self.sequence).unwrap_or(i64::MAX);
        self.publisher
            .put(cdr)
            .attachment(attachment(sequence, stamp, &self.gid).to_vec())
            .wait()
            .map_err(zenoh_error)
    }
}

/// The pad topics of one pad.
struct PadPublishers {
    topics: PadTopics,
    /// The device's sequence numbers as the pressure's and wrench's (the same numbers on both).
    sequence: SequenceExtender,
    pressure: TopicPublisher,
    wrench: TopicPublisher,
    contact_started: TopicPublisher,
    contact_ended: TopicPublisher,
}

/// What the publishing loop did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PublishCounts {
    /// Sample frames published (each as a pressure cloud and a wrench).
    pub samples: u64,
    /// Contact events published.
    pub contacts: u64,
    /// Diagnostic arrays published.
    pub diagnostics: u64,
}

/// Where the publishing loop puts frames and health: the ROS 2 form ([`RosPublisher`]) or the
/// plain one ([`crate::plain::PlainPublisher`]), and the Foxglove view
/// ([`crate::foxglove::FoxglovePublisher`]); [`crate::fanout::FanOut`] gives each to several.
pub trait FramePublisher {
    /// Publishes one stamped sample frame or contact event.
    fn publish(&mut self, outgoing: &Outgoing) -> anyhow::Result<()>;
    /// Publishes every device's health, stamped `stamp_ns` (ns since the Unix epoch).
    fn publish_health(&mut self, healths: &[DeviceHealth], stamp_ns: u64) -> anyhow::Result<()>;
}

/// The session with the node's token, and the publishers declared so far.
pub struct RosPublisher {
    session: Session,
    naming: Naming,
    node: GraphNode,
    _node_token: LivelinessToken,
    next_entity_id: u32,
    pads: HashMap<(usize, u8), PadPublishers>,
    diagnostics: Option<TopicPublisher>,
    geometries: HashMap<(usize, u8), PadGeometry>,
    recorder: Option<Recorder>,
}

fn zenoh_error(error: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("zenoh: {error}")
}

impl RosPublisher {
    /// Declares the node on `session`; with a `recorder`, every published message is also
    /// written to it.
    pub fn new(
        session: Session,
        naming: Naming,
        recorder: Option<Recorder>,
    ) -> anyhow::Result<Self> {
        let node = GraphNode {
            ros_distro: naming.ros_distro,
            domain_id: naming.domain_id,
            session_id: session.zid().to_string(),
            namespace: "/".to_owned(),
            node_name: naming.node_name.clone(),
        };
        let node_token = session
            .liveliness()
            .declare_token(node.node_token())
            .wait()
            .map_err(zenoh_error)?;
        Ok(Self {
            session,
            naming,
            node,
            _node_token: node_token,
            next_entity_id: 1,
            pads: HashMap::new(),
            diagnostics: None,
            geometries: HashMap::new(),
            recorder,
        })
    }

    fn declare(
        &mut self,
        topic: &str,
        message_type: &'static MessageType,
    ) -> anyhow::Result<TopicPublisher> {
        let entity_id = self.next_entity_id;
        self.next_entity_id += 1;
        let token_key = self.node.publisher_token(entity_id, topic, message_type);
        let token = self
            .session
            .liveliness()
            .declare_token(token_key.as_str())
            .wait()
            .map_err(zenoh_error)?;
        let publisher = self
            .session
            .declare_publisher(key_expression(
                self.naming.domain_id,
                topic,
                message_type,
                self.naming.ros_distro,
            ))
            .congestion_control(CongestionControl::Block)
            .wait()
            .map_err(zenoh_error)?;
        let recorded_as = match self.recorder.as_mut() {
            Some(recorder) => Some(recorder.add_topic(topic, message_type)?),
            None => None,
        };
        Ok(TopicPublisher {
            publisher,
            _token: token,
            gid: gid(&token_key),
            sequence: 0,
            recorded_as,
        })
    }

    /// Serves the commands of devices `0..pad_counts.len()` from ROS 2 (`--allow-commands`),
    /// with a tare of each of device `d`'s `pad_counts[d]` pads: their services are entities of
    /// the bridge's node, numbered after the publishers declared so far.
    pub fn declare_commands(
        &mut self,
        pad_counts: &[u8],
        settings: CommandSettings,
    ) -> anyhow::Result<DeviceCommands> {
        DeviceCommands::declare(
            &self.session,
            &self.node,
            &mut self.next_entity_id,
            &self.naming,
            pad_counts,
            settings,
        )
    }

    fn pad(&mut self, device: usize, pad: u8) -> anyhow::Result<&mut PadPublishers> {
        if !self.pads.contains_key(&(device, pad)) {
            let topics = PadTopics::new(
                &self.naming.namespace,
                &self.naming.frame_prefix,
                device,
                pad,
            );
            let publishers = PadPublishers {
                pressure: self.declare(&topics.pressure, &POINT_CLOUD2_MESSAGE)?,
                wrench: self.declare(&topics.wrench, &WRENCH_STAMPED_MESSAGE)?,
                contact_started: self.declare(&topics.contact_started, &HEADER_MESSAGE)?,
                contact_ended: self.declare(&topics.contact_ended, &HEADER_MESSAGE)?,
                topics,
                sequence: SequenceExtender::default(),
            };
            self.pads.insert((device, pad), publishers);
        }
        self.pads
            .get_mut(&(device, pad))
            .ok_or_else(|| anyhow::anyhow!("pad publishers missing"))
    }

    /// Pad `pad` of `device` has `geometry` (its PadInfo's): its pressure clouds place the
    /// taxels there. Until this is called a pad has the built-in geometry.
    pub fn set_geometry(&mut self, device: usize, pad: u8, geometry: PadGeometry) {
        self.geometries.insert((device, pad), geometry);
    }

    /// Completes the MCAP file, if there is one, and gives back its file (flushed) for the
    /// caller to put in place.
    pub fn finish(self) -> anyhow::Result<Option<File>> {
        match self.recorder {
            Some(recorder) => {
                let file = recorder
                    .finish()?
                    .into_inner()
                    .map_err(|error| error.into_error())?;
                Ok(Some(file))
            }
            None => Ok(None),
        }
    }
}

impl FramePublisher for RosPublisher {
    fn publish(&mut self, outgoing: &Outgoing) -> anyhow::Result<()> {
        let (device, pad) = match outgoing {
            Outgoing::Sample { device, sample, .. } => (*device, sample.pad.get()),
            Outgoing::Contact { device, pad, .. } => (*device, *pad),
        };
        self.pad(device, pad)?;
        let Self {
            pads,
            recorder,
            geometries,
            ..
        } = self;
        let geometry = geometries
            .get(&(device, pad))
            .unwrap_or(&PadGeometry::ARTICLE);
        let publishers = pads
            .get_mut(&(device, pad))
            .ok_or_else(|| anyhow::anyhow!("pad publishers missing"))?;
        match outgoing {
            Outgoing::Sample {
                sample,
                stamp_ns,
                arrival_ns,
                ..
            } => {
                let header = Header {
                    stamp: Time::from_unix_ns(*stamp_ns),
                    frame_id: publishers.topics.frame_id.clone(),
                };
                let sequence = Some(publishers.sequence.next(sample.sequence));
                let cloud = pressure_cloud(sample, header.clone(), geometry).to_cdr();
                publishers
                    .pressure
                    .put(recorder, sequence, *stamp_ns, *arrival_ns, cloud)?;
                let wrench = pad_wrench(sample, header).to_cdr();
                publishers
                    .wrench
                    .put(recorder, sequence, *stamp_ns, *arrival_ns, wrench)
            }
            Outgoing::Contact {
                started,
                stamp_ns,
                arrival_ns,
                ..
            } => {
                let header = Header {
                    stamp: Time::from_unix_ns(*stamp_ns),
                    frame_id: publishers.topics.frame_id.clone(),
                };
                let publisher = if *started {
                    &mut publishers.contact_started
                } else {
                    &mut publishers.contact_ended
                };
                publisher.put(recorder, None, *stamp_ns, *arrival_ns, header.to_cdr())
            }
        }
    }

    /// Every device's health as one diagnostic array.
    fn publish_health(&mut self, healths: &[DeviceHealth], stamp_ns: u64) -> anyhow::Result<()> {
        if self.diagnostics.is_none() {
            let topic = self.naming.diagnostics_topic.clone();
            self.diagnostics = Some(self.declare(&topic, &DIAGNOSTIC_ARRAY_MESSAGE)?);
        }
        let array = DiagnosticArray {
            header: Header {
                stamp: Time::from_unix_ns(stamp_ns),
                frame_id: String::new(),
            },
            status: healths
                .iter()
                .enumerate()
                .map(|(device, health)| device_status(device, health))
                .collect(),
        };
        match self.diagnostics.as_mut() {
            Some(publisher) => {
                publisher.put(&mut self.recorder, None, stamp_ns, stamp_ns, array.to_cdr())
            }
            None => Ok(()),
        }
    }
}

/// Where `--timing-log` writes one line per published sample frame: device, pad, sequence,
/// arrival and publication (ns since the Unix epoch), for the latency table.
pub type TimingLog = Box<dyn Write + Send>;
