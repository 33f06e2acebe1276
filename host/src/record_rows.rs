//! The rows of a recording's CSV file. A device with one pad gets one row per sample frame, in
//! the single-pad layout ([`crate::recording::record_header`]); a device with several pads gets
//! one row per sample set in the pad-prefixed layout ([`crate::pad_set::pad_set_header`]),
//! written once every pad's frame of the set arrived or the set was closed without them (a
//! later set began, or the recording ended); a missing pad's cells are empty.

use std::io::Write;

use anyhow::Context;
use wire::SampleFrame;

use crate::pad_set::{pad_set_cells, pad_set_header, PadSet, PadSetAssembler, MAX_PAD_COUNT};
use crate::recording::{record_header, sample_cells, SampleSink};

/// Writes a recording's rows to a CSV writer (see the module documentation).
#[derive(Debug)]
pub struct RecordRows<W: Write> {
    csv: csv::Writer<W>,
    sets: Option<PadSetAssembler>,
    pending_marker: Option<String>,
    markers: u64,
    rows: u64,
    incomplete_rows: u64,
    missing_of_pad: [u64; MAX_PAD_COUNT as usize],
}

impl<W: Write> RecordRows<W> {
    /// Rows for a device of `pad_count` pads (1 to 8); writes the header at once. The CSV
    /// writer should end lines with CRLF, as every file of the tool does.
    pub fn new(mut csv: csv::Writer<W>, pad_count: u8) -> anyhow::Result<Self> {
        let sets = (pad_count > 1).then(|| PadSetAssembler::new(pad_count));
        match &sets {
            Some(sets) => csv.write_record(pad_set_header(sets.pad_count() as u8)),
            None => csv.write_record(record_header()),
        }
        .context("writing the CSV header")?;
        Ok(Self {
            csv,
            sets,
            pending_marker: None,
            markers: 0,
            rows: 0,
            incomplete_rows: 0,
            missing_of_pad: [0; MAX_PAD_COUNT as usize],
        })
    }

    /// A CRLF-terminated CSV writer over `output`, with its header (see [`RecordRows::new`]).
    pub fn from_writer(output: W, pad_count: u8) -> anyhow::Result<Self> {
        Self::new(
            csv::WriterBuilder::new()
                .terminator(csv::Terminator::CRLF)
                .from_writer(output),
            pad_count,
        )
    }

    /// The pads of a row: 1 for the single-pad layout.
    pub fn pad_count(&self) -> usize {
        self.sets.as_ref().map_or(1, PadSetAssembler::pad_count)
    }

    /// Puts a marker on the next row written (markers dropped before it are joined with '|').
    pub fn mark(&mut self, label: &str) {
        self.markers += 1;
        match &mut self.pending_marker {
            Some(pending) => {
                pending.push('|');
                pending.push_str(label);
            }
            None => self.pending_marker = Some(label.to_owned()),
        }
    }

    /// Markers dropped.
    pub fn markers(&self) -> u64 {
        self.markers
    }

    /// Rows written: sample frames with one pad, sample sets with several.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Rows of a sample set that lacked the frame of at least one pad.
    pub fn incomplete_rows(&self) -> u64 {
        self.incomplete_rows
    }

    /// Rows in which pad `pad`'s frame was missing (its cells empty).
    pub fn missing_of_pad(&self, pad: usize) -> u64 {
        self.missing_of_pad.get(pad).copied().unwrap_or(0)
    }

    /// Whether `sample` would close the sample set in progress (always false with one pad):
    /// the row of that set is then written before `sample` is taken.
    pub fn would_close_set(&self, sample: &SampleFrame) -> bool {
        self.sets
            .as_ref()
            .is_some_and(|sets| sets.would_close(sample))
    }

    /// Takes one sample frame; writes the rows it completes.
    pub fn write_frame(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        let Some(sets) = self.sets.as_mut() else {
            if sample.pad.get() != 0 {
                anyhow::bail!(
                    "a frame of pad {} reached a recording of one pad",
                    sample.pad.get()
                );
            }
            let marker = self.pending_marker.take().unwrap_or_default();
            self.csv
                .write_record(sample_cells(sample, &marker))
                .with_context(|| format!("writing the CSV after {} rows", self.rows))?;
            self.rows += 1;
            return Ok(());
        };
        for set in sets.push(*sample) {
            self.write_set(&set)?;
        }
        Ok(())
    }

    fn write_set(&mut self, set: &PadSet) -> anyhow::Result<()> {
        let marker = self.pending_marker.take().unwrap_or_default();
        self.csv
            .write_record(pad_set_cells(set, &marker))
            .with_context(|| format!("writing the CSV after {} rows", self.rows))?;
        self.rows += 1;
        if !set.is_complete() {
            self.incomplete_rows += 1;
            for pad in set.missing_pads() {
                if let Some(count) = self.missing_of_pad.get_mut(pad) {
                    *count += 1;
                }
            }
        }
        Ok(())
    }

    /// The stream ended: writes the row of the sample set in progress, with its missing pads.
    pub fn end_of_stream(&mut self) -> anyhow::Result<()> {
        if let Some(set) = self.sets.as_mut().and_then(PadSetAssembler::finish) {
            self.write_set(&set)?;
        }
        Ok(())
    }

    /// Pushes written rows out (the set in progress stays open).
    pub fn flush(&mut self) -> anyhow::Result<()> {
        self.csv.flush().context("writing the CSV")
    }

    /// Ends the rows (see [`RecordRows::end_of_stream`]), flushes, and gives the CSV writer back.
    pub fn finish(mut self) -> anyhow::Result<csv::Writer<W>> {
        self.end_of_stream()?;
        self.flush()?;
        Ok(self.csv)
    }

    /// Words for people on the sets that lacked pads, e.g. "2 of 100 rows lack a pad (pad 1: 2)",
    /// and on the frames before the first whole set (in the raw log, not in a row); `None` with
    /// one pad or when every set was complete.
    pub fn incomplete_words(&self) -> Option<String> {
        let skipped = self
            .sets
            .as_ref()
            .map_or(0, PadSetAssembler::frames_before_first_set);
        let skipped_words = (skipped > 0)
            .then(|| format!("{skipped} frames of a set begun before the recording were skipped"));
        if self.incomplete_rows == 0 {
            return skipped_words;
        }
        let per_pad: Vec<String> = (0..self.pad_count())
            .filter(|&pad| self.missing_of_pad(pad) > 0)
            .map(|pad| format!("pad {pad}: {}", self.missing_of_pad(pad)))
            .collect();
        let incomplete = format!(
            "{} of {} rows lack the frame of a pad, their cells empty ({})",
            self.incomplete_rows,
            self.rows,
            per_pad.join(", ")
        );
        Some(match skipped_words {
            Some(skipped_words) => format!("{incomplete}; {skipped_words}"),
            None => incomplete,
        })
    }
}

impl<W: Write> SampleSink for RecordRows<W> {
    fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        self.write_frame(sample)
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        RecordRows::flush(self)
    }

    fn rows(&self) -> Option<u64> {
        Some(self.rows)
    }

    fn would_close_set(&self, sample: &SampleFrame) -> bool {
        RecordRows::would_close_set(self, sample)
    }
}
