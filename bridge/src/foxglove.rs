//! A live view in Foxglove (`--foxglove [ADDR]`): a Foxglove WebSocket server (the official
//! `foxglove` SDK's) serving the pads the bridge publishes, read-only. Topics, under the
//! namespace (`/taxel`):
//!
//! | topic | encoding | content |
//! |---|---|---|
//! | `<namespace>/device<d>/pad<p>/state` | JSON (schema `taxel.PadState`) | every sample frame: pressures and flags per taxel, force, centre of pressure, contact, partial, temperature, stamp |
//! | `<namespace>/scene` | protobuf `foxglove.SceneUpdate` | every pad as four cubes coloured by pressure, at most every [`SCENE_PERIOD_NS`] |
//! | `<namespace>/transforms` | protobuf `foxglove.FrameTransforms` | each pad's frame placed in the root frame `<frame prefix>pads`, side by side, with each scene |
//! | `<namespace>/health` | JSON (schema `taxel.Health`) | every device's health, once a second |
//!
//! The messages are built by [`crate::foxglove_messages`]. Logging a message never waits: the
//! SDK queues it for each client that subscribed, in a queue of [`MESSAGE_BACKLOG`] messages
//! from which a slow client loses its oldest, and sends from its own threads. So a slow or
//! stuck Foxglove client neither slows the Zenoh publishing nor the device readers; and with no
//! client subscribed, nothing is encoded.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;

use foxglove::messages::{FrameTransforms, SceneUpdate};
use foxglove::{Channel, Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use model_core::PadGeometry;
use wire::SampleFrame;

use crate::foxglove_messages::{
    health_json, health_schema, pad_entity, pad_half_extent_mm, pad_offset_mm, pad_pitch_mm,
    pad_state_json, pad_state_schema, pad_transform, HEALTH_SCHEMA_NAME, PAD_STATE_SCHEMA_NAME,
};
use crate::health::DeviceHealth;
use crate::publisher::{FramePublisher, Outgoing};

/// Where the server listens unless told otherwise: this machine only, Foxglove's usual port.
pub const DEFAULT_FOXGLOVE_ADDRESS: &str = "127.0.0.1:8765";

/// The shortest time between two scene updates, ns (20 per second: enough for the eye, and
/// the 3D panel redraws the whole scene for each).
pub const SCENE_PERIOD_NS: u64 = 50_000_000;

/// Messages queued per client before its oldest are dropped (about 2.5 s of 4 pads at
/// 100 sample sets per second).
pub const MESSAGE_BACKLOG: usize = 1024;

/// How the view names its topics and frames.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FoxgloveNaming {
    /// The topics' namespace (`/taxel`).
    pub namespace: String,
    /// The start of every pad's frame id (`taxel_`), as in the ROS 2 messages.
    pub frame_prefix: String,
}

impl FoxgloveNaming {
    fn topic(&self, name: &str) -> String {
        format!("{}/{name}", self.namespace.trim_end_matches('/'))
    }

    /// The root frame the pads are laid out in.
    pub fn root_frame(&self) -> String {
        format!("{}pads", self.frame_prefix)
    }

    fn pad_frame(&self, device: usize, pad: u8) -> String {
        format!("{}device{device}_pad{pad}", self.frame_prefix)
    }
}

/// One pad as the view follows it.
struct PadView {
    state: Arc<RawChannel>,
    geometry: PadGeometry,
    /// Its latest sample frame and that frame's stamp.
    latest: Option<(SampleFrame, u64)>,
}

/// The Foxglove WebSocket server and its channels (see the module documentation).
pub struct FoxglovePublisher {
    context: Arc<Context>,
    server: Option<foxglove::WebSocketServerHandle>,
    address: SocketAddr,
    naming: FoxgloveNaming,
    pads: BTreeMap<(usize, u8), PadView>,
    scene: Channel<SceneUpdate>,
    transforms: Channel<FrameTransforms>,
    health: Arc<RawChannel>,
    /// When the last scene went out, on the arrival clock (ns since the Unix epoch).
    last_scene_ns: Option<u64>,
}

fn foxglove_error(error: foxglove::FoxgloveError) -> anyhow::Error {
    anyhow::anyhow!("Foxglove server: {error}")
}

fn json_channel(
    context: &Arc<Context>,
    topic: &str,
    name: &str,
    schema: &serde_json::Value,
) -> anyhow::Result<Arc<RawChannel>> {
    context
        .channel_builder(topic)
        .message_encoding("json")
        .schema(Schema::new(name, "jsonschema", serde_json::to_vec(schema)?))
        .build_raw()
        .map_err(foxglove_error)
}

