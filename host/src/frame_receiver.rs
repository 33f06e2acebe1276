//! The decoding half of the link to a taxel pad: bytes in, device frames out, resynchronising
//! at every 0x00, with counters of what was seen. Sample frames of every pad the device reads
//! are delivered; a frame of a pad it does not have is a protocol violation, counted and set
//! aside. Re-exported by [`crate::device_link`].

use wire::{DecodeError, DeviceFrame, DeviceFrameDecoder, ReplyFrame, ReplyPayload};

/// Counters of what a [`FrameReceiver`] saw.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkStatistics {
    /// Bytes received.
    pub bytes_received: u64,
    /// Frames decoded.
    pub frames_decoded: u64,
    /// Frames rejected (garbage, corruption, unknown kind or version).
    pub frames_rejected: u64,
    /// Bytes that belonged to no decoded frame (rejected frames and their delimiters).
    pub bytes_rejected: u64,
    /// The last decoding error.
    pub last_error: Option<DecodeError>,
    /// Sample frames of a pad the device does not have (pad index at or above the pad count of
    /// its last Info): a protocol violation. They are counted here and set aside, never
    /// delivered.
    pub samples_beyond_pad_count: u64,
    /// The last frame counted in `samples_beyond_pad_count`: its pad index and the device's pad
    /// count then.
    pub last_pad_beyond_pad_count: Option<(u8, u8)>,
    /// The protocol version of the last intact frame of a version this host does not speak,
    /// unless a frame of its own version has been decoded since.
    pub other_protocol_version: Option<u8>,
}

/// The decoding half of the link: bytes in, device frames out, resynchronising at every 0x00.
///
/// Sample frames of every pad the device reads are delivered. The pad count comes from the
/// device's Info (an Info frame or the reply to an Info request, as they pass) or from
/// [`FrameReceiver::set_pad_count`]; until it is known, every pad index the protocol allows
/// (0 to 7) is delivered.
#[derive(Debug, Clone, Default)]
pub struct FrameReceiver {
    decoder: DeviceFrameDecoder,
    bytes_in_chunk: u64,
    statistics: LinkStatistics,
    pad_count: Option<u8>,
}

impl FrameReceiver {
    /// A receiver with nothing pending.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets how many pads the device reads (as its Info says); sample frames of pad indices at
    /// or above it are then set aside and counted. A later Info replaces it.
    pub fn set_pad_count(&mut self, pad_count: u8) {
        self.pad_count = Some(pad_count);
    }

    /// How many pads the device reads, when known.
    pub fn pad_count(&self) -> Option<u8> {
        self.pad_count
    }

    fn learn_pad_count(&mut self, frame: &DeviceFrame) {
        let info = match frame {
            DeviceFrame::Info(info) => info,
            DeviceFrame::Reply(ReplyFrame {
                result: Ok(ReplyPayload::Info(info)),
                ..
            }) => info,
            _ => return,
        };
        self.pad_count = Some(info.pad_count);
    }

    fn is_beyond_pad_count(&self, frame: &DeviceFrame) -> bool {
        match (frame, self.pad_count) {
            (DeviceFrame::Sample(sample), Some(pad_count)) => sample.pad.get() >= pad_count,
            _ => false,
        }
    }

    /// Decodes bytes and appends every frame they complete to `frames`.
    pub fn push_bytes(&mut self, bytes: &[u8], frames: &mut impl Extend<DeviceFrame>) {
        self.statistics.bytes_received += bytes.len() as u64;
        for &byte in bytes {
            self.bytes_in_chunk += 1;
            match self.decoder.push(byte) {
                Some(Ok(frame)) => {
                    self.statistics.frames_decoded += 1;
                    // A frame of our version since: the device speaks it (a stale frame of
                    // another version from before a firmware update is history).
                    self.statistics.other_protocol_version = None;
                    self.bytes_in_chunk = 0;
                    self.learn_pad_count(&frame);
                    if self.is_beyond_pad_count(&frame) {
                        if let DeviceFrame::Sample(sample) = &frame {
                            self.statistics.samples_beyond_pad_count += 1;
                            self.statistics.last_pad_beyond_pad_count =
                                Some((sample.pad.get(), self.pad_count.unwrap_or_default()));
                        }
                    } else {
                        frames.extend([frame]);
                    }
                }
                Some(Err(error)) => {
                    if let DecodeError::UnsupportedVersion { found, .. } = error {
                        self.statistics.other_protocol_version = Some(found);
                    }
                    self.statistics.frames_rejected += 1;
                    self.statistics.bytes_rejected += self.bytes_in_chunk;
                    self.statistics.last_error = Some(error);
                    self.bytes_in_chunk = 0;
                }
                None if byte == 0 => {
                    // A lone delimiter (the host-side leading 00, or two in a row) is framing.
                    self.bytes_in_chunk = 0;
                }
                None => {}
            }
        }
    }

