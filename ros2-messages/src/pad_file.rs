//! The pads' messages in an MCAP file: each pad of each device gets its topics on first use
//! (pressure cloud, wrench, contact started and ended, see [`crate::pad_messages`]), and every
//! sample frame and contact event is written with its stamp and arrival. The recorder of
//! `taxel record` (and the live view) writes through it; the bridge's `--mcap` writes the
//! messages it publishes, diagnostics included, through [`crate::McapRecorder`] itself.

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use model_core::PadGeometry;
use wire::SampleFrame;

use crate::mcap_file::{McapError, McapRecorder, TopicId};
use crate::messages::{Header, RosMessage, Time};
use crate::pad_messages::{pad_wrench, pressure_cloud, PadTopics};
use crate::types::{HEADER_MESSAGE, POINT_CLOUD2_MESSAGE, WRENCH_STAMPED_MESSAGE};

/// One pad's topics in the file.
#[derive(Debug, Clone)]
struct PadChannels {
    frame_id: String,
    pressure: TopicId,
    wrench: TopicId,
    contact_started: TopicId,
    contact_ended: TopicId,
}

/// An MCAP file of the pads' messages (see the module documentation).
pub struct PadMessagesFile<W: Write + Seek> {
    recorder: McapRecorder<W>,
    namespace: String,
    frame_prefix: String,
    geometries: BTreeMap<(usize, u8), PadGeometry>,
    pads: BTreeMap<(usize, u8), PadChannels>,
    messages: u64,
}

impl<W: Write + Seek> PadMessagesFile<W> {
    /// A file whose topics live under `namespace`, frames named `<frame_prefix>device<d>_pad<p>`.
    pub fn new(output: W, namespace: &str, frame_prefix: &str) -> Result<Self, McapError> {
        Ok(Self {
            recorder: McapRecorder::new(output)?,
            namespace: namespace.to_owned(),
            frame_prefix: frame_prefix.to_owned(),
            geometries: BTreeMap::new(),
            pads: BTreeMap::new(),
            messages: 0,
        })
    }

    /// The file's name (without directory), for the rosbag2 metadata record (see
    /// [`McapRecorder::set_file_name`]).
    pub fn set_file_name(&mut self, file_name: &str) {
        self.recorder.set_file_name(file_name);
    }

    /// Pad `pad` of `device` has `geometry` (the one its PadInfo reports): its pressure clouds
    /// place the taxels there. Until this is called a pad has the built-in geometry.
    pub fn set_geometry(&mut self, device: usize, pad: u8, geometry: PadGeometry) {
        self.geometries.insert((device, pad), geometry);
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Writes a pad's sample frame of `device`: its pressure cloud and its wrench, stamped
    /// `stamp_ns`, received at `arrival_ns` (ns since the Unix epoch).
    pub fn write_sample(
        &mut self,
        device: usize,
        sample: &SampleFrame,
        stamp_ns: u64,
        arrival_ns: u64,
    ) -> Result<(), McapError> {
        let channels = self.channels(device, sample.pad.get())?;
        let header = Header {
            stamp: Time::from_unix_ns(stamp_ns),
            frame_id: channels.frame_id.clone(),
        };
        let geometry = self
            .geometries
            .get(&(device, sample.pad.get()))
            .unwrap_or(&PadGeometry::ARTICLE);
        let cloud = pressure_cloud(sample, header.clone(), geometry);
        self.recorder.write_cdr(
            channels.pressure,
            sample.sequence,
            arrival_ns,
            stamp_ns,
            &cloud.to_cdr(),
        )?;
        self.recorder.write_cdr(
            channels.wrench,
            sample.sequence,
            arrival_ns,
            stamp_ns,
            &pad_wrench(sample, header).to_cdr(),
        )?;
        self.messages += 2;
        Ok(())
    }

    /// Writes a contact event of `pad` of `device` (started or ended).
    pub fn write_contact(
        &mut self,
        device: usize,
        pad: u8,
        started: bool,
        stamp_ns: u64,
        arrival_ns: u64,
    ) -> Result<(), McapError> {
        let channels = self.channels(device, pad)?;
        let header = Header {
            stamp: Time::from_unix_ns(stamp_ns),
            frame_id: channels.frame_id.clone(),
        };
        let topic = if started {
            channels.contact_started
        } else {
            channels.contact_ended
        };
        self.recorder
            .write_cdr(topic, 0, arrival_ns, stamp_ns, &header.to_cdr())?;
        self.messages += 1;
        Ok(())
    }

    /// Closes the file; returns its writer.
    pub fn finish(self) -> Result<W, McapError> {
        self.recorder.finish()
    }

    fn channels(&mut self, device: usize, pad: u8) -> Result<PadChannels, McapError> {
        if let Some(channels) = self.pads.get(&(device, pad)) {
            return Ok(channels.clone());
        }
        let topics = PadTopics::new(&self.namespace, &self.frame_prefix, device, pad);
        let channels = PadChannels {
            pressure: self
                .recorder
                .add_topic(&topics.pressure, &POINT_CLOUD2_MESSAGE)?,
            wrench: self
                .recorder
                .add_topic(&topics.wrench, &WRENCH_STAMPED_MESSAGE)?,
            contact_started: self
                .recorder
                .add_topic(&topics.contact_started, &HEADER_MESSAGE)?,
            contact_ended: self
                .recorder
                .add_topic(&topics.contact_ended, &HEADER_MESSAGE)?,
            frame_id: topics.frame_id,
        };
        self.pads.insert((device, pad), channels.clone());
        Ok(channels)
    }
}