impl FoxglovePublisher {
    /// Starts the server on `address` (its own threads), named `taxel-bridge`.
    pub fn start(address: SocketAddr, naming: FoxgloveNaming) -> anyhow::Result<Self> {
        let context = Context::new();
        let scene = context
            .channel_builder(naming.topic("scene"))
            .build::<SceneUpdate>();
        let transforms = context
            .channel_builder(naming.topic("transforms"))
            .build::<FrameTransforms>();
        let health = json_channel(
            &context,
            &naming.topic("health"),
            HEALTH_SCHEMA_NAME,
            &health_schema(),
        )?;
        let server = WebSocketServer::new()
            .name("taxel-bridge")
            .context(&context)
            .bind(address.ip().to_string(), address.port())
            .message_backlog_size(MESSAGE_BACKLOG)
            .start_blocking()
            .map_err(|error| {
                anyhow::anyhow!("starting the Foxglove server on {address}: {error}")
            })?;
        let address = SocketAddr::new(address.ip(), server.port());
        Ok(Self {
            context,
            server: Some(server),
            address,
            naming,
            pads: BTreeMap::new(),
            scene,
            transforms,
            health,
            last_scene_ns: None,
        })
    }

    /// Where the server listens (the port chosen when asked for port 0).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    fn pad(&mut self, device: usize, pad: u8) -> anyhow::Result<&mut PadView> {
        if !self.pads.contains_key(&(device, pad)) {
            let topic = self.naming.topic(&format!("device{device}/pad{pad}/state"));
            let state = json_channel(
                &self.context,
                &topic,
                PAD_STATE_SCHEMA_NAME,
                &pad_state_schema(),
            )?;
            self.pads.insert(
                (device, pad),
                PadView {
                    state,
                    geometry: PadGeometry::ARTICLE,
                    latest: None,
                },
            );
        }
        self.pads
            .get_mut(&(device, pad))
            .ok_or_else(|| anyhow::anyhow!("pad view missing"))
    }

    /// Pad `pad` of `device` has `geometry` (its PadInfo's); its state topic is advertised from
    /// now on. Until this is called a pad has the built-in geometry.
    pub fn set_geometry(
        &mut self,
        device: usize,
        pad: u8,
        geometry: PadGeometry,
    ) -> anyhow::Result<()> {
        self.pad(device, pad)?.geometry = geometry;
        Ok(())
    }

    /// Every pad's transform and cubes, as they were last, logged at `log_ns`.
    fn publish_scene(&self, log_ns: u64) {
        let largest_half_extent_mm = self
            .pads
            .values()
            .map(|view| pad_half_extent_mm(&view.geometry))
            .fold(0.0, f64::max);
        let pitch_mm = pad_pitch_mm(largest_half_extent_mm);
        let root_frame = self.naming.root_frame();
        let mut transforms = FrameTransforms::default();
        let mut scene = SceneUpdate::default();
        for (&(device, pad), view) in &self.pads {
            let Some((sample, stamp_ns)) = &view.latest else {
                continue;
            };
            let frame_id = self.naming.pad_frame(device, pad);
            let offset_mm = pad_offset_mm(device, pad, pitch_mm);
            transforms
                .transforms
                .push(pad_transform(&root_frame, &frame_id, offset_mm, *stamp_ns));
            scene.entities.push(pad_entity(
                &format!("device{device}/pad{pad}"),
                &frame_id,
                &format!("device{device} pad{pad}"),
                &view.geometry,
                sample,
                *stamp_ns,
            ));
        }
        let metadata = PartialMetadata::with_log_time(log_ns);
        // The transforms first, so that the scene's frames are known when it comes.
        self.transforms.log_with_meta(&transforms, metadata);
        self.scene.log_with_meta(&scene, metadata);
    }
}

impl FramePublisher for FoxglovePublisher {
    fn publish(&mut self, outgoing: &Outgoing) -> anyhow::Result<()> {
        // Contact events are in every state's `contact`.
        let Outgoing::Sample {
            device,
            sample,
            stamp_ns,
            arrival_ns,
        } = outgoing
        else {
            return Ok(());
        };
        let view = self.pad(*device, sample.pad.get())?;
        if view.state.has_sinks() {
            let state = serde_json::to_vec(&pad_state_json(*device, sample, *stamp_ns))?;
            view.state
                .log_with_meta(&state, PartialMetadata::with_log_time(*arrival_ns));
        }
        view.latest = Some((*sample, *stamp_ns));
        let due = self
            .last_scene_ns
            .is_none_or(|last_ns| arrival_ns.saturating_sub(last_ns) >= SCENE_PERIOD_NS);
        if due && (self.scene.has_sinks() || self.transforms.has_sinks()) {
            self.publish_scene(*arrival_ns);
            self.last_scene_ns = Some(*arrival_ns);
        }
        Ok(())
    }

    fn publish_health(&mut self, healths: &[DeviceHealth], stamp_ns: u64) -> anyhow::Result<()> {
        if self.health.has_sinks() {
            let health = serde_json::to_vec(&health_json(healths, stamp_ns))?;
            self.health
                .log_with_meta(&health, PartialMetadata::with_log_time(stamp_ns));
        }
        Ok(())
    }
}

/// Dropping the publisher stops the server: its clients are disconnected.
impl Drop for FoxglovePublisher {
    fn drop(&mut self) {
        if let Some(server) = self.server.take() {
            // Not waited for: a stuck client must not hold the bridge's end.
            server.stop().detach_all();
        }
    }
}
