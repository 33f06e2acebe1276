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
pub const RETAINED_LEN: usize = CRC_AT + 4;

const MAGIC: [u8; 4] = *b"TXRS";
const FORMAT_VERSION: u8 = 1;
const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

// Where each part of the record starts. The record is an array of constant length, so every
// index below is a constant the compiler checks against it.
const VERSION_AT: usize = MAGIC.len();
const SLOTS_AT: usize = VERSION_AT + 1;
/// Bytes of one taxel's slot: presence, offset pF, fine pF, temperature °C.
const SLOT_LEN: usize = 13;
const TIER_AT: usize = SLOTS_AT + TAXEL_COUNT * SLOT_LEN;
const CRC_AT: usize = TIER_AT + 1;

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
        bytes[..VERSION_AT].copy_from_slice(&MAGIC);
        bytes[VERSION_AT] = FORMAT_VERSION;
        let (slots, _) = bytes[SLOTS_AT..TIER_AT].as_chunks_mut::<SLOT_LEN>();
        for (slot, baseline) in slots.iter_mut().zip(&self.baselines) {
            if let Some(record) = baseline {
                *slot = encode_slot(record);
            }
        }
        bytes[TIER_AT] = self.tier as u8;
        let checksum = CRC.checksum(&bytes[..CRC_AT]);
        bytes[CRC_AT..].copy_from_slice(&checksum.to_le_bytes());
        bytes
    }

    /// The state in a record, or `None` when the bytes are not an intact record (RAM after a
    /// power-on holds noise; a torn write fails the CRC).
    pub fn decode(bytes: &[u8; RETAINED_LEN]) -> Option<Self> {
        let stored = u32::from_le_bytes([
            bytes[CRC_AT],
            bytes[CRC_AT + 1],
            bytes[CRC_AT + 2],
            bytes[CRC_AT + 3],
        ]);
        if bytes[..VERSION_AT] != MAGIC
            || bytes[VERSION_AT] != FORMAT_VERSION
            || CRC.checksum(&bytes[..CRC_AT]) != stored
        {
            return None;
        }
        let mut baselines = [None; TAXEL_COUNT];
        let (slots, _) = bytes[SLOTS_AT..TIER_AT].as_chunks::<SLOT_LEN>();
        for (baseline, slot) in baselines.iter_mut().zip(slots) {
            *baseline = decode_slot(slot)?;
        }
        Some(Self {
            baselines,
            tier: Tier::from_id(bytes[TIER_AT])?,
        })
    }
}

/// One taxel's slot holding `record`: presence 1, then the three values as f32 LE.
fn encode_slot(record: &BaselineRecord) -> [u8; SLOT_LEN] {
    let [o0, o1, o2, o3] = record.capacitance.offset_pf.to_le_bytes();
    let [f0, f1, f2, f3] = record.capacitance.fine_pf.to_le_bytes();
    let [t0, t1, t2, t3] = record.temperature_c.to_le_bytes();
    [1, o0, o1, o2, o3, f0, f1, f2, f3, t0, t1, t2, t3]
}

/// The baseline in a slot (`Some(None)` for an empty one), `None` for a bad presence byte.
fn decode_slot(slot: &[u8; SLOT_LEN]) -> Option<Option<BaselineRecord>> {
    let [present, o0, o1, o2, o3, f0, f1, f2, f3, t0, t1, t2, t3] = *slot;
    match present {
        0 => Some(None),
        1 => Some(Some(BaselineRecord {
            capacitance: SplitCapacitance {
                offset_pf: f32::from_le_bytes([o0, o1, o2, o3]),
                fine_pf: f32::from_le_bytes([f0, f1, f2, f3]),
            },
            temperature_c: f32::from_le_bytes([t0, t1, t2, t3]),
        })),
        _ => None,
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
