//! One calibration per pad: every pad loads the newest record that is for it (its own, or one for
//! every pad), checked against a reference that is only the list of saves; moves carry every
//! record another pad still loads; a power loss at every operation of a pad's save leaves every
//! other pad exactly as it was and the saved pad with its old or its new calibration; a page
//! too small for the records in use refuses the save and loses nothing; a record a later
//! firmware wrote is never passed over for an older one.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use core::ops::Range;

use calibration_store::{
    encode_scoped_record, CalibrationKey, CalibrationStore, CorruptReason, LoadOutcome, RamFlash,
    RamFlashError, RecordError, RecordScope, StoreError, Tear, CALIBRATION_KEY, MAX_PADS,
    MAX_RECORD_LEN,
};
use common::{block_on, config, describe, mixed_spec, small_flash, small_store, spec};
use model_core::calibration::CalibrationSpec;
use proptest::prelude::*;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};

/// Pages that hold twelve of the longest records: moves happen every few saves.
const PAGE: usize = 8192;
type PadFlash = RamFlash<{ 3 * PAGE }, PAGE>;
const RANGE: Range<u32> = PAGE as u32..3 * PAGE as u32;

fn store(flash: &mut PadFlash) -> CalibrationStore<&mut PadFlash> {
    CalibrationStore::new(flash, RANGE).unwrap()
}

fn save(flash: &mut PadFlash, scope: RecordScope, spec: &CalibrationSpec) {
    block_on(store(flash).save_for(scope, spec)).unwrap();
}

/// What every pad (and an index past the last, which only records for every pad cover) loads
/// after a reboot.
fn load_every_pad(flash: &mut PadFlash) -> Vec<LoadOutcome<RamFlashError>> {
    flash.power_cycle();
    (0..=MAX_PADS)
        .map(|pad| block_on(store(flash).load(pad)))
        .collect()
}

/// The reference: the saves in order. A pad loads the last one that covers it.
#[derive(Debug, Clone, Default)]
struct Saves(Vec<(RecordScope, CalibrationSpec)>);

impl Saves {
    fn expected(&self, pad: u8) -> Option<&CalibrationSpec> {
        self.0.iter().rev().find_map(|(scope, spec)| {
            let covers = match scope {
                RecordScope::EveryPad => true,
                RecordScope::Pad(own) => *own == pad,
            };
            covers.then_some(spec)
        })
    }

    fn outcomes(&self) -> Vec<LoadOutcome<RamFlashError>> {
        (0..=MAX_PADS)
            .map(|pad| match self.expected(pad) {
                Some(spec) => LoadOutcome::Stored(spec.clone()),
                None => LoadOutcome::Absent,
            })
            .collect()
    }
}

fn scope_strategy() -> impl Strategy<Value = RecordScope> {
    prop_oneof![
        1 => Just(RecordScope::EveryPad),
        4 => (0..MAX_PADS).prop_map(RecordScope::Pad),
    ]
}

proptest! {
    #![proptest_config(config(48))]

    /// Any sequence of saves, for one pad or for every pad, short and long records: after each,
    /// every pad loads what the list of saves says, across several moves.
    #[test]
    fn every_pad_loads_the_last_save_that_covers_it(
        scopes in proptest::collection::vec(scope_strategy(), 1..40)
    ) {
        let mut flash = Box::new(PadFlash::new());
        let mut saves = Saves::default();
        for (index, scope) in scopes.into_iter().enumerate() {
            let spec = mixed_spec(index as u32 + 1);
            save(&mut flash, scope, &spec);
            saves.0.push((scope, spec));
            prop_assert_eq!(load_every_pad(&mut flash), saves.outcomes(), "after save {}", index);
        }
    }
}

#[test]
fn a_record_for_every_pad_replaces_the_pads_own_records() {
    let mut flash = Box::new(PadFlash::new());
    save(&mut flash, RecordScope::EveryPad, &spec(1));
    save(&mut flash, RecordScope::Pad(2), &spec(2));
    save(&mut flash, RecordScope::Pad(7), &spec(3));
    let outcomes = load_every_pad(&mut flash);
    assert_eq!(outcomes[0], LoadOutcome::Stored(spec(1)));
    assert_eq!(outcomes[2], LoadOutcome::Stored(spec(2)));
    assert_eq!(outcomes[7], LoadOutcome::Stored(spec(3)));
    assert_eq!(outcomes[8], LoadOutcome::Stored(spec(1)));
    save(&mut flash, RecordScope::EveryPad, &spec(4));
    assert!(load_every_pad(&mut flash)
        .iter()
        .all(|outcome| *outcome == LoadOutcome::Stored(spec(4))));
}

