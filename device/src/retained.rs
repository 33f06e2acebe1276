//! State kept across an MCU-only reset (watchdog, software reset, reset pin) in RAM that the
//! start-up code does not clear, and what a boot does with it.
//!
//! A pad may be loaded when the MCU resets (a gripper holding an object): taring then would turn
//! the held load into a zero that looks like good data. So only a power-on tares by itself (the
//! pad is taken to be unloaded at power-up, as documented); after an MCU-only reset the baselines
//! from before the reset are restored when their record is intact, and otherwise every taxel
//! stays `not_tared` (a fault) until the host sends a tare.
//!
//! Record: postcard of [`RetainedRecord`] (magic "TXRS", format version, the state) followed by
//! postcard's CRC-32/ISO-HDLC of those bytes, in a buffer of [`RETAINED_LEN`] bytes.

use acquisition::discovery::MAX_PADS;
use crc::{Crc, CRC_32_ISO_HDLC};
use model_core::{BaselineRecord, PadModel, Tier, TAXEL_COUNT};
use serde::{Deserialize, Serialize};

/// Bytes kept for the record: the largest encoding (eight pads, every taxel tared) is 4 + 1 +
/// 8 × (1 + 2 + 4 × 17 + 1) + 4 = 585 bytes; a test checks that it fits. The bytes after the
/// CRC must be 0.
pub const RETAINED_LEN: usize = 588;

const MAGIC: [u8; 4] = *b"TXRS";
/// 3: one entry per pad (2 held the first pad's alone, and is refused: those taxels stay
/// untared after the update's reset until the host tares).
const FORMAT_VERSION: u8 = 3;
const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// What one pad had before an MCU-only reset.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RetainedPad {
    /// The multiplexer channel the pad is on (`None`: on the bus itself): a pad is given back
    /// its own baselines only if discovery finds it on the same channel again.
    pub channel: Option<u8>,
    /// Per taxel, the baseline in force before the reset (with its tracked drift).
    pub baselines: [Option<BaselineRecord>; TAXEL_COUNT],
    /// The tier in force before the reset.
    pub tier: Tier,
}

/// What survives an MCU-only reset: every pad's state, in discovery order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RetainedState {
    /// Per pad found before the reset; the rest `None`.
    pub pads: [Option<RetainedPad>; MAX_PADS],
}

/// The record as encoded: the magic and version make a record of another layout unreadable
/// rather than misread.
#[derive(Serialize, Deserialize)]
struct RetainedRecord {
    magic: [u8; 4],
    format_version: u8,
    state: RetainedState,
}

impl RetainedState {
    /// The record's bytes (unused bytes after the CRC are 0).
    pub fn encode(&self) -> [u8; RETAINED_LEN] {
        let mut bytes = [0u8; RETAINED_LEN];
        let record = RetainedRecord {
            magic: MAGIC,
            format_version: FORMAT_VERSION,
            state: *self,
        };
        // Cannot fail: the largest encoding fits (tested); should it ever not, the zeroed buffer
        // is refused at the next boot, which then leaves the taxels untared.
        if postcard::to_slice_crc32(&record, &mut bytes, CRC.digest()).is_err() {
            bytes = [0u8; RETAINED_LEN];
        }
        bytes
    }

    /// The state in a record, or `None` when the bytes are not an intact record (RAM after a
    /// power-on holds noise; a torn write fails the CRC).
    pub fn decode(bytes: &[u8; RETAINED_LEN]) -> Option<Self> {
        let (record, unused): (RetainedRecord, _) =
            postcard::take_from_bytes_crc32(bytes, CRC.digest()).ok()?;
        let intact = record.magic == MAGIC
            && record.format_version == FORMAT_VERSION
            && unused.iter().all(|&byte| byte == 0);
        intact.then_some(record.state)
    }
}

/// Why the MCU started.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetKind {
    /// Power-on or brown-out: retained RAM holds nothing.
    PowerOn,
    /// Watchdog, software reset, reset pin: the pad kept its state, perhaps under load.
    McuOnly,
}

/// What a boot does about the baselines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BootPlan {
    /// State to restore (baselines, tier), if any.
    pub restore: Option<RetainedState>,
    /// Sample sets of the tare to take at start (0 = none).
    pub tare_sets_at_start: u16,
}

impl BootPlan {
    /// Restores into a model built from the boot's calibration the retained baselines and tier
    /// of the pad that was on `channel` (none: nothing); returns the taxels restored (bit n =
    /// taxel n). The tare at start is the caller's to pass to the acquisition loop.
    pub fn apply_to(&self, channel: Option<u8>, pad: &mut PadModel) -> u8 {
        let Some(state) = self.restore else {
            return 0;
        };
        let Some(retained) = state
            .pads
            .iter()
            .flatten()
            .find(|retained| retained.channel == channel)
        else {
            return 0;
        };
        let _ = pad.set_tier(retained.tier);
        pad.restore_baselines(&retained.baselines)
    }
}

