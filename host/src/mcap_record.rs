//! `taxel record --format mcap`: one device's stream as the ROS 2 messages `taxel bridge`
//! publishes, in an MCAP file that Foxglove and the ROS 2 bag tools open (docs/BRIDGE.md gives
//! the types, topics and frames): per pad a `sensor_msgs/msg/PointCloud2` of the pressures and
//! flags and a `geometry_msgs/msg/WrenchStamped` on `/taxel/device0/pad<p>/...`, with the
//! sample set's sequence number as the MCAP sequence, and the contact events as
//! `std_msgs/msg/Header` on `contact_started` / `contact_ended`.
//!
//! Stamps are the device time mapped to the host clock ([`ClockMapper`]) and never later than
//! the frame's arrival (the MCAP log time): nothing looks fresher than it is. The mapping needs
//! about 1.5 s of frames, so the first frames wait for it; frames still waiting at the end take
//! the last estimate, or, when there never was one, their arrival time. The file is written
//! under a temporary name and renamed when the recording ends cleanly.

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use anyhow::Context;
use model_core::PadGeometry;
use taxel_ros2::mcap_file::TopicId;
use taxel_ros2::pad_messages::{pad_wrench, pressure_cloud, PadTopics};
use taxel_ros2::types::{HEADER_MESSAGE, POINT_CLOUD2_MESSAGE, WRENCH_STAMPED_MESSAGE};
use taxel_ros2::{Header, McapRecorder, RosMessage, Time};
use wire::{DeviceEvent, EventFrame, SampleFrame};

use crate::clock_sync::ClockMapper;
use crate::multi_record::{HostClock, MonotonicClock};
use crate::output_file::PendingRename;
use crate::recording::{SampleSink, SetCounter};

/// The namespace and frame prefix of the topics, as `taxel bridge` has them by default.
const NAMESPACE: &str = "/taxel";
const FRAME_PREFIX: &str = "taxel_";
/// The device's index in the topic names (a recording holds one device).
const DEVICE: usize = 0;
/// Frames held while the clock mapping has no estimate yet (80 s of one pad at 100 sets/s):
/// beyond that the oldest are written stamped with their arrival.
const MAX_WAITING: usize = 8_000;

/// A frame waiting for the clock mapping.
enum Waiting {
    Sample {
        sample: SampleFrame,
        arrival_us: u64,
    },
    Contact {
        pad: u8,
        started: bool,
        device_us: u64,
        arrival_us: u64,
    },
}

/// One pad's topics in the file.
struct PadChannels {
    frame_id: String,
    pressure: TopicId,
    wrench: TopicId,
    contact_started: TopicId,
    contact_ended: TopicId,
}

/// Writes the frames of a recording to an MCAP file (see the module documentation).
pub struct McapSink {
    recorder: McapRecorder<BufWriter<File>>,
    pending: PendingRename,
    mapper: ClockMapper,
    clock: MonotonicClock,
    start_unix_ns: u64,
    waiting: VecDeque<Waiting>,
    pads: BTreeMap<u8, PadChannels>,
    geometry: PadGeometry,
    /// The sample sets seen (`--samples` counts sets).
    sets: SetCounter,
    messages: u64,
}

