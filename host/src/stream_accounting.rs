//! Where sample frames went, told apart honestly for one connection:
//!
//! - **received**: sample frames decoded;
//! - **dropped by the device**: the growth of the device's `dropped_sample_frames` counter since
//!   this connection's first counters (sample frames it produced while streaming and could not
//!   send, one per pad per sample set; a dropped event or counters frame is not a lost sample);
//! - **lost on the link**: sequence gaps between consecutive received samples of one pad's
//!   stream that the device's drops do not explain;
//! - **stale**: frames that were waiting in the port's buffer from before this connection and
//!   were discarded.
//!
//! Every pad is a stream of its own: each of its frames is compared with that pad's previous
//! one, so a frame of one pad missing from a sample set is a gap of that pad (seen when the pad's
//! next frame arrives), whatever the other pads did. With one pad, frames and sample sets are
//! the same thing.
//!
//! A sequence gap across anything that stops the stream (a stop and start, a text-mode switch,
//! a reconnection, a device restart) is not loss: the device numbers every sample set it
//! acquires whether or not anybody is listening.

use wire::{CountersFrame, PadIndex, SampleFrame};

/// How many pads a device can have (pad indices 0 to [`PadIndex::MAX`]).
pub const MAX_PADS: usize = PadIndex::MAX as usize + 1;

/// Accounting of one connection's samples.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StreamAccounting {
    received: u64,
    sequence_gap_sets: u64,
    stale_frames: u64,
    previous_sequence: [Option<u32>; MAX_PADS],
    received_of_pad: [u64; MAX_PADS],
    sequence_gap_of_pad: [u64; MAX_PADS],
    device_dropped_origin: Option<u32>,
    device_dropped_since_origin: u64,
    device_dropped_last: u32,
}

impl StreamAccounting {
    /// Nothing counted yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one sample frame; returns the frames of its pad missing just before it (0 when
    /// consecutive or after an interruption).
    pub fn sample(&mut self, sample: &SampleFrame) -> u64 {
        let pad = usize::from(sample.pad.get()).min(MAX_PADS - 1);
        self.received += 1;
        self.received_of_pad[pad] += 1;
        let gap = self.previous_sequence[pad]
            .map_or(0, |previous| sequence_gap(previous, sample.sequence));
        self.sequence_gap_sets += gap;
        self.sequence_gap_of_pad[pad] += gap;
        self.previous_sequence[pad] = Some(sample.sequence);
        gap
    }

    /// Takes the device's counters (a Counters reply or frame). The first one is the origin;
    /// a counter that went down means the device restarted, and its new value counts from 0.
    /// The device's drops are its `dropped_sample_frames`: sample frames (one per pad per set) it
    /// produced while streaming and could not send (other frames it could not send are not
    /// samples).
    pub fn counters(&mut self, counters: &CountersFrame) {
        let now = counters.dropped_sample_frames;
        match self.device_dropped_origin {
            None => {
                self.device_dropped_origin = Some(now);
            }
            Some(_) if now < self.device_dropped_last => {
                self.device_dropped_since_origin += u64::from(now);
                self.previous_sequence = [None; MAX_PADS];
            }
            Some(_) => {
                self.device_dropped_since_origin += u64::from(now - self.device_dropped_last);
            }
        }
        self.device_dropped_last = now;
    }

    /// The stream was interrupted on purpose (stopped, switched to text, reconnected): the next
    /// sample's sequence is not compared with the last one.
    pub fn interrupted(&mut self) {
        self.previous_sequence = [None; MAX_PADS];
    }

    /// Frames found waiting from before the connection and discarded.
    pub fn stale_discarded(&mut self, frames: u64) {
        self.stale_frames += frames;
    }

