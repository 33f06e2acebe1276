//! The host's batch path (feature `batch`): [`PadModel::process`] and [`PadPipeline::process`]
//! over many sample sets with the tier's inverses of the sets computed together, which a
//! superscalar core runs faster. The firmware calls `process` set by set and does not build
//! this.

use crate::calibration::TAXEL_COUNT;
use crate::flags::TaxelFlags;
use crate::pad::{PadModel, PadOutput, SampleInput};
use crate::pad_pipeline::{PadPipeline, PadReport};
use crate::taxel::TaxelOutput;
use crate::temperature::TemperatureUsed;

/// Most sample sets [`PadModel::process_all`] holds at once: enough independent inverses to
/// keep a host core busy, little enough for its stack.
pub const BATCH_SAMPLE_SETS: usize = 64;

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
        let unset = PadOutput {
            taxels: [TaxelOutput::fault(TaxelFlags::empty(), None); TAXEL_COUNT],
            temperature: TemperatureUsed {
                temperature_c: 0.0,
                permittivity_ratio: 1.0,
                flags: TaxelFlags::empty(),
            },
        };
        let mut outputs = [(unset, 0u8); BATCH_SAMPLE_SETS];
        let mut position = 0;
        loop {
            let mut count = 0;
            for (slot, sample) in outputs.iter_mut().zip(samples.by_ref()) {
                // The pressures of in-range taxels are left to `invert_batch`.
                let mut needs_inverse = 0u8;
                let output = self.process_with(&sample, |taxel, _, _, _| {
                    needs_inverse |= 1 << taxel;
                    0.0
                });
                *slot = (output, needs_inverse);
                count += 1;
            }
            let outputs = outputs.get_mut(..count).unwrap_or_default();
            if outputs.is_empty() {
                return;
            }
            self.invert_batch(outputs);
            for (output, _) in outputs.iter() {
                each(position, output);
                position += 1;
            }
        }
    }

    /// Fills in the pressures [`PadModel::process_all`] left to the inverse, taxel by taxel
    /// across the sets.
    fn invert_batch(&self, outputs: &mut [(PadOutput, u8)]) {
        for (taxel, (model, calibration)) in self.taxel_models().enumerate() {
            let needs = |needs_inverse: u8| needs_inverse & (1 << taxel) != 0;
            let mut values = [0.0f32; BATCH_SAMPLE_SETS];
            let mut count = 0;
            for (output, needs_inverse) in outputs.iter() {
                if let (true, Some(slot), Some(value)) = (
                    needs(*needs_inverse),
                    values.get_mut(count),
                    output
                        .taxels
                        .get(taxel)
                        .and_then(TaxelOutput::relative_change),
                ) {
                    *slot = value;
                    count += 1;
                }
            }
            let values = values.get_mut(..count).unwrap_or_default();
            model.inverse().pressures_kpa(calibration.curve(), values);
            let mut pressures_kpa = values.iter();
            for (output, needs_inverse) in outputs.iter_mut() {
                if !needs(*needs_inverse) {
                    continue;
                }
                if let (Some(slot), Some(pressure_kpa)) =
                    (output.taxels.get_mut(taxel), pressures_kpa.next())
                {
                    *slot = slot.with_pressure_kpa(*pressure_kpa);
                }
            }
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
        let (model, force_and_contact) = self.parts_mut();
        model.process_all(samples.iter().copied(), |position, output| {
            let time_us = samples
                .get(position)
                .and_then(|sample| sample.time_us)
                .unwrap_or(0);
            let contact = force_and_contact.update(&output.taxels, time_us);
            each(
                position,
                &PadReport {
                    output: *output,
                    contact,
                },
            );
        });
    }
}
