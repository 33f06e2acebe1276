//! The host's batch path (feature `batch`): [`PadModel::process`] and [`PadPipeline::process`]
//! over many sample sets with the tier's inverses of the sets computed together, which a
//! superscalar core runs faster. The firmware calls `process` set by set and does not build
//! this.

use crate::calibration::TAXEL_COUNT;
use crate::flags::TaxelFlags;
use crate::pad::{PadModel, PadOutput, SampleInput};
use crate::pad_pipeline::{PadPipeline, PadReport};
use crate::reading::TaxelReading;
use crate::taxel::TaxelOutput;
use crate::temperature::TemperatureUsed;

/// Most sample sets [`PadModel::process_all`] holds at once: enough independent inverses to
/// keep a host core busy, little enough for its stack.
pub const BATCH_SAMPLE_SETS: usize = 64;

// A set's position in a batch is kept in a byte.
const _: () = assert!(BATCH_SAMPLE_SETS <= 256);

impl PadModel {
    /// [`PadModel::process`] of every sample set in turn, handing each output to `each` in
    /// order with its set's position: the same outputs bit for bit (tested), faster when a host
    /// converts a recording,
    /// because the tier's inverses of up to [`BATCH_SAMPLE_SETS`] sets run together per taxel
    /// (nothing the sets change depends on them). It holds those sets' outputs on the stack
    /// (about 7 KB): a host's path; the device calls `process`.
    pub fn process_all<I>(&mut self, samples: I, mut each: impl FnMut(usize, &PadOutput))
    where
        I: IntoIterator<Item = SampleInput>,
    {
        let mut samples = samples.into_iter();
        self.process_all_in(
            &mut samples,
            |samples, _| samples.next(),
            |_, position, output, _| each(position, output),
        );
    }

    /// [`PadModel::process_all`] of the sets `sample(context, position)` gives in turn (until
    /// `None`), made as they are needed, with each output and its set's time handed to
    /// `each(context, position, ...)`, which may change `context` (where the sets are read
    /// from, e.g. to write the results beside them).
    pub fn process_all_in<C: ?Sized>(
        &mut self,
        context: &mut C,
        mut sample: impl FnMut(&mut C, usize) -> Option<SampleInput>,
        mut each: impl FnMut(&mut C, usize, &PadOutput, Option<u64>),
    ) {
        let unset = PadOutput {
            taxels: [TaxelOutput::fault(TaxelFlags::empty(), None); TAXEL_COUNT],
            temperature: TemperatureUsed {
                temperature_c: 0.0,
                permittivity_ratio: 1.0,
                flags: TaxelFlags::empty(),
            },
        };
        let mut outputs = [unset; BATCH_SAMPLE_SETS];
        let mut samples =
            [SampleInput::new([TaxelReading::Unavailable; TAXEL_COUNT], None); BATCH_SAMPLE_SETS];
        let mut position = 0;
        loop {
            let mut count = 0;
            for (set, slot) in samples.iter_mut().enumerate() {
                let Some(sample) = sample(context, position + set) else {
                    break;
                };
                *slot = sample;
                count += 1;
            }
            let (Some(samples), Some(outputs)) = (samples.get(..count), outputs.get_mut(..count))
            else {
                return;
            };
            if samples.is_empty() {
                return;
            }
            // Per taxel, the dC/C0 of the sets whose pressure is left to the inverse and those
            // sets' places, written as the conversion meets them: no second pass over the
            // outputs to gather them.
            let mut columns = [InverseColumn::EMPTY; TAXEL_COUNT];
            // Set by set while a tare averages (its end changes every taxel's baseline), then
            // the rest taxel by taxel.
            let mut first_independent = 0;
            for (set, (sample, output)) in samples.iter().zip(outputs.iter_mut()).enumerate() {
                if self.taxels_independent() {
                    break;
                }
                *output = self.process_with(sample, |taxel, _, _, relative_change| {
                    if let Some(column) = columns.get_mut(taxel) {
                        column.push(set, relative_change);
                    }
                    0.0
                });
                first_independent = set + 1;
            }
            if let (Some(samples), Some(outputs)) = (
                samples.get(first_independent..),
                outputs.get_mut(first_independent..),
            ) {
                self.process_columns(samples, outputs, |taxel, set, relative_change| {
                    if let Some(column) = columns.get_mut(taxel) {
                        column.push(first_independent + set, relative_change);
                    }
                    0.0
                });
            }
            for (taxel, ((model, calibration), column)) in
                self.taxel_models().zip(&mut columns).enumerate()
            {
                let values = column.values.get_mut(..column.count).unwrap_or_default();
                model.inverse().pressures_kpa(calibration.curve(), values);
                for (pressure_kpa, set) in values.iter().zip(&column.sets) {
                    if let Some(slot) = outputs
                        .get_mut(usize::from(*set))
                        .and_then(|output| output.taxels.get_mut(taxel))
                    {
                        *slot = slot.with_pressure_kpa(*pressure_kpa);
                    }
                }
            }
            for (output, sample) in outputs.iter().zip(samples) {
                each(context, position, output, sample.time_us);
                position += 1;
            }
        }
    }
}

/// One taxel's readings of a batch that need the inverse: their dC/C0 (replaced by the
/// pressures) and the positions of their sets.
struct InverseColumn {
    values: [f32; BATCH_SAMPLE_SETS],
    sets: [u8; BATCH_SAMPLE_SETS],
    count: usize,
}

impl InverseColumn {
    const EMPTY: Self = Self {
        values: [0.0; BATCH_SAMPLE_SETS],
        sets: [0; BATCH_SAMPLE_SETS],
        count: 0,
    };

    /// Adds set `set`'s dC/C0 (a batch holds at most [`BATCH_SAMPLE_SETS`] sets, so it fits).
    #[inline(always)]
    fn push(&mut self, set: usize, relative_change: f32) {
        if let (Some(value), Some(slot)) = (
            self.values.get_mut(self.count),
            self.sets.get_mut(self.count),
        ) {
            *value = relative_change;
            *slot = set as u8;
            self.count += 1;
        }
    }
}

impl PadPipeline {
    /// [`PadPipeline::process`] of every sample set of `samples` in turn, handing each report to
    /// `each` in order with its set's position: the same reports bit for bit (tested), with the
    /// model's inverses run together as [`PadModel::process_all`] runs them.
    pub fn process_all(
        &mut self,
        samples: &[SampleInput],
        mut each: impl FnMut(usize, &PadReport),
    ) {
        self.process_all_in(
            &mut (),
            |_, position| samples.get(position).copied(),
            |_, position, report| each(position, report),
        );
    }

    /// [`PadPipeline::process_all`] of the sets `sample(context, position)` gives in turn
    /// (until `None`), made as they are needed, with each report handed to
    /// `each(context, position, report)`, which may change `context`: a host converting
    /// recorded readings reads the sets from them and writes the reports back into them, with
    /// no list of the sets made.
    pub fn process_all_in<C: ?Sized>(
        &mut self,
        context: &mut C,
        sample: impl FnMut(&mut C, usize) -> Option<SampleInput>,
        mut each: impl FnMut(&mut C, usize, &PadReport),
    ) {
        let (model, force_and_contact) = self.parts_mut();
        model.process_all_in(context, sample, |context, position, output, time_us| {
            let contact = force_and_contact.update(&output.taxels, time_us.unwrap_or(0));
            each(
                context,
                position,
                &PadReport {
                    output: *output,
                    contact,
                },
            );
        });
    }
}
