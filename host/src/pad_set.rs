//! Sample sets of a device that reads several pads: the device sends one sample frame per pad
//! per set, in pad order, all with the set's sequence number. [`PadSetAssembler`] gathers the
//! frames of one set; a set is complete when every pad's frame arrived, and it is closed
//! incomplete when a frame of another set (or a second frame of a pad already in it) arrives,
//! or when the stream ends. A pad whose frame never came stays `None`: it is never filled in.
//! The first set taken is the first that starts with pad 0's frame: frames before it belong to
//! a set that began before the recording, and are skipped and counted.
//!

use wire::{PadIndex, SampleFrame};

/// The most pads a device reads (pad indices 0 to [`PadIndex::MAX`]).
pub const MAX_PAD_COUNT: u8 = PadIndex::MAX + 1;

/// The frames of one sample set, one slot per pad in pad order.
#[derive(Debug, Clone, PartialEq)]
pub struct PadSet {
    /// The set's sequence number.
    pub sequence: u32,
    /// Each pad's frame, `None` when it did not arrive.
    pub pads: Vec<Option<SampleFrame>>,
}

impl PadSet {
    fn new(sequence: u32, pad_count: usize) -> Self {
        Self {
            sequence,
            pads: vec![None; pad_count],
        }
    }

    /// Every pad's frame is there.
    pub fn is_complete(&self) -> bool {
        self.pads.iter().all(Option::is_some)
    }

    /// The pads whose frame is missing.
    pub fn missing_pads(&self) -> impl Iterator<Item = usize> + '_ {
        self.pads
            .iter()
            .enumerate()
            .filter(|(_, frame)| frame.is_none())
            .map(|(pad, _)| pad)
    }
}

/// Gathers the frames of each sample set (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct PadSetAssembler {
    pad_count: usize,
    open: Option<PadSet>,
    frames_beyond_pad_count: u64,
    // Sets start with pad 0: until its first frame, what arrives is the tail of a set that began
    // before the recording, which would make a first row with pads missing for no fault.
    started: bool,
    frames_before_first_set: u64,
}

impl PadSetAssembler {
    /// An assembler for a device of `pad_count` pads (taken as 1 to [`MAX_PAD_COUNT`]).
    pub fn new(pad_count: u8) -> Self {
        Self {
            pad_count: usize::from(pad_count.clamp(1, MAX_PAD_COUNT)),
            open: None,
            frames_beyond_pad_count: 0,
            started: false,
            frames_before_first_set: 0,
        }
    }

    /// Frames skipped at the start: the rest of a set that began before the first frame of
    /// pad 0 arrived.
    pub fn frames_before_first_set(&self) -> u64 {
        self.frames_before_first_set
    }

    /// The number of pads of a set.
    pub fn pad_count(&self) -> usize {
        self.pad_count
    }

    /// Frames of a pad at or above the pad count, ignored (the link sets them aside before).
    pub fn frames_beyond_pad_count(&self) -> u64 {
        self.frames_beyond_pad_count
    }

    /// Whether `frame` would close the set that is open: it belongs to another set, or its pad
    /// already has a frame in it.
    pub fn would_close(&self, frame: &SampleFrame) -> bool {
        self.open.as_ref().is_some_and(|open| {
            open.sequence != frame.sequence
                || open
                    .pads
                    .get(usize::from(frame.pad.get()))
                    .is_some_and(Option::is_some)
        })
    }

    /// Takes one frame; returns the sets it closed, in order: the set that was open if the
    /// frame belongs to another one, then the frame's own set if the frame completed it.
    pub fn push(&mut self, frame: SampleFrame) -> Vec<PadSet> {
        let pad = usize::from(frame.pad.get());
        if pad >= self.pad_count {
            self.frames_beyond_pad_count += 1;
            return Vec::new();
        }
        if !self.started {
            if pad != 0 {
                self.frames_before_first_set += 1;
                return Vec::new();
            }
            self.started = true;
        }
        let mut closed = Vec::new();
        if self.would_close(&frame) {
            closed.extend(self.open.take());
        }
        let open = self
            .open
            .get_or_insert_with(|| PadSet::new(frame.sequence, self.pad_count));
        if let Some(slot) = open.pads.get_mut(pad) {
            *slot = Some(frame);
        }
        if open.is_complete() {
            closed.extend(self.open.take());
        }
        closed
    }