    /// Call at the end of a finite stream: a partial frame left over is counted as rejected.
    pub fn finish(&mut self) {
        if self.bytes_in_chunk > 0 {
            self.statistics.frames_rejected += 1;
            self.statistics.bytes_rejected += self.bytes_in_chunk;
            self.bytes_in_chunk = 0;
            self.decoder.reset();
        }
    }

    /// What was seen so far.
    pub fn statistics(&self) -> &LinkStatistics {
        &self.statistics
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wire::encode_frame_to_vec;

    fn sample_of_pad(pad: u8) -> DeviceFrame {
        DeviceFrame::Sample(wire::SampleFrame {
            pad: wire::PadIndex::new(pad).unwrap(),
            sequence: 7,
            timestamp_us: 1_000 + u64::from(pad),
            temperature_c: None,
            temperature_source: wire::TemperatureSource::None,
            taxels: [wire::TaxelSample {
                pressure_kpa: None,
                capacitance_pf: 4.5 + f32::from(pad),
                flags: 0,
            }; 4],
            summary: wire::PadSummary::default(),
        })
    }

    fn info_with_pads(pad_count: u8) -> wire::InfoFrame {
        wire::InfoFrame {
            protocol_version: wire::PROTOCOL_VERSION,
            firmware_version: wire::FirmwareVersion {
                major: 1,
                minor: 0,
                patch: 0,
            },
            board_serial: [0; 12],
            calibration_id: 0,
            calibration_source: wire::CalibrationSource::Defaults,
            rate: wire::SampleRate::Sps400,
            model_tier: wire::Tier::MonotoneCubic,
            streaming: true,
            text_mode: false,
            pad_count,
            clock_us_per_s: 1_000_000,
        }
    }

    #[test]
    fn samples_of_every_pad_of_the_device_are_delivered_and_others_set_aside() {
        let mut bytes = Vec::new();
        bytes.extend(encode_frame_to_vec(&sample_of_pad(5)).unwrap());
        bytes.extend(encode_frame_to_vec(&DeviceFrame::Info(info_with_pads(2))).unwrap());
        for pad in [0, 1, 0, 7, 2, 1] {
            bytes.extend(encode_frame_to_vec(&sample_of_pad(pad)).unwrap());
        }
        let mut receiver = FrameReceiver::new();
        let mut frames = Vec::new();
        receiver.push_bytes(&bytes, &mut frames);
        assert_eq!(receiver.pad_count(), Some(2));
        assert_eq!(
            frames,
            [
                sample_of_pad(5),
                DeviceFrame::Info(info_with_pads(2)),
                sample_of_pad(0),
                sample_of_pad(1),
                sample_of_pad(0),
                sample_of_pad(1),
            ],
            "before the Info every pad index passes; after it, those below its pad count"
        );
        assert_eq!(receiver.statistics().samples_beyond_pad_count, 2);
        assert_eq!(
            receiver.statistics().last_pad_beyond_pad_count,
            Some((2, 2))
        );
        assert_eq!(receiver.statistics().frames_rejected, 0);
        assert_eq!(receiver.statistics().frames_decoded, 8);
    }

    #[test]
    fn the_pad_count_is_learnt_from_the_reply_to_an_info_request() {
        let reply = DeviceFrame::Reply(ReplyFrame {
            request_id: 1,
            result: Ok(ReplyPayload::Info(info_with_pads(1))),
        });
        let mut bytes = encode_frame_to_vec(&reply).unwrap();
        bytes.extend(encode_frame_to_vec(&sample_of_pad(1)).unwrap());
        bytes.extend(encode_frame_to_vec(&sample_of_pad(0)).unwrap());
        let mut receiver = FrameReceiver::new();
        let mut frames = Vec::new();
        receiver.push_bytes(&bytes, &mut frames);
        assert_eq!(frames, [reply, sample_of_pad(0)]);
        assert_eq!(receiver.statistics().samples_beyond_pad_count, 1);
        let mut receiver = FrameReceiver::new();
        receiver.set_pad_count(8);
        frames.clear();
        receiver.push_bytes(
            &encode_frame_to_vec(&sample_of_pad(7)).unwrap(),
            &mut frames,
        );
        assert_eq!(frames, [sample_of_pad(7)]);
    }
}
