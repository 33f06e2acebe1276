//! State kept across an MCU-only reset (watchdog, software reset, reset pin) in RAM that the
//! start-up code does not clear, and what a boot does with it.
//!
//! A pad may be loaded when the MCU resets (a gripper holding an object): taring then would turn
//! the held load into a zero that looks like good data. So only a power-on tares by itself (the
//! pad is taken to be unloaded at power-up, as documented); after an MCU-only reset the baselines
//! from before the reset are restored when their record is intact, and otherwise every taxel
//! stays `not_tared` (a fault) until the host sends a tare.
//!
//! Record: magic "TXRS", format version, per taxel a presence byte and the tared capacitance
//! (CAPDAC part, code part, pF) and tare temperature (°C) as f32 LE, the tier id, and a
//! CRC-32/ISO-HDLC of everything before it, LE.

use crc::{Crc, CRC_32_ISO_HDLC};
use model_core::{BaselineRecord, PadModel, SplitCapacitance, Tier, TAXEL_COUNT};

/// Bytes of the record.
pub const RETAINED_LEN: usize = 4 + 1 + TAXEL_COUNT * 13 + 1 + 4;

const MAGIC: [u8; 4] = *b"TXRS";
const FORMAT_VERSION: u8 = 1;
const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// What survives an MCU-only reset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetainedState {
    /// Per taxel, the baseline in force before the reset.
    pub baselines: [Option<BaselineRecord>; TAXEL_COUNT],
    /// The tier in force before the reset.
    pub tier: Tier,
}

impl RetainedState {
    /// The record's bytes.
    pub fn encode(&self) -> [u8; RETAINED_LEN] {
        let mut bytes = [0u8; RETAINED_LEN];
        bytes[..4].copy_from_slice(&MAGIC);
        bytes[4] = FORMAT_VERSION;
        for (taxel, baseline) in self.baselines.iter().enumerate() {
            let start = 5 + taxel * 13;
            let slot = &mut bytes[start..start + 13];
            if let Some(record) = baseline {
                slot[0] = 1;
                slot[1..5].copy_from_slice(&record.capacitance.offset_pf.to_le_bytes());
                slot[5..9].copy_from_slice(&record.capacitance.fine_pf.to_le_bytes());
                slot[9..13].copy_from_slice(&record.temperature_c.to_le_bytes());
            }
        }
        let tier_at = 5 + TAXEL_COUNT * 13;
        bytes[tier_at] = self.tier as u8;
        let checksum = CRC.checksum(&bytes[..tier_at + 1]);
        bytes[tier_at + 1..].copy_from_slice(&checksum.to_le_bytes());
        bytes
    }

    /// The state in a record, or `None` when the bytes are not an intact record (RAM after a
    /// power-on holds noise; a torn write fails the CRC).
    pub fn decode(bytes: &[u8; RETAINED_LEN]) -> Option<Self> {
        let tier_at = 5 + TAXEL_COUNT * 13;
        let stored = u32::from_le_bytes([
            bytes[tier_at + 1],
            bytes[tier_at + 2],
            bytes[tier_at + 3],
            bytes[tier_at + 4],
        ]);
        if bytes[..4] != MAGIC
            || bytes[4] != FORMAT_VERSION
            || CRC.checksum(&bytes[..tier_at + 1]) != stored
        {
            return None;
        }
        let float = |at: usize| {
            f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        let mut baselines = [None; TAXEL_COUNT];
        for (taxel, baseline) in baselines.iter_mut().enumerate() {
            let start = 5 + taxel * 13;
            match bytes[start] {
                0 => {}
                1 => {
                    *baseline = Some(BaselineRecord {
                        capacitance: SplitCapacitance {
                            offset_pf: float(start + 1),
                            fine_pf: float(start + 5),
                        },
                        temperature_c: float(start + 9),
                    });
                }
                _ => return None,
            }
        }
        Some(Self {
            baselines,
            tier: Tier::from_id(bytes[tier_at])?,
        })
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
    /// Restores the retained baselines and tier into a model built from the boot's calibration;
    /// returns the taxels restored (bit n = taxel n). The tare at start is the caller's to pass
    /// to the acquisition loop.
    pub fn apply_to(&self, pad: &mut PadModel) -> u8 {
        let Some(state) = self.restore else {
            return 0;
        };
        let _ = pad.set_tier(state.tier);
        pad.restore_baselines(&state.baselines)
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

    fn state() -> RetainedState {
        RetainedState {
            baselines: [
                Some(BaselineRecord {
                    capacitance: SplitCapacitance {
                        offset_pf: 3.125,
                        fine_pf: 2.5625,
                    },
                    temperature_c: 27.5,
                }),
                None,
                Some(BaselineRecord {
                    capacitance: SplitCapacitance {
                        offset_pf: 0.0,
                        fine_pf: 5.7,
                    },
                    temperature_c: 31.0,
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
