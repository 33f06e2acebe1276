//! MCAP files of ROS 2 messages, as `ros2 bag record -s mcap` writes them: profile `ros2`, one
//! `ros2msg` schema per message type (the definition text of [`MessageType::definition`]), one
//! channel per topic with `cdr` messages, and each message's log and publish times in ns since
//! the Unix epoch. Foxglove, `ros2 bag` and the Python `mcap-ros2-support` reader open them.
//!
//! For `taxel record --mcap` (through [`crate::PadMessagesFile`]) and the bridge: create a [`McapRecorder`] on the output file, call
//! [`McapRecorder::add_topic`] once per topic and [`McapRecorder::write`] with the same
//! messages the bridge publishes, then [`McapRecorder::finish`].

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use crate::messages::RosMessage;
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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicId(u16);

/// Writes ROS 2 messages to an MCAP file (see the module documentation).
pub struct McapRecorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    schemas: BTreeMap<&'static str, u16>,
    topics: BTreeMap<String, TopicId>,
}

impl<W: Write + Seek> McapRecorder<W> {
    /// A recorder writing to `output` (chunks not compressed: no C library in the build).
    pub fn new(output: W) -> Result<Self, McapError> {
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .compression(None)
            .create(output)?;
        Ok(Self {
            writer,
            schemas: BTreeMap::new(),
            topics: BTreeMap::new(),
        })
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
        let metadata = BTreeMap::from([("type_hash".to_owned(), message_type.type_hash())]);
        let channel = self
            .writer
            .add_channel(schema_id, topic, "cdr", &metadata)?;
        let id = TopicId(channel);
        self.topics.insert(topic.to_owned(), id);
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

    /// Writes the summary and index records and returns the output.
    pub fn finish(mut self) -> Result<W, McapError> {
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

    fn recorder_topic_error() -> McapError {
        let recorder = McapRecorder::new(std::io::Cursor::new(Vec::new())).unwrap();
        recorder.topic("/none").unwrap_err()
    }
}