#[test]
fn a_pad_index_beyond_the_last_is_refused_and_nothing_is_written() {
    let mut flash = Box::new(PadFlash::new());
    save(&mut flash, RecordScope::EveryPad, &spec(1));
    let before = flash.snapshot();
    assert_eq!(
        block_on(store(&mut flash).save_for(RecordScope::Pad(MAX_PADS), &spec(2))),
        Err(StoreError::Record(RecordError::PadOutOfRange {
            pad: MAX_PADS
        }))
    );
    assert!(flash.snapshot() == before);
}

/// Three 2 KiB-page items fit in a page: three pads' records and a fourth pad's save cannot be
/// moved together. The save is refused and every pad keeps its calibration; a save for every
/// pad, which leaves nothing to carry, then works.
#[test]
fn records_that_do_not_fit_a_page_refuse_the_save_and_lose_nothing() {
    let mut flash = small_flash();
    let long = |id| common::worst_case_spec(id);
    for pad in 0..3 {
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(pad), &long(u32::from(pad))))
            .unwrap();
    }
    assert_eq!(
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(3), &long(3))),
        Err(StoreError::Full)
    );
    flash.power_cycle();
    for pad in 0..3 {
        assert_eq!(
            block_on(small_store(&mut flash).load(pad)),
            LoadOutcome::Stored(long(u32::from(pad)))
        );
    }
    assert_eq!(
        block_on(small_store(&mut flash).load(3)),
        LoadOutcome::Absent
    );
    block_on(small_store(&mut flash).save(&long(9))).unwrap();
    flash.power_cycle();
    for pad in 0..MAX_PADS {
        assert_eq!(
            block_on(small_store(&mut flash).load(pad)),
            LoadOutcome::Stored(long(9))
        );
    }
}

/// Writes `record` as an item after the last one, the way any writer of the format would.
fn store_raw_item(flash: &mut PadFlash, value: &[u8]) {
    let mut map = MapStorage::<CalibrationKey, _, _>::new(
        flash,
        MapConfig::new(RANGE),
        Cache::new_uncached(),
    );
    let mut buffer = [0u8; 1024];
    block_on(map.store_item(&mut buffer, &CALIBRATION_KEY, &value)).unwrap();
}

/// A pad's record of a format this firmware does not read (version 5), before pad 1's record:
/// it may be any pad's newest, so every pad whose record is older loads Corrupt; pad 1's newer
/// record and later saves are unaffected, a save for one pad never drops it, and a save for
/// every pad replaces it.
#[test]
fn a_record_this_firmware_refuses_flags_every_pad_whose_record_may_be_older() {
    let mut flash = Box::new(PadFlash::new());
    save(&mut flash, RecordScope::EveryPad, &spec(1));
    let mut unknown = [0u8; MAX_RECORD_LEN];
    let length = encode_scoped_record(RecordScope::Pad(4), &spec(2), 7, &mut unknown).unwrap();
    let mut unknown = unknown[..length].to_vec();
    unknown[0] = 5;
    let crc_at = unknown.len() - 4;
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&unknown[..crc_at]);
    unknown[crc_at..].copy_from_slice(&crc.to_le_bytes());
    store_raw_item(&mut flash, &unknown);
    save(&mut flash, RecordScope::Pad(1), &spec(3));
    let refused = LoadOutcome::Corrupt(CorruptReason::Record(RecordError::UnsupportedVersion {
        found: 5,
    }));
    let outcomes = load_every_pad(&mut flash);
    for (pad, outcome) in outcomes.iter().enumerate() {
        let expected = if pad == 1 {
            &LoadOutcome::Stored(spec(3))
        } else {
            &refused
        };
        assert_eq!(outcome, expected, "pad {pad}");
    }
    // Saves for one pad append while they fit; the move that would drop the unreadable record
    // (and with it the other pads' flag) is refused, with nothing written.
    let mut saved = 0;
    let refusal = loop {
        match block_on(store(&mut flash).save_for(RecordScope::Pad(2), &mixed_spec(100 + saved))) {
            Ok(()) => saved += 1,
            Err(error) => break error,
        }
        assert!(saved < 30, "no move in 30 saves");
    };
    assert_eq!(refusal, StoreError::Unreadable);
    let outcomes = load_every_pad(&mut flash);
    assert_eq!(
        outcomes[2],
        LoadOutcome::Stored(mixed_spec(100 + saved - 1))
    );
    assert_eq!(outcomes[1], LoadOutcome::Stored(spec(3)));
    for pad in [0, 3, 4, 5, 6, 7, 8] {
        assert_eq!(outcomes[pad], refused, "pad {pad} after the refused move");
    }
    // A save for every pad is newer than anything: it clears the flag.
    save(&mut flash, RecordScope::EveryPad, &spec(4));
    assert!(load_every_pad(&mut flash)
        .iter()
        .all(|outcome| *outcome == LoadOutcome::Stored(spec(4))));
}