    /// The stream ended: returns the set still open, if any, with its missing pads.
    pub fn finish(&mut self) -> Option<PadSet> {
        self.open.take()
    }

    /// Whether a set is open (some of its frames arrived, not all).
    pub fn has_open_set(&self) -> bool {
        self.open.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(pad: u8, sequence: u32) -> SampleFrame {
        let base = wire::testing::sample_frame(pad);
        SampleFrame {
            sequence,
            timestamp_us: u64::from(sequence) * 10_000 + u64::from(pad) * 300,
            temperature_c: Some(24.0),
            taxels: [wire::TaxelSample {
                pressure_kpa: Some(f32::from(pad)),
                ..base.taxels[0]
            }; 4],
            summary: wire::PadSummary {
                force_n: Some(0.25),
                centre_of_pressure_mm: Some([-1.5, 2.75]),
                partial: false,
                contact: pad == 1,
            },
            ..base
        }
    }

    #[test]
    fn a_set_closes_when_complete_or_when_another_begins() {
        let mut assembler = PadSetAssembler::new(3);
        assert!(assembler.push(frame(0, 1)).is_empty());
        assert!(assembler.push(frame(1, 1)).is_empty());
        let closed = assembler.push(frame(2, 1));
        assert_eq!(closed.len(), 1);
        assert!(closed[0].is_complete());
        // Set 2 lacks pad 1; set 3 begins and closes it.
        assembler.push(frame(0, 2));
        assert!(!assembler.would_close(&frame(2, 2)));
        assert!(assembler.would_close(&frame(0, 3)));
        assembler.push(frame(2, 2));
        let closed = assembler.push(frame(0, 3));
        assert_eq!(closed.len(), 1);
        assert_eq!(closed[0].sequence, 2);
        assert_eq!(closed[0].missing_pads().collect::<Vec<_>>(), [1]);
        assert_eq!(closed[0].pads[2], Some(frame(2, 2)));
        // A repeated pad closes the set too; pad 0 of set 3 is not lost.
        let closed = assembler.push(frame(0, 3));
        assert_eq!(closed[0].missing_pads().collect::<Vec<_>>(), [1, 2]);
        let last = assembler.finish().unwrap();
        assert_eq!(last.pads[0], Some(frame(0, 3)));
        assert!(assembler.finish().is_none());
        assert!(assembler.push(frame(5, 4)).is_empty());
        assert_eq!(assembler.frames_beyond_pad_count(), 1);
    }

    #[test]
    fn the_tail_of_a_set_begun_before_the_recording_is_skipped_and_counted() {
        let mut assembler = PadSetAssembler::new(3);
        assert!(assembler.push(frame(1, 9)).is_empty());
        assert!(assembler.push(frame(2, 9)).is_empty());
        assert!(!assembler.has_open_set());
        assert_eq!(assembler.frames_before_first_set(), 2);
        assembler.push(frame(0, 10));
        assembler.push(frame(1, 10));
        let closed = assembler.push(frame(2, 10));
        assert_eq!(closed.len(), 1);
        assert!(closed[0].is_complete());
        // Later, a set missing pad 0 is a set with a missing pad, not skipped.
        assembler.push(frame(1, 11));
        assert_eq!(assembler.frames_before_first_set(), 2);
        assert_eq!(
            assembler
                .finish()
                .unwrap()
                .missing_pads()
                .collect::<Vec<_>>(),
            [0, 2]
        );
    }

    #[test]
    fn a_set_missing_its_last_pad_closes_and_the_next_completes_in_one_push() {
        let mut assembler = PadSetAssembler::new(2);
        assembler.push(frame(0, 7));
        let closed = assembler.push(frame(1, 8));
        assert_eq!(closed.len(), 1, "set 8 still lacks pad 0");
        assert_eq!(closed[0].missing_pads().collect::<Vec<_>>(), [1]);
        let mut assembler = PadSetAssembler::new(1);
        let closed = assembler.push(frame(0, 9));
        assert_eq!(closed.len(), 1);
        assert!(!assembler.has_open_set());
    }
}