impl McapSink {
    /// A recording into `path` (written as a temporary file beside it until [`Self::finish`]).
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let pending = PendingRename::beside(path)?;
        let file = File::create(pending.path())
            .with_context(|| format!("creating {}", pending.path().display()))?;
        let recorder = McapRecorder::new(BufWriter::new(file))
            .with_context(|| format!("starting {}", path.display()))?;
        let start_unix_ns = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |since| {
                u64::try_from(since.as_nanos()).unwrap_or(u64::MAX)
            });
        Ok(Self {
            recorder,
            pending,
            mapper: ClockMapper::new(),
            clock: MonotonicClock::new(),
            start_unix_ns,
            waiting: VecDeque::new(),
            pads: BTreeMap::new(),
            geometry: PadGeometry::ARTICLE,
            sets: SetCounter::default(),
            messages: 0,
        })
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Writes what still waits, closes the file and renames it into place; returns its path
    /// and the messages in it.
    pub fn finish(mut self) -> anyhow::Result<(PathBuf, u64)> {
        while let Some(waiting) = self.waiting.pop_front() {
            self.write(waiting)?;
        }
        let target = self.pending.target().to_path_buf();
        let writer = self
            .recorder
            .finish()
            .with_context(|| format!("finishing {}", target.display()))?;
        let file = writer
            .into_inner()
            .map_err(|error| error.into_error())
            .with_context(|| format!("writing {}", target.display()))?;
        self.pending.commit_file(file)?;
        Ok((target, self.messages))
    }

    /// Keeps the unfinished file under its temporary name (a recording that failed) and
    /// returns that name.
    pub fn abandon(self) -> Option<PathBuf> {
        drop(self.recorder);
        self.pending.keep().ok()
    }

    fn unix_ns(&self, host_us: u64) -> u64 {
        self.start_unix_ns
            .saturating_add(host_us.saturating_mul(1_000))
    }

    /// Writes the frames whose stamps the mapping can give now (all of them once it has an
    /// estimate; the oldest when too many wait).
    fn release(&mut self) -> anyhow::Result<()> {
        while self.mapper.estimate().is_some() || self.waiting.len() > MAX_WAITING {
            let Some(waiting) = self.waiting.pop_front() else {
                break;
            };
            self.write(waiting)?;
        }
        Ok(())
    }

    fn write(&mut self, waiting: Waiting) -> anyhow::Result<()> {
        let (pad, device_us, arrival_us) = match &waiting {
            Waiting::Sample { sample, arrival_us } => {
                (sample.pad.get(), sample.timestamp_us, *arrival_us)
            }
            Waiting::Contact {
                pad,
                device_us,
                arrival_us,
                ..
            } => (*pad, *device_us, *arrival_us),
        };
        let stamp_us = self
            .mapper
            .to_host_us(device_us)
            .map_or(arrival_us, |mapped| mapped.min(arrival_us));
        let (stamp_ns, arrival_ns) = (self.unix_ns(stamp_us), self.unix_ns(arrival_us));
        let channels = self.channels(pad)?;
        let header = Header {
            stamp: Time::from_unix_ns(stamp_ns),
            frame_id: channels.frame_id.clone(),
        };
        let (pressure, wrench, started, ended) = (
            channels.pressure,
            channels.wrench,
            channels.contact_started,
            channels.contact_ended,
        );
        match waiting {
            Waiting::Sample { sample, .. } => {
                let cloud = pressure_cloud(&sample, header.clone(), &self.geometry);
                self.recorder.write_cdr(
                    pressure,
                    sample.sequence,
                    arrival_ns,
                    stamp_ns,
                    &cloud.to_cdr(),
                )?;
                self.recorder.write_cdr(
                    wrench,
                    sample.sequence,
                    arrival_ns,
                    stamp_ns,
                    &pad_wrench(&sample, header).to_cdr(),
                )?;
                self.messages += 2;
            }
            Waiting::Contact { started: true, .. } => {
                self.recorder
                    .write_cdr(started, 0, arrival_ns, stamp_ns, &header.to_cdr())?;
                self.messages += 1;
            }
            Waiting::Contact { started: false, .. } => {
                self.recorder
                    .write_cdr(ended, 0, arrival_ns, stamp_ns, &header.to_cdr())?;
                self.messages += 1;
            }
        }
        Ok(())
    }

    /// The pad's topics, added to the file on first use.
    fn channels(&mut self, pad: u8) -> anyhow::Result<&PadChannels> {
        if !self.pads.contains_key(&pad) {
            let topics = PadTopics::new(NAMESPACE, FRAME_PREFIX, DEVICE, pad);
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
            self.pads.insert(pad, channels);
        }
        self.pads
            .get(&pad)
            .ok_or_else(|| anyhow::anyhow!("pad {pad}'s topics are missing"))
    }
}

impl SampleSink for McapSink {
    fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        let arrival_us = self.clock.now_us();
        self.sets.observe(sample);
        self.mapper.observe(sample.timestamp_us, arrival_us);
        self.waiting.push_back(Waiting::Sample {
            sample: *sample,
            arrival_us,
        });
        self.release()
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        Ok(())
    }

    /// Sample sets closed: every set started but the one in progress.
    fn rows(&self) -> Option<u64> {
        Some(self.sets.closed())
    }

    fn would_close_set(&self, sample: &SampleFrame) -> bool {
        self.sets.would_close(sample)
    }

    fn device_event(&mut self, event: &EventFrame) -> anyhow::Result<()> {
        let (pad, started) = match event.event {
            DeviceEvent::ContactStarted { pad } => (pad.get(), true),
            DeviceEvent::ContactEnded { pad } => (pad.get(), false),
            _ => return Ok(()),
        };
        self.waiting.push_back(Waiting::Contact {
            pad,
            started,
            device_us: event.timestamp_us,
            arrival_us: self.clock.now_us(),
        });
        self.release()
    }
}