    /// Sample frames received (of every pad).
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Sample frames received of one pad (0 for an index beyond the protocol's pads).
    pub fn received_of_pad(&self, pad: usize) -> u64 {
        self.received_of_pad.get(pad).copied().unwrap_or(0)
    }

    /// Frames missing from the sequence numbers within uninterrupted streams, summed over the
    /// pads (with one pad: sample sets).
    pub fn sequence_gap_sets(&self) -> u64 {
        self.sequence_gap_sets
    }

    /// Frames of one pad missing from its sequence numbers within uninterrupted streams.
    pub fn sequence_gap_of_pad(&self, pad: usize) -> u64 {
        self.sequence_gap_of_pad.get(pad).copied().unwrap_or(0)
    }

    /// Sample frames the device says it dropped since this connection's first counters.
    pub fn device_dropped(&self) -> u64 {
        self.device_dropped_since_origin
    }

    /// Sample frames lost between the device and this program: gaps the device's drops do not
    /// explain. The device counts its drops over every pad together, so this is a total.
    pub fn lost_on_link(&self) -> u64 {
        self.sequence_gap_sets
            .saturating_sub(self.device_dropped_since_origin)
    }

    /// Frames discarded as stale at connection.
    pub fn stale_frames(&self) -> u64 {
        self.stale_frames
    }

    /// Pads a frame was received of: one more than the highest pad index seen (0 before any).
    pub fn pads_seen(&self) -> usize {
        self.received_of_pad
            .iter()
            .rposition(|&count| count > 0)
            .map_or(0, |pad| pad + 1)
    }

    /// One line for people: "1988 sample sets received, 0 lost on the link, 0 dropped by the
    /// device"; with several pads, in frames, followed by each pad's frames and gaps.
    pub fn summary(&self) -> String {
        let pads = self.pads_seen();
        let unit = if pads > 1 {
            "sample frames"
        } else {
            "sample sets"
        };
        let mut text = format!(
            "{} {unit} received, {} lost on the link, {} dropped by the device",
            self.received,
            self.lost_on_link(),
            self.device_dropped()
        );
        if pads > 1 {
            let per_pad: Vec<String> = (0..pads)
                .map(|pad| {
                    format!(
                        "pad {pad} {} received, {} missing",
                        self.received_of_pad(pad),
                        self.sequence_gap_of_pad(pad)
                    )
                })
                .collect();
            text.push_str(&format!(" ({})", per_pad.join("; ")));
        }
        if self.stale_frames > 0 {
            text.push_str(&format!(
                ", {} stale frames from before the connection discarded",
                self.stale_frames
            ));
        }
        text
    }
}

/// Sets missing between two sequence numbers (wrapping), 0 for consecutive ones. A repeated or
/// backward number (the device restarted) counts as no loss.
pub fn sequence_gap(previous: u32, current: u32) -> u64 {
    let step = current.wrapping_sub(previous);
    if step == 0 || step > u32::MAX / 2 {
        0
    } else {
        u64::from(step - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(sequence: u32) -> SampleFrame {
        SampleFrame {
            sequence,
            ..wire::testing::sample_frame(0)
        }
    }

    fn counters(dropped: u32) -> CountersFrame {
        CountersFrame {
            dropped_sample_frames: dropped,
            ..CountersFrame::default()
        }
    }

    #[test]
    fn sequence_gaps_wrap() {
        assert_eq!(sequence_gap(1, 2), 0);
        assert_eq!(sequence_gap(1, 5), 3);
        assert_eq!(sequence_gap(u32::MAX, 0), 0);
        assert_eq!(sequence_gap(u32::MAX - 1, 1), 2);
        assert_eq!(sequence_gap(7, 7), 0);
        assert_eq!(sequence_gap(1000, 3), 0);
    }

    #[test]
    fn device_drops_are_deltas_since_connection_and_explain_gaps() {
        let mut accounting = StreamAccounting::new();
        accounting.counters(&counters(91_843));
        accounting.sample(&sample(10));
        accounting.sample(&sample(15));
        assert_eq!(accounting.sequence_gap_sets(), 4);
        assert_eq!(accounting.device_dropped(), 0);
        assert_eq!(accounting.lost_on_link(), 4);
        accounting.counters(&counters(91_846));
        assert_eq!(accounting.device_dropped(), 3);
        assert_eq!(accounting.lost_on_link(), 1);
    }

    fn sample_of_pad(pad: u8, sequence: u32) -> SampleFrame {
        SampleFrame {
            sequence,
            ..wire::testing::sample_frame(pad)
        }
    }

    #[test]
    fn every_pad_is_its_own_stream_and_a_missing_frame_counts_for_its_pad() {
        let mut accounting = StreamAccounting::new();
        accounting.counters(&counters(0));
        // Sets 1 to 4 of two pads; pad 1's frame of set 2 and pad 0's of set 3 are missing.
        for (pad, sequence) in [(0, 1), (1, 1), (0, 2), (1, 3), (0, 4), (1, 4)] {
            accounting.sample(&sample_of_pad(pad, sequence));
        }
        assert_eq!(accounting.received(), 6);
        assert_eq!(accounting.received_of_pad(0), 3);
        assert_eq!(accounting.received_of_pad(1), 3);
        assert_eq!(accounting.sequence_gap_of_pad(0), 1);
        assert_eq!(accounting.sequence_gap_of_pad(1), 1);
        assert_eq!(accounting.sequence_gap_sets(), 2);
        assert_eq!(accounting.lost_on_link(), 2);
        accounting.counters(&counters(1));
        assert_eq!(accounting.lost_on_link(), 1, "the device dropped one frame");
        assert_eq!(accounting.pads_seen(), 2);
        assert_eq!(
            accounting.summary(),
            "6 sample frames received, 1 lost on the link, 1 dropped by the device \
             (pad 0 3 received, 1 missing; pad 1 3 received, 1 missing)"
        );
    }

    #[test]
    fn one_pad_is_summarised_in_sample_sets_as_before() {
        let mut accounting = StreamAccounting::new();
        accounting.sample(&sample(1));
        accounting.sample(&sample(3));
        assert_eq!(
            accounting.summary(),
            "2 sample sets received, 1 lost on the link, 0 dropped by the device"
        );
    }

    #[test]
    fn gaps_across_an_interruption_or_a_restart_are_not_loss() {
        let mut accounting = StreamAccounting::new();
        accounting.sample(&sample(1));
        accounting.interrupted();
        accounting.sample(&sample(1_219));
        assert_eq!(accounting.lost_on_link(), 0);
        accounting.counters(&counters(50));
        accounting.counters(&counters(2));
        assert_eq!(accounting.device_dropped(), 2, "a restart counts from 0");
        accounting.sample(&sample(3));
        assert_eq!(accounting.sequence_gap_sets(), 0);
        assert_eq!(accounting.received(), 3);
    }
}