/// Decides the boot: a power-on tares over `tare_sets` sets; an MCU-only reset restores the
/// retained state when it is intact and otherwise leaves the taxels untared.
pub fn boot_plan(reset: ResetKind, retained: Option<RetainedState>, tare_sets: u16) -> BootPlan {
    match reset {
        ResetKind::PowerOn => BootPlan {
            restore: None,
            tare_sets_at_start: tare_sets,
        },
        ResetKind::McuOnly => BootPlan {
            restore: retained,
            tare_sets_at_start: 0,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::SplitCapacitance;

    fn state() -> RetainedState {
        let mut pads = [None; MAX_PADS];
        pads[0] = Some(pad(Some(2)));
        pads[1] = Some(RetainedPad {
            tier: Tier::Linear,
            ..pad(Some(5))
        });
        RetainedState { pads }
    }

    fn pad(channel: Option<u8>) -> RetainedPad {
        RetainedPad {
            channel,
            baselines: [
                Some(BaselineRecord {
                    capacitance: SplitCapacitance {
                        offset_pf: 3.125,
                        fine_pf: 2.5625,
                    },
                    temperature_c: 27.5,
                    tracked_drift_pf: -0.003,
                }),
                None,
                Some(BaselineRecord {
                    capacitance: SplitCapacitance {
                        offset_pf: 0.0,
                        fine_pf: 5.7,
                    },
                    temperature_c: 31.0,
                    tracked_drift_pf: 0.0,
                }),
                None,
            ],
            tier: Tier::Polynomial,
        }
    }

    #[test]
    fn a_record_round_trips() {
        assert_eq!(RetainedState::decode(&state().encode()), Some(state()));
    }

    #[test]
    fn the_largest_record_fits() {
        let mut full_pad = pad(Some(7));
        full_pad.baselines = [full_pad.baselines[0]; TAXEL_COUNT];
        full_pad.baselines[3] = Some(BaselineRecord {
            capacitance: SplitCapacitance {
                offset_pf: f32::MAX,
                fine_pf: f32::MIN,
            },
            temperature_c: f32::NAN,
            tracked_drift_pf: f32::INFINITY,
        });
        full_pad.tier = Tier::ALL[Tier::ALL.len() - 1];
        let full = RetainedState {
            pads: [Some(full_pad); MAX_PADS],
        };
        let bytes = full.encode();
        assert_ne!(bytes, [0u8; RETAINED_LEN], "the record did not fit");
        let decoded = RetainedState::decode(&bytes);
        // NaN != NaN, so compare the bits of the odd one.
        let bits = |state: &RetainedState| {
            state.pads.map(|pad| {
                pad.map(|pad| {
                    (
                        pad.channel,
                        pad.tier,
                        pad.baselines.map(|record| {
                            record.map(|record| {
                                [
                                    record.capacitance.offset_pf.to_bits(),
                                    record.capacitance.fine_pf.to_bits(),
                                    record.temperature_c.to_bits(),
                                    record.tracked_drift_pf.to_bits(),
                                ]
                            })
                        }),
                    )
                })
            })
        };
        assert_eq!(decoded.as_ref().map(bits), Some(bits(&full)));
    }

    #[test]
    fn a_pad_gets_back_the_state_of_the_pad_that_was_on_its_channel() {
        let plan = boot_plan(ResetKind::McuOnly, Some(state()), 16);
        let calibration = model_core::Calibration::default();
        let mut on_five = PadModel::new(calibration.clone());
        assert_eq!(plan.apply_to(Some(5), &mut on_five), 0b0101);
        assert_eq!(on_five.tier(), Tier::Linear);
        assert_eq!(on_five.baseline_records(), pad(None).baselines);
        let mut elsewhere = PadModel::new(calibration);
        assert_eq!(plan.apply_to(Some(3), &mut elsewhere), 0);
        assert_eq!(elsewhere.baseline_records(), [None; TAXEL_COUNT]);
    }

    #[test]
    fn any_single_bit_flip_or_noise_is_refused() {
        let bytes = state().encode();
        for bit in 0..RETAINED_LEN * 8 {
            let mut flipped = bytes;
            flipped[bit / 8] ^= 1 << (bit % 8);
            assert_eq!(RetainedState::decode(&flipped), None, "bit {bit}");
        }
        assert_eq!(RetainedState::decode(&[0u8; RETAINED_LEN]), None);
        assert_eq!(RetainedState::decode(&[0xA5u8; RETAINED_LEN]), None);
    }

    #[test]
    fn only_a_power_on_tares_by_itself() {
        let cold = boot_plan(ResetKind::PowerOn, Some(state()), 16);
        assert_eq!((cold.restore, cold.tare_sets_at_start), (None, 16));
        let warm = boot_plan(ResetKind::McuOnly, Some(state()), 16);
        assert_eq!((warm.restore, warm.tare_sets_at_start), (Some(state()), 0));
        let warm_lost = boot_plan(ResetKind::McuOnly, None, 16);
        assert_eq!((warm_lost.restore, warm_lost.tare_sets_at_start), (None, 0));
    }
}
