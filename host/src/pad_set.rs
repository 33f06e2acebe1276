//! Sample sets of a device that reads several pads: the device sends one sample frame per pad
//! per set, in pad order, all with the set's sequence number. [`PadSetAssembler`] gathers the
//! frames of one set; a set is complete when every pad's frame arrived, and it is closed
//! incomplete when a frame of another set (or a second frame of a pad already in it) arrives,
//! or when the stream ends. A pad whose frame never came stays `None`: it is never filled in.
//! The first set taken is the first that starts with pad 0's frame: frames before it belong to
//! a set that began before the recording, and are skipped and counted.
//!
//! The CSV row of a set (see [`pad_set_header`]) has the sequence number, then every pad's
//! columns prefixed `pad<n>_`, then the marker.

use wire::{PadIndex, SampleFrame};

use crate::csv_format::{
    format_number, format_optional, format_time_us, temperature_source_name, wire_flag_names,
    CAPACITANCE_COLUMNS, FLAGS_COLUMNS, PRESSURE_COLUMNS, TEMPERATURE_COLUMN, TIME_COLUMN,
};
use crate::recording::{MARKER_COLUMN, SEQUENCE_COLUMN};

/// The most pads a device reads (pad indices 0 to [`PadIndex::MAX`]).
pub const MAX_PAD_COUNT: u8 = PadIndex::MAX + 1;

/// Temperature-source column of a recording (without a pad prefix).
pub const TEMPERATURE_SOURCE_COLUMN: &str = "temp_source";

/// A pad's total normal force, N; empty when no taxel of the pad reads.
pub const FORCE_COLUMN: &str = "force_n";

/// Centre of pressure, x then y in the pad's frame, mm; empty when there is none (no force, or
/// too little to place it).
pub const CENTRE_OF_PRESSURE_COLUMNS: [&str; 2] = ["cop_x_mm", "cop_y_mm"];

/// `1` when faulted taxels were left out of force and centre of pressure, else `0`.
pub const PARTIAL_COLUMN: &str = "partial";

/// `1` while the device says the pad is in contact, else `0`.
pub const CONTACT_COLUMN: &str = "contact";

/// The prefix of pad `pad`'s columns: `pad0_`, `pad1_`, ...
pub fn pad_prefix(pad: usize) -> String {
    format!("pad{pad}_")
}

/// Pad `pad`'s column `name`: `pad1_c12_pf`.
pub fn pad_column(pad: usize, name: &str) -> String {
    format!("{}{name}", pad_prefix(pad))
}

/// The columns of one pad in a multi-pad recording, without their prefix, in order.
pub fn pad_record_columns() -> Vec<&'static str> {
    let mut columns = vec![TIME_COLUMN, TEMPERATURE_COLUMN, TEMPERATURE_SOURCE_COLUMN];
    columns.extend(CAPACITANCE_COLUMNS);
    columns.extend(PRESSURE_COLUMNS);
    columns.extend(FLAGS_COLUMNS);
    columns.push(FORCE_COLUMN);
    columns.extend(CENTRE_OF_PRESSURE_COLUMNS);
    columns.push(PARTIAL_COLUMN);
    columns.push(CONTACT_COLUMN);
    columns
}

/// The CSV header of a recording of `pad_count` pads: `seq`, every pad's
/// [`pad_record_columns`] prefixed `pad<n>_` in pad order, `marker`.
pub fn pad_set_header(pad_count: u8) -> Vec<String> {
    let mut header = vec![SEQUENCE_COLUMN.to_owned()];
    for pad in 0..usize::from(pad_count) {
        header.extend(
            pad_record_columns()
                .into_iter()
                .map(|name| pad_column(pad, name)),
        );
    }
    header.push(MARKER_COLUMN.to_owned());
    header
}

fn flag_cell(value: bool) -> String {
    if value { "1" } else { "0" }.to_owned()
}

