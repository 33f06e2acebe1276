//! MCAP files of ROS 2 messages, as `ros2 bag record -s mcap` writes them: profile `ros2`, one
//! `ros2msg` schema per message type (the definition text of [`MessageType::definition`]), one
//! channel per topic with `cdr` messages, and each message's log and publish times in ns since
//! the Unix epoch; each channel's `offered_qos_profiles` and `topic_type_hash`, and the
//! `rosbag2` metadata record, as rosbag2 writes them ([`crate::rosbag2_metadata`], Jazzy's form
//! unless [`McapRecorder::with_distro`] says Humble). Foxglove, `ros2 bag` and the Python
//! `mcap-ros2-support` reader open them.
//!
//! For `taxel record --mcap` (through [`crate::PadMessagesFile`]) and the bridge: create a [`McapRecorder`] on the output file, call
//! [`McapRecorder::add_topic`] once per topic and [`McapRecorder::write`] with the same
//! messages the bridge publishes, then [`McapRecorder::finish`].

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use crate::distro::RosDistro;
use crate::messages::RosMessage;
use crate::rosbag2_metadata::{channel_metadata, metadata_record, BagSummary, TopicSummary};
use crate::type_hash::MessageType;

/// Why an MCAP file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum McapError {
    /// The MCAP library (or the file beneath it) failed.
    #[error("writing the MCAP file: {0}")]
    Mcap(#[from] mcap::McapError),
    /// A topic was written to before [`McapRecorder::add_topic`].
    #[error("topic {0} was not added")]
    UnknownTopic(String),
}

/// A topic of an [`McapRecorder`], as [`McapRecorder::add_topic`] returns it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct TopicId(u16);

/// Writes ROS 2 messages to an MCAP file (see the module documentation).
pub struct McapRecorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    distro: RosDistro,
    schemas: BTreeMap<&'static str, u16>,
    topics: BTreeMap<String, TopicId>,
    /// Each topic's place in `summary.topics`.
    topic_indices: BTreeMap<TopicId, usize>,
    /// What the `rosbag2` record will say: every topic (in the order of their ids) and the
    /// time range.
    summary: BagSummary,
}

impl<W: Write + Seek> McapRecorder<W> {
    /// A recorder writing to `output` (chunks not compressed: no C library in the build) in
    /// Jazzy's form.
    pub fn new(output: W) -> Result<Self, McapError> {
        Self::with_distro(output, RosDistro::Jazzy)
    }

    /// A recorder writing `distro`'s form of the rosbag2 metadata (see the module
    /// documentation).
    pub fn with_distro(output: W, distro: RosDistro) -> Result<Self, McapError> {
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .compression(None)
            .create(output)?;
        Ok(Self {
            writer,
            distro,
            schemas: BTreeMap::new(),
            topics: BTreeMap::new(),
            topic_indices: BTreeMap::new(),
            summary: BagSummary::default(),
        })
    }

    /// The file's name (without directory), for the `rosbag2` record's file list; without it
    /// the list is empty (`ros2 bag info` puts the file it opened there anyway).
    pub fn set_file_name(&mut self, file_name: &str) {
        self.summary.file_name = Some(file_name.to_owned());
    }

    /// Adds a topic (a ROS 2 topic name such as `/taxel/device0/pad0/pressure`) of messages of
    /// `message_type`; adding it again returns the same id.
    pub fn add_topic(
        &mut self,
        topic: &str,
        message_type: &'static MessageType,
    ) -> Result<TopicId, McapError> {
        if let Some(id) = self.topics.get(topic) {
            return Ok(*id);
        }
        let schema_id = match self.schemas.get(message_type.name()) {
            Some(id) => *id,
            None => {
                let id = self.writer.add_schema(
                    message_type.name(),
                    "ros2msg",
                    message_type.definition.as_bytes(),
                )?;
                self.schemas.insert(message_type.name(), id);
                id
            }
        };
        let type_hash = message_type.type_hash();
        let metadata = channel_metadata(self.distro, &type_hash);
        let channel = self
            .writer
            .add_channel(schema_id, topic, "cdr", &metadata)?;
        let id = TopicId(channel);
        self.topics.insert(topic.to_owned(), id);
        self.topic_indices.insert(id, self.summary.topics.len());
        self.summary.topics.push(TopicSummary {
            name: topic.to_owned(),
            type_name: message_type.name().to_owned(),
            type_hash,
            message_count: 0,
        });
        Ok(id)
    }