/// Pages of 4 KiB: the records of eight pads and one for every pad (short ones) and the longest
/// new record fit, and saves move often.
const TIGHT_PAGE: usize = 4096;
type TightFlash = RamFlash<{ 3 * TIGHT_PAGE }, TIGHT_PAGE>;
const TIGHT_RANGE: Range<u32> = TIGHT_PAGE as u32..3 * TIGHT_PAGE as u32;

fn tight_store(flash: &mut TightFlash) -> CalibrationStore<&mut TightFlash> {
    CalibrationStore::new(flash, TIGHT_RANGE).unwrap()
}

fn tight_save(flash: &mut TightFlash, scope: RecordScope, spec: &CalibrationSpec) {
    block_on(tight_store(flash).save_for(scope, spec)).unwrap();
}

fn tight_load_every_pad(flash: &mut TightFlash) -> Vec<LoadOutcome<RamFlashError>> {
    flash.power_cycle();
    (0..=MAX_PADS)
        .map(|pad| block_on(tight_store(flash).load(pad)))
        .collect()
}

/// A history of saves (short records) for several pads and for every pad, so that the save
/// under test is appended at several positions and moves often.
fn history(length: u32) -> (Box<TightFlash>, Saves) {
    let mut flash = Box::new(TightFlash::new());
    let mut saves = Saves::default();
    for index in 0..length {
        let scope = match index % 5 {
            0 => RecordScope::EveryPad,
            other => RecordScope::Pad((index * 3 + other) as u8 % MAX_PADS),
        };
        let spec = spec(index + 1);
        tight_save(&mut flash, scope, &spec);
        saves.0.push((scope, spec));
    }
    (flash, saves)
}