/// One pad's cells in [`pad_record_columns`] order; every cell empty when its frame is missing
/// (a frame that arrived always has its time and its `0`/`1` cells).
pub fn pad_cells(frame: Option<&SampleFrame>) -> Vec<String> {
    let Some(frame) = frame else {
        return vec![String::new(); pad_record_columns().len()];
    };
    let mut cells = vec![
        format_time_us(frame.timestamp_us),
        format_optional(frame.temperature_c),
        temperature_source_name(frame.temperature_source).to_owned(),
    ];
    cells.extend(
        frame
            .taxels
            .iter()
            .map(|taxel| format_number(taxel.capacitance_pf)),
    );
    cells.extend(
        frame
            .taxels
            .iter()
            .map(|taxel| format_optional(taxel.pressure_kpa)),
    );
    cells.extend(
        frame
            .taxels
            .iter()
            .map(|taxel| wire_flag_names(taxel.flags)),
    );
    let summary = &frame.summary;
    cells.push(format_optional(summary.force_n));
    let centre = summary.centre_of_pressure_mm;
    cells.push(format_optional(centre.map(|[x_mm, _]| x_mm)));
    cells.push(format_optional(centre.map(|[_, y_mm]| y_mm)));
    cells.push(flag_cell(summary.partial));
    cells.push(flag_cell(summary.contact));
    cells
}

/// The CSV cells of one sample set, in [`pad_set_header`] order.
pub fn pad_set_cells(set: &PadSet, marker: &str) -> Vec<String> {
    let mut cells = vec![set.sequence.to_string()];
    for frame in &set.pads {
        cells.extend(pad_cells(frame.as_ref()));
    }
    cells.push(marker.to_owned());
    cells
}

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
        SampleFrame {
            pad: PadIndex::new(pad).unwrap(),
            sequence,
            timestamp_us: u64::from(sequence) * 10_000 + u64::from(pad) * 300,
            temperature_c: Some(24.0),
            temperature_source: wire::TemperatureSource::Tmp117,
            taxels: [wire::TaxelSample {
                pressure_kpa: Some(f32::from(pad)),
                capacitance_pf: 4.5,
                flags: 0,
            }; 4],
            summary: wire::PadSummary {
                force_n: Some(0.25),
                centre_of_pressure_mm: Some([-1.5, 2.75]),
                partial: false,
                contact: pad == 1,
            },
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

    #[test]
    fn header_and_cells_name_every_pad_and_leave_a_missing_pad_empty() {
        let header = pad_set_header(2);
        assert_eq!(header.len(), 1 + 2 * 20 + 1);
        assert_eq!(header[0], "seq");
        assert_eq!(
            &header[1..21],
            [
                "pad0_time_s",
                "pad0_temp_c",
                "pad0_temp_source",
                "pad0_c11_pf",
                "pad0_c12_pf",
                "pad0_c21_pf",
                "pad0_c22_pf",
                "pad0_p11_kpa",
                "pad0_p12_kpa",
                "pad0_p21_kpa",
                "pad0_p22_kpa",
                "pad0_flags11",
                "pad0_flags12",
                "pad0_flags21",
                "pad0_flags22",
                "pad0_force_n",
                "pad0_cop_x_mm",
                "pad0_cop_y_mm",
                "pad0_partial",
                "pad0_contact",
            ]
        );
        assert_eq!(header[21], "pad1_time_s");
        assert_eq!(header[41], "marker");
        let set = PadSet {
            sequence: 12,
            pads: vec![None, Some(frame(1, 12))],
        };
        let cells = pad_set_cells(&set, "m");
        assert_eq!(cells.len(), header.len());
        assert_eq!(cells[0], "12");
        assert!(cells[1..21].iter().all(String::is_empty));
        assert_eq!(
            &cells[21..41],
            [
                "0.120300", "24", "tmp117", "4.5", "4.5", "4.5", "4.5", "1", "1", "1", "1", "", "",
                "", "", "0.25", "-1.5", "2.75", "0", "1",
            ]
        );
        assert_eq!(cells[41], "m");
    }
}