    /// The id of a topic added before.
    pub fn topic(&self, topic: &str) -> Result<TopicId, McapError> {
        self.topics
            .get(topic)
            .copied()
            .ok_or_else(|| McapError::UnknownTopic(topic.to_owned()))
    }

    /// Writes one serialised message: `sequence` is the publication's sequence number (the
    /// device's, for the pad topics), `log_time_ns` when it was received, `publish_time_ns`
    /// its header stamp, both ns since the Unix epoch.
    pub fn write_cdr(
        &mut self,
        topic: TopicId,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), McapError> {
        self.writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: topic.0,
                sequence,
                log_time: log_time_ns,
                publish_time: publish_time_ns,
            },
            cdr,
        )?;
        if let Some(summary) = self
            .topic_indices
            .get(&topic)
            .and_then(|index| self.summary.topics.get_mut(*index))
        {
            summary.message_count += 1;
        }
        self.summary.time_range_ns = Some(match self.summary.time_range_ns {
            None => (log_time_ns, log_time_ns),
            Some((start, end)) => (start.min(log_time_ns), end.max(log_time_ns)),
        });
        Ok(())
    }

    /// Serialises and writes one message (see [`Self::write_cdr`]).
    pub fn write<M: RosMessage>(
        &mut self,
        topic: TopicId,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        message: &M,
    ) -> Result<(), McapError> {
        self.write_cdr(
            topic,
            sequence,
            log_time_ns,
            publish_time_ns,
            &message.to_cdr(),
        )
    }

    /// Writes the `rosbag2` metadata record, the summary and index records, and returns the
    /// output.
    pub fn finish(mut self) -> Result<W, McapError> {
        self.writer.write_metadata(&mcap::records::Metadata {
            name: "rosbag2".to_owned(),
            metadata: metadata_record(self.distro, &self.summary),
        })?;
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{Header, Time};
    use crate::types::HEADER_MESSAGE;

    #[test]
    fn a_recording_reads_back_with_its_schema_and_sequence() {
        let mut recorder = McapRecorder::new(std::io::Cursor::new(Vec::new())).unwrap();
        let topic = recorder.add_topic("/contact", &HEADER_MESSAGE).unwrap();
        assert_eq!(
            recorder.add_topic("/contact", &HEADER_MESSAGE).unwrap(),
            topic
        );
        let header = Header {
            stamp: Time::from_unix_ns(5),
            frame_id: "pad".into(),
        };
        recorder.write(topic, 7, 10, 5, &header).unwrap();
        let bytes = recorder.finish().unwrap().into_inner();
        let messages: Vec<_> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(messages.len(), 1);
        assert_eq!(messages[0].sequence, 7);
        assert_eq!(messages[0].data.as_ref(), header.to_cdr().as_slice());
        let schema = messages[0].channel.schema.as_ref().unwrap();
        assert_eq!(schema.name, "std_msgs/msg/Header");
        assert_eq!(schema.encoding, "ros2msg");
        assert!(matches!(recorder_topic_error(), McapError::UnknownTopic(_)));
    }

    #[test]
    fn channels_and_the_rosbag2_record_are_as_rosbag2_writes_them() {
        let mut recorder = McapRecorder::new(std::io::Cursor::new(Vec::new())).unwrap();
        recorder.set_file_name("rec.mcap");
        let topic = recorder.add_topic("/contact", &HEADER_MESSAGE).unwrap();
        for time_ns in [30, 10, 20] {
            recorder
                .write(topic, 1, time_ns, time_ns, &Header::default())
                .unwrap();
        }
        let bytes = recorder.finish().unwrap().into_inner();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let channel = summary.channels.values().next().unwrap();
        assert_eq!(
            channel.metadata.get("topic_type_hash"),
            Some(&HEADER_MESSAGE.type_hash())
        );
        assert!(channel.metadata["offered_qos_profiles"].starts_with("- history: keep_last\n"));
        let index = summary
            .metadata_indexes
            .iter()
            .find(|index| index.name == "rosbag2")
            .unwrap();
        let metadata = mcap::read::metadata(&bytes, index).unwrap();
        let yaml = &metadata.metadata["serialized_metadata"];
        assert!(yaml.contains("message_count: 3\n"), "{yaml}");
        assert!(yaml.contains("starting_time:\n  nanoseconds_since_epoch: 10\n"));
        assert!(yaml.contains("duration:\n  nanoseconds: 20\n"));
        assert!(yaml.contains("  - path: rec.mcap\n"));
    }

    fn recorder_topic_error() -> McapError {
        let recorder = McapRecorder::new(std::io::Cursor::new(Vec::new())).unwrap();
        recorder.topic("/none").unwrap_err()
    }
}