/// Power loss at every write and erase of a save for one pad, torn at the first, second, middle
/// and last word and half-programmed: after the reboot, every other pad loads exactly what it
/// loaded before (a move carries its record); the saved pad loads its old or its new
/// calibration (or the defaults flagged when it had none and the torn bytes are all there is);
/// the next save works.
#[test]
fn power_loss_during_a_pads_save_leaves_the_other_pads_untouched() {
    let mut torn = 0;
    let mut moves = 0;
    let mut max_operations = 0;
    for history_length in 0..120 {
        let (base, saves) = history(history_length);
        let pad = (history_length % u32::from(MAX_PADS)) as u8;
        let new = mixed_spec(500 + history_length);
        // Every save under test that moves, and some that append.
        let mut probe = Box::new((*base).clone());
        let erases = probe.erase_count();
        tight_save(&mut probe, RecordScope::Pad(pad), &new);
        if probe.erase_count() == erases && history_length % 15 != 0 {
            continue;
        }
        let before = saves.outcomes();
        let mut operations = 0;
        loop {
            let mut probe = Box::new((*base).clone());
            probe.schedule_power_loss(operations, Tear::NOTHING);
            if block_on(tight_store(&mut probe).save_for(RecordScope::Pad(pad), &new)).is_ok() {
                break;
            }
            let report = probe.last_power_loss().unwrap();
            if report.kind == calibration_store::OperationKind::Erase {
                moves += 1;
            }
            max_operations = max_operations.max(operations + 1);
            let words = report.words.max(1);
            let mut tears = vec![];
            for whole_words in [0, 1, words / 2, words - 1] {
                for partial_word_mask in [0, 0x0000_000F, 0xFFFF_FFFE] {
                    tears.push(Tear {
                        whole_words: whole_words.min(words - 1),
                        partial_word_mask,
                    });
                }
            }
            for tear in tears {
                let mut flash = Box::new((*base).clone());
                flash.schedule_power_loss(operations, tear);
                assert!(
                    block_on(tight_store(&mut flash).save_for(RecordScope::Pad(pad), &new))
                        .is_err()
                );
                torn += 1;
                let context = format!(
                    "history {history_length}, pad {pad}, operation {operations} ({:?}), {tear:?}",
                    report.kind
                );
                let after = tight_load_every_pad(&mut flash);
                for (other, outcome) in after.iter().enumerate() {
                    if other == usize::from(pad) {
                        let acceptable = *outcome == before[other]
                            || *outcome == LoadOutcome::Stored(new.clone())
                            || (before[other] == LoadOutcome::Absent && outcome.is_corrupt());
                        assert!(
                            acceptable,
                            "{context}: the saved pad loaded {}",
                            describe(outcome)
                        );
                    } else if before[other] == LoadOutcome::Absent {
                        // Nothing saved for it: the torn bytes may be all the region holds.
                        assert!(
                            *outcome == LoadOutcome::Absent || outcome.is_corrupt(),
                            "{context}: pad {other} loaded {}",
                            describe(outcome)
                        );
                    } else {
                        assert_eq!(*outcome, before[other], "{context}: pad {other}");
                    }
                }
                // The next save is for another pad: the torn save's pad keeps what it loaded
                // (a wrong choice of the current page would lose it here).
                let other_pad = (pad + 1) % MAX_PADS;
                let next = spec(9000 + history_length);
                block_on(tight_store(&mut flash).save_for(RecordScope::Pad(other_pad), &next))
                    .unwrap_or_else(|error| panic!("{context}: next save failed: {error:?}"));
                let healed = tight_load_every_pad(&mut flash);
                for (index, outcome) in healed.iter().enumerate() {
                    if index == usize::from(other_pad) {
                        assert_eq!(*outcome, LoadOutcome::Stored(next.clone()), "{context}");
                    } else if after[index].is_corrupt() && before[index] == LoadOutcome::Absent {
                        assert!(
                            *outcome == LoadOutcome::Absent || outcome.is_corrupt(),
                            "{context}: after the next save, pad {index}: {}",
                            describe(outcome)
                        );
                    } else {
                        assert_eq!(
                            *outcome, after[index],
                            "{context}: after the next save, pad {index}"
                        );
                    }
                }
            }
            operations += 1;
        }
    }
    println!(
        "{torn} torn saves of one pad ({moves} saves under test moved, up to {max_operations} \
         writes and erases in one save)"
    );
    assert!(moves >= 5, "only {moves} saves under test moved");
}

/// Writes `spec` for `scope` with `save_counter` as a raw item, in `version` if given (a format
/// this firmware does not read).
fn raw_record(
    flash: &mut PadFlash,
    scope: RecordScope,
    spec: &CalibrationSpec,
    save_counter: u32,
    version: Option<u8>,
) {
    let mut bytes = [0u8; MAX_RECORD_LEN];
    let length = encode_scoped_record(scope, spec, save_counter, &mut bytes).unwrap();
    let mut bytes = bytes[..length].to_vec();
    if let Some(version) = version {
        bytes[0] = version;
        let crc_at = bytes.len() - 4;
        let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&bytes[..crc_at]);
        bytes[crc_at..].copy_from_slice(&crc.to_le_bytes());
    }
    store_raw_item(flash, &bytes);
}

/// The other page, not erased (what a torn erase leaves): the next save must move.
fn dirty_other_page(flash: &mut PadFlash) {
    flash.as_bytes_mut()[2 * PAGE + 4000] = 0x00;
}

