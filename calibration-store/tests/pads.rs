//! One calibration per pad: every pad loads the newest record that is for it (its own, or one for
//! every pad), checked against a reference that is only the list of saves; moves carry every
//! record another pad still loads; a page too small for the records in use refuses the save and
//! loses nothing. (Power loss during a pad's save: power_loss.rs.)

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::PadRecord;
use calibration_store::{LoadOutcome, RamFlash, RecordScope, StoreError, Tear, MAX_PADS};
use common::{
    block_on, config, load_every_pad, mixed_spec, small_flash, small_store, spec, store_of, History,
};
use proptest::prelude::*;

/// Pages that hold twelve of the longest records: moves happen every few saves.
const PAGE: usize = 8192;
type PadFlash = RamFlash<{ 3 * PAGE }, PAGE>;

fn save(flash: &mut PadFlash, scope: RecordScope, spec: &PadRecord) {
    block_on(store_of(flash).save_for(scope, spec)).unwrap();
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
        let mut saves = History::default();
        for (index, scope) in scopes.into_iter().enumerate() {
            let spec = mixed_spec(index as u32 + 1);
            save(&mut flash, scope, &spec);
            saves = saves.with(scope, &spec);
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

/// Every pad has its own record, newer than the one for every pad: a move still carries the
/// one for every pad, which a pad index beyond the last loads.
#[test]
fn a_move_keeps_the_record_for_every_pad_under_newer_own_records() {
    let mut flash = Box::new(PadFlash::new());
    let mut saves = History::default();
    let scopes = core::iter::once(RecordScope::EveryPad)
        .chain((0..4).flat_map(|_| (0..MAX_PADS).map(RecordScope::Pad)));
    for (id, scope) in (1..).zip(scopes) {
        let spec = common::worst_case_spec(id);
        save(&mut flash, scope, &spec);
        saves = saves.with(scope, &spec);
    }
    assert!(flash.erase_count() >= 2, "no move happened");
    let outcomes = load_every_pad(&mut flash);
    assert_eq!(outcomes, saves.outcomes());
    assert_eq!(outcomes[8], LoadOutcome::Stored(common::worst_case_spec(1)));
}

#[test]
fn a_pad_index_beyond_the_last_is_refused_and_nothing_is_written() {
    let mut flash = Box::new(PadFlash::new());
    save(&mut flash, RecordScope::EveryPad, &spec(1));
    let before = flash.snapshot();
    assert_eq!(
        block_on(store_of(&mut *flash).save_for(RecordScope::Pad(MAX_PADS), &spec(2))),
        Err(StoreError::PadOutOfRange { pad: MAX_PADS })
    );
    assert!(flash.snapshot() == before);
}

/// Two of the longest records fit a 2 KiB page (three on the F411's 128 KiB pages would be
/// hundreds): two pads' records and a third pad's save cannot be moved together. The save is
/// refused before anything is written and every pad keeps its calibration; a save for every pad,
/// which leaves nothing to carry, then works.
#[test]
fn records_that_do_not_fit_a_page_refuse_the_save_and_lose_nothing() {
    let mut flash = small_flash();
    let long = common::worst_case_spec;
    for pad in 0..2 {
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(pad), &long(u32::from(pad))))
            .unwrap();
    }
    let snapshot = flash.snapshot();
    assert_eq!(
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(2), &long(2))),
        Err(StoreError::Full)
    );
    assert!(flash.snapshot() == snapshot);
    let outcomes = load_every_pad(&mut flash);
    for (pad, outcome) in outcomes.iter().enumerate().take(2) {
        assert_eq!(*outcome, LoadOutcome::Stored(long(pad as u32)));
    }
    assert_eq!(outcomes[2], LoadOutcome::Absent);
    block_on(small_store(&mut flash).save(&long(9))).unwrap();
    assert!(load_every_pad(&mut flash)
        .iter()
        .all(|outcome| *outcome == LoadOutcome::Stored(long(9))));
}

/// Page 0: pad 0's and pad 1's records and a torn record (so the next save moves); a save for
/// pad 0 is torn at every operation, then a save for pad 2 goes over whatever it left: pad 0
/// keeps what the reboot loaded, pad 1 its record.
#[test]
fn a_torn_move_then_another_pads_save_keeps_every_record() {
    let mut base = Box::new(PadFlash::new());
    save(&mut base, RecordScope::Pad(0), &spec(10));
    save(&mut base, RecordScope::Pad(1), &spec(11));
    base.schedule_power_loss(0, Tear::words(3));
    assert!(block_on(store_of(&mut *base).save_for(RecordScope::Pad(3), &spec(99))).is_err());
    base.power_cycle();
    let mut torn = 0;
    for operations in 0.. {
        let mut flash = Box::new((*base).clone());
        flash.schedule_power_loss(operations, Tear::NOTHING);
        if block_on(store_of(&mut *flash).save_for(RecordScope::Pad(0), &spec(12))).is_ok() {
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
    assert!(torn >= 5, "{torn}");
}
