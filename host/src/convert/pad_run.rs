//! Running one pad's model over a stream of samples: the model with its calibration and tier,
//! the baselines (a tare on the first rows, or the recorded ones installed at their sequence
//! numbers), and what the tare said. One [`PadRun`] per pad.

use model_core::{
    BaselineRecord, PadModel, SampleInput, TareStatus, TaxelFlags, TaxelReading, TAXEL_COUNT,
    TAXEL_NAMES,
};
use wire::SampleFrame;

use super::{PadOptions, TareSource};
use crate::csv_format::{flag_names, format_optional};
use crate::recording::BaselineChange;

/// Flags a recording's sample frames carry that come from the acquisition, not the model, and
/// so must be kept when the model runs again.
pub(super) const ACQUISITION_FLAGS: TaxelFlags = TaxelFlags::CONVERTER_ERROR
    .union(TaxelFlags::STUCK)
    .union(TaxelFlags::SATURATED);

fn new_model(options: &PadOptions) -> anyhow::Result<PadModel> {
    let mut pad = PadModel::new(options.calibration.clone());
    pad.set_tier(options.tier).map_err(|_| {
        anyhow::anyhow!(
            "tier {} is not available for this calibration (the saturating fit needs a concave curve on every taxel)",
            options.tier.name()
        )
    })?;
    if let TareSource::Rows(rows) = options.tare {
        pad.start_tare(rows);
    }
    Ok(pad)
}

/// Installs the recorded baselines in force at each sample's sequence number.
#[derive(Debug, Default)]
struct RecordedBaselines {
    changes: Vec<BaselineChange>,
    installed: Option<usize>,
    warnings: Vec<String>,
}

impl RecordedBaselines {
    fn new(tare: &TareSource) -> Self {
        match tare {
            TareSource::Recorded(changes) => Self {
                changes: changes.clone(),
                ..Self::default()
            },
            TareSource::Rows(_) => Self::default(),
        }
    }

    /// Before a sample: installs the baselines that apply from `sequence` on (the first ones
    /// when the data has no sequence numbers).
    fn before_sample(&mut self, pad: &mut PadModel, sequence: Option<u32>) {
        let wanted = match sequence {
            Some(sequence) => self
                .changes
                .iter()
                .rposition(|change| change.from_sequence <= sequence)
                .or(if self.changes.is_empty() {
                    None
                } else {
                    Some(0)
                }),
            None if self.changes.is_empty() => None,
            None => Some(0),
        };
        if wanted.is_none() || wanted == self.installed {
            return;
        }
        self.installed = wanted;
        let Some(change) = wanted.and_then(|index| self.changes.get(index)) else {
            return;
        };
        install_baselines(pad, &change.taxels, &mut self.warnings);
    }
}

fn install_baselines(
    pad: &mut PadModel,
    baselines: &[Option<BaselineRecord>; TAXEL_COUNT],
    warnings: &mut Vec<String>,
) {
    let restored = pad.restore_baselines(baselines);
    for (taxel, baseline) in baselines.iter().enumerate() {
        if baseline.is_some() && restored & (1 << taxel) == 0 {
            warnings.push(format!(
                "the recorded baseline of taxel {} is not valid with this calibration; it stays not_tared",
                TAXEL_NAMES[taxel]
            ));
        }
    }
}

/// Runs one sample through the model and returns the output cells after `time_s,temp_c`.
fn model_cells(
    pad: &mut PadModel,
    sample: &SampleInput,
    tare_watch: &mut TareWatch,
) -> Vec<String> {
    let output = pad.process(sample);
    tare_watch.observe(pad);
    let mut cells: Vec<String> = output
        .taxels
        .iter()
        .map(|taxel| format_optional(taxel.pressure_kpa()))
        .collect();
    cells.extend(output.taxels.iter().map(|taxel| flag_names(taxel.flags())));
    cells
}

/// Notices when the tare finishes and whether every taxel got a baseline.
#[derive(Debug, Default)]
struct TareWatch {
    reported: bool,
    warnings: Vec<String>,
}

impl TareWatch {
    fn observe(&mut self, pad: &PadModel) {
        if self.reported {
            return;
        }
        if let TareStatus::Finished { tared_mask } = pad.tare_status() {
            self.reported = true;
            let errors = pad.last_tare_errors();
            for taxel in 0..TAXEL_COUNT {
                if tared_mask & (1 << taxel) == 0 {
                    self.warnings.push(format!(
                        "taxel {} could not be tared ({}); it stays not_tared",
                        TAXEL_NAMES[taxel],
                        errors[taxel]
                            .map(|error| crate::device_words::baseline_error_words(&error))
                            .unwrap_or_else(|| "no usable reading".to_owned())
                    ));
                }
            }
        }
    }

    fn finish(mut self, pad: &PadModel) -> Vec<String> {
        if let TareStatus::Running { remaining } = pad.tare_status() {
            self.warnings.push(format!(
                "the tare never finished ({remaining} more readable rows were needed); every pressure is empty (not_tared)"
            ));
        }
        self.warnings
    }
}

/// One pad's model, baselines and tare watch over a stream.
#[derive(Debug)]
pub(super) struct PadRun {
    model: PadModel,
    baselines: RecordedBaselines,
    tare_watch: TareWatch,
}

impl PadRun {
    /// A fresh run with a pad's calibration, tier and baselines.
    pub(super) fn new(options: &PadOptions) -> anyhow::Result<Self> {
        Ok(Self {
            model: new_model(options)?,
            baselines: RecordedBaselines::new(&options.tare),
            tare_watch: TareWatch::default(),
        })
    }

    /// Runs one sample (with its sequence number, when known) and returns the pressure and
    /// flags cells.
    pub(super) fn cells(&mut self, sequence: Option<u32>, input: &SampleInput) -> Vec<String> {
        self.baselines.before_sample(&mut self.model, sequence);
        model_cells(&mut self.model, input, &mut self.tare_watch)
    }

    /// The tare's problems, at the end.
    pub(super) fn warnings(self) -> Vec<String> {
        let mut warnings = self.baselines.warnings;
        warnings.extend(self.tare_watch.finish(&self.model));
        warnings
    }
}

/// The model input of a recorded sample frame: its capacitances and temperature, the
/// acquisition's flags kept, and a converter error read as no reading.
pub(super) fn frame_input(sample: &SampleFrame) -> SampleInput {
    let mut input = SampleInput::new(
        [TaxelReading::Unavailable; TAXEL_COUNT],
        sample.temperature_c.filter(|value| !value.is_nan()),
    )
    .at_time_us(sample.timestamp_us);
    for (taxel, recorded) in sample.taxels.iter().enumerate() {
        let acquisition_flags =
            TaxelFlags::from_bits_retain(recorded.flags).intersection(ACQUISITION_FLAGS);
        input.reading_flags[taxel] = acquisition_flags;
        if !acquisition_flags.contains(TaxelFlags::CONVERTER_ERROR) {
            input.readings[taxel] = TaxelReading::CapacitancePf(recorded.capacitance_pf);
        }
    }
    input
}