/// A save for one pad over records of a later firmware that may be newer than other pads' (or
/// over nothing else): refused, nothing written, the flags kept; a save for every pad works.
#[test]
fn a_pads_save_never_drops_an_unreadable_record_another_pad_may_load() {
    for pad_first in [false, true] {
        let mut flash = Box::new(PadFlash::new());
        if pad_first {
            raw_record(&mut flash, RecordScope::Pad(1), &spec(1), 1, None);
        }
        raw_record(&mut flash, RecordScope::Pad(4), &spec(50), 7, Some(5));
        dirty_other_page(&mut flash);
        let before = load_every_pad(&mut flash);
        assert!(before[0].is_corrupt());
        let snapshot = flash.snapshot();
        assert_eq!(
            block_on(store(&mut flash).save_for(RecordScope::Pad(2), &spec(2))),
            Err(StoreError::Unreadable)
        );
        assert!(flash.snapshot() == snapshot, "the refused save wrote");
        save(&mut flash, RecordScope::EveryPad, &spec(3));
        assert!(load_every_pad(&mut flash)
            .iter()
            .all(|outcome| *outcome == LoadOutcome::Stored(spec(3))));
    }
}

/// An intact item longer than any record (a later firmware's) after pad 0's record: a save for
/// one pad that must move is refused; a save for every pad replaces it.
#[test]
fn an_item_longer_than_any_record_is_never_copied_and_a_save_for_every_pad_replaces_it() {
    let mut flash = Box::new(PadFlash::new());
    save(&mut flash, RecordScope::Pad(0), &spec(1));
    let mut long = vec![0x5Au8; 800];
    long[0] = 6;
    store_raw_item(&mut flash, &long);
    dirty_other_page(&mut flash);
    assert!(load_every_pad(&mut flash)[0].is_corrupt());
    assert_eq!(
        block_on(store(&mut flash).save_for(RecordScope::Pad(1), &spec(2))),
        Err(StoreError::Unreadable)
    );
    save(&mut flash, RecordScope::EveryPad, &spec(4));
    assert!(load_every_pad(&mut flash)
        .iter()
        .all(|outcome| *outcome == LoadOutcome::Stored(spec(4))));
}

/// Page 0: pad 0's and pad 1's records; a save for pad 0 that moves is torn after pad 1's copy
/// (both pages then end on the same save counter). A later save for pad 2 keeps pad 0's record:
/// the page copied from stays the current one.
#[test]
fn a_move_torn_after_its_last_copy_then_another_pads_save_keeps_every_record() {
    let mut base = Box::new(PadFlash::new());
    save(&mut base, RecordScope::Pad(0), &spec(10));
    save(&mut base, RecordScope::Pad(1), &spec(11));
    dirty_other_page(&mut base);
    let mut torn = 0;
    for operations in 0..12 {
        let mut flash = Box::new((*base).clone());
        flash.schedule_power_loss(operations, Tear::NOTHING);
        if block_on(store(&mut flash).save_for(RecordScope::Pad(0), &spec(12))).is_ok() {
            break;
        }
        torn += 1;
        let pad_0 = load_every_pad(&mut flash)[0].clone();
        assert!(pad_0 == LoadOutcome::Stored(spec(10)) || pad_0 == LoadOutcome::Stored(spec(12)));
        save(&mut flash, RecordScope::Pad(2), &spec(13));
        let after = load_every_pad(&mut flash);
        assert_eq!(after[0], pad_0, "operation {operations}");
        assert_eq!(
            after[1],
            LoadOutcome::Stored(spec(11)),
            "operation {operations}"
        );
        assert_eq!(
            after[2],
            LoadOutcome::Stored(spec(13)),
            "operation {operations}"
        );
    }
    assert!(torn >= 4, "{torn}");
}

/// Full is found before anything is erased or written.
#[test]
fn full_is_refused_before_anything_is_written() {
    let mut flash = small_flash();
    let long = common::worst_case_spec;
    for pad in 0..3 {
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(pad), &long(u32::from(pad))))
            .unwrap();
    }
    let snapshot = flash.snapshot();
    assert_eq!(
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(3), &long(3))),
        Err(StoreError::Full)
    );
    assert!(flash.snapshot() == snapshot);
}
