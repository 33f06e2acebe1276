//! The on-flash format, checked against its documentation re-declared in `common::layout`: the
//! bytes the store writes (first save, append, move), and what it reads from pages written by
//! hand (the current page, incomplete and damaged pages, damaged lengths, pads this firmware
//! does not hold, later format and body versions, bodies longer than this firmware reads).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{
    CorruptReason, LoadOutcome, RecordError, RecordScope, StoreError, MAX_BODY_LEN, MAX_PADS,
    MAX_RECORD_LEN, STORE_FORMAT_VERSION,
};
use common::layout::{self, EVERY_PAD, RECORDS_AT};
use common::{
    block_on, load_every_pad, small_flash, small_store, spec, SmallFlash, OUTSIDE_RANGE, SMALL_PAGE,
};

/// Page `page` (0 or 1) of the store's range.
fn page(flash: &SmallFlash, page: usize) -> &[u8] {
    let start = SMALL_PAGE * (1 + page);
    &flash.as_bytes()[start..start + SMALL_PAGE]
}

fn page_mut(flash: &mut SmallFlash, page: usize) -> &mut [u8] {
    let start = SMALL_PAGE * (1 + page);
    &mut flash.as_bytes_mut()[start..start + SMALL_PAGE]
}

fn erased(bytes: &[u8]) -> bool {
    bytes.iter().all(|&byte| byte == 0xFF)
}

/// A complete page of this format holding `records`, everything after them erased.
fn expected_page(generation: u32, records: &[Vec<u8>]) -> Vec<u8> {
    let mut bytes = vec![0xFF; SMALL_PAGE];
    layout::write_page(&mut bytes, 1, generation, records);
    bytes
}

fn record(spec_id: u32, save_counter: u32, pads: u8) -> Vec<u8> {
    layout::record(&layout::body(&spec(spec_id)), save_counter, pads)
}

#[test]
fn the_constants_match_the_documentation() {
    assert_eq!(STORE_FORMAT_VERSION, 1);
    assert_eq!(MAX_RECORD_LEN, layout::RECORD_HEADER_LEN + MAX_BODY_LEN);
    assert_eq!(MAX_PADS, 8);
}

/// The first save writes page 0: header (generation 0), commit word, the record (save counter
/// 0, every pad). Nothing else in or outside the range.
#[test]
fn the_first_save_writes_a_page_of_generation_0_with_its_record() {
    let mut flash = small_flash();
    block_on(small_store(&mut flash).save(&spec(1))).unwrap();
    assert_eq!(
        page(&flash, 0),
        expected_page(0, &[record(1, 0, EVERY_PAD)]).as_slice()
    );
    assert!(erased(page(&flash, 1)));
    assert!(erased(&flash.as_bytes()[OUTSIDE_RANGE]));
}

/// Saves append with the next save counter; the pads byte is the pad's index.
#[test]
fn saves_append_records_with_the_next_save_counter() {
    let mut flash = small_flash();
    block_on(small_store(&mut flash).save(&spec(1))).unwrap();
    block_on(small_store(&mut flash).save_for(RecordScope::Pad(3), &spec(2))).unwrap();
    block_on(small_store(&mut flash).save_for(RecordScope::Pad(7), &spec(3))).unwrap();
    assert_eq!(
        page(&flash, 0),
        expected_page(
            0,
            &[record(1, 0, EVERY_PAD), record(2, 1, 3), record(3, 2, 7)]
        )
        .as_slice()
    );
}

/// When the page is full, a save moves into page 1 with generation 1: the records pads still
/// load (pads 1, 3 and 6, and the one for every pad; not pad 0's, replaced by the one for every
/// pad, nor pad 5's, replaced by the new one), then the new one; page 0 is erased.
#[test]
fn a_move_writes_the_next_generation_with_the_records_still_loaded_then_the_new_one() {
    let mut flash = small_flash();
    let saves = [
        (RecordScope::Pad(0), 1),
        (RecordScope::Pad(3), 2),
        (RecordScope::EveryPad, 3),
        (RecordScope::Pad(3), 4),
        (RecordScope::Pad(5), 5),
        (RecordScope::Pad(1), 6),
    ];
    let mut records = Vec::new();
    for (counter, (scope, id)) in saves.into_iter().enumerate() {
        block_on(small_store(&mut flash).save_for(scope, &spec(id))).unwrap();
        let pads = match scope {
            RecordScope::EveryPad => EVERY_PAD,
            RecordScope::Pad(pad) => pad,
        };
        records.push(record(id, counter as u32, pads));
    }
    let used: usize = RECORDS_AT + records.iter().map(Vec::len).sum::<usize>();
    assert_eq!(page(&flash, 0), expected_page(0, &records).as_slice());
    assert!(
        used + records[0].len() > SMALL_PAGE,
        "the next save must move"
    );

    block_on(small_store(&mut flash).save_for(RecordScope::Pad(5), &spec(8))).unwrap();
    assert!(erased(page(&flash, 0)));
    // Copies in scope order (pads 0 to 7, then every pad), then the new record.
    let moved = [
        record(6, 5, 1),
        record(4, 3, 3),
        record(3, 2, EVERY_PAD),
        record(8, 6, 5),
    ];
    assert_eq!(page(&flash, 1), expected_page(1, &moved).as_slice());
}

/// Pages written by hand load as the format says: a pad loads its newest record (own or for
/// every pad) of the complete page with the highest generation.
#[test]
fn hand_written_pages_load_from_the_complete_page_of_the_highest_generation() {
    let mut flash = small_flash();
    layout::write_page(
        page_mut(&mut flash, 1),
        1,
        7,
        &[
            record(10, 40, EVERY_PAD),
            record(11, 42, 2),
            record(12, 41, 2),
            record(13, 39, 4),
        ],
    );
    // Older generation: ignored, whatever it holds.
    layout::write_page(page_mut(&mut flash, 0), 1, 6, &[record(20, 99, EVERY_PAD)]);
    let outcomes = load_every_pad(&mut flash);
    for (pad, outcome) in outcomes.iter().enumerate() {
        let expected = if pad == 2 { spec(11) } else { spec(10) };
        assert_eq!(*outcome, LoadOutcome::Stored(expected), "pad {pad}");
    }
    // The next save continues the save counter of the current page and appends there.
    block_on(small_store(&mut flash).save_for(RecordScope::Pad(4), &spec(14))).unwrap();
    let start = layout::free_start(page(&flash, 1));
    assert!(start > RECORDS_AT);
    assert!(page(&flash, 1)
        .windows(record(14, 43, 4).len())
        .any(|window| window == record(14, 43, 4)));
    // The append erased the stale page first.
    assert!(erased(page(&flash, 0)));
}

#[test]
fn an_incomplete_or_damaged_page_is_never_current() {
    for damage in ["no commit word", "torn commit word", "header CRC", "magic"] {
        let mut flash = small_flash();
        layout::write_page(page_mut(&mut flash, 0), 1, 3, &[record(1, 5, EVERY_PAD)]);
        layout::write_page(page_mut(&mut flash, 1), 1, 4, &[record(2, 6, EVERY_PAD)]);
        let second = page_mut(&mut flash, 1);
        match damage {
            "no commit word" => second[16..20].fill(0xFF),
            "torn commit word" => second[18] = 0x01,
            "header CRC" => second[13] ^= 0x10,
            _ => second[0] = b'X',
        }
        assert_eq!(
            load_every_pad(&mut flash)[0],
            LoadOutcome::Stored(spec(1)),
            "{damage}"
        );
    }
    // Of two complete pages of equal generation, page 0.
    let mut flash = small_flash();
    layout::write_page(page_mut(&mut flash, 0), 1, 3, &[record(1, 5, EVERY_PAD)]);
    layout::write_page(page_mut(&mut flash, 1), 1, 3, &[record(2, 6, EVERY_PAD)]);
    assert_eq!(load_every_pad(&mut flash)[0], LoadOutcome::Stored(spec(1)));
    // No complete page, but written bytes: corrupt, not absent.
    let mut flash = small_flash();
    layout::write_page(page_mut(&mut flash, 0), 1, 3, &[record(1, 5, EVERY_PAD)]);
    page_mut(&mut flash, 0)[16] = 0xFF;
    assert_eq!(
        load_every_pad(&mut flash)[0],
        LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
    );
}

/// A record whose length does not match its complement hides where the next one starts: the
/// walk tries every word after it and finds the next record. The pad whose record it may have
/// been, with none intact, is flagged; the next save moves and leaves it behind.
#[test]
fn a_damaged_length_is_stepped_over_word_by_word() {
    let mut flash = small_flash();
    let first = record(1, 0, 1);
    layout::write_page(
        page_mut(&mut flash, 0),
        1,
        0,
        &[first.clone(), record(2, 1, 2)],
    );
    page_mut(&mut flash, 0)[RECORDS_AT + 2] ^= 0x04;
    let outcomes = load_every_pad(&mut flash);
    assert_eq!(outcomes[2], LoadOutcome::Stored(spec(2)));
    assert_eq!(
        outcomes[1],
        LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
    );
    let erases = flash.erase_count();
    block_on(small_store(&mut flash).save_for(RecordScope::Pad(3), &spec(3))).unwrap();
    assert!(erased(page(&flash, 0)));
    assert_eq!(flash.erase_count(), erases + 1);
    let outcomes = load_every_pad(&mut flash);
    assert_eq!(outcomes[1], LoadOutcome::Absent);
    assert_eq!(outcomes[2], LoadOutcome::Stored(spec(2)));
    assert_eq!(outcomes[3], LoadOutcome::Stored(spec(3)));
}

/// A record for pad 9 (a later firmware's, with more pads) is intact: no pad loads it, nothing
/// is flagged, its save counter still counts.
#[test]
fn a_record_for_a_pad_this_firmware_does_not_hold_is_left_alone() {
    let mut flash = small_flash();
    layout::write_page(
        page_mut(&mut flash, 0),
        1,
        0,
        &[record(1, 0, 0), record(9, 8, 9)],
    );
    let outcomes = load_every_pad(&mut flash);
    assert_eq!(outcomes[0], LoadOutcome::Stored(spec(1)));
    assert!(outcomes[1..]
        .iter()
        .all(|outcome| *outcome == LoadOutcome::Absent));
    block_on(small_store(&mut flash).save_for(RecordScope::Pad(1), &spec(2))).unwrap();
    assert!(page(&flash, 0)
        .windows(record(2, 9, 1).len())
        .any(|window| window == record(2, 9, 1)));
}

/// A current page of a later format version: nothing in it can be read, so every pad is
/// flagged; a save for one pad cannot carry the others' records and is refused with nothing
/// written; a save for every pad replaces it. Such a page of an older generation is ignored.
#[test]
fn a_later_format_version_is_flagged_and_only_a_save_for_every_pad_goes_over_it() {
    let mut flash = small_flash();
    layout::write_page(page_mut(&mut flash, 0), 1, 4, &[record(1, 0, EVERY_PAD)]);
    layout::write_page(page_mut(&mut flash, 1), 2, 5, &[]);
    let flagged = LoadOutcome::Corrupt(CorruptReason::UnsupportedFormat { found: 2 });
    assert!(load_every_pad(&mut flash)
        .iter()
        .all(|outcome| *outcome == flagged));
    let before = flash.snapshot();
    assert_eq!(
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(0), &spec(2))),
        Err(StoreError::Unreadable)
    );
    assert!(flash.snapshot() == before);
    block_on(small_store(&mut flash).save(&spec(3))).unwrap();
    assert!(load_every_pad(&mut flash)
        .iter()
        .all(|outcome| *outcome == LoadOutcome::Stored(spec(3))));
    assert_eq!(
        page(&flash, 0),
        expected_page(6, &[record(3, 0, EVERY_PAD)]).as_slice()
    );

    let mut flash = small_flash();
    layout::write_page(page_mut(&mut flash, 0), 2, 3, &[]);
    layout::write_page(page_mut(&mut flash, 1), 1, 4, &[record(1, 0, EVERY_PAD)]);
    assert_eq!(load_every_pad(&mut flash)[0], LoadOutcome::Stored(spec(1)));
}

/// Intact records whose bodies this firmware refuses (a later body version; a body longer than
/// it reads) flag exactly the pads they are the newest record of, and a move carries them
/// whole: those pads stay flagged until they are saved again.
#[test]
fn intact_records_with_refused_bodies_flag_their_pads_and_are_carried_by_a_move() {
    let mut flash = small_flash();
    let mut later_body = layout::body(&spec(4));
    later_body[0] = 5;
    let long_body = vec![0x5A; MAX_BODY_LEN + 1];
    layout::write_page(
        page_mut(&mut flash, 0),
        1,
        0,
        &[
            record(1, 0, EVERY_PAD),
            layout::record(&later_body, 1, 4),
            layout::record(&long_body, 2, 5),
        ],
    );
    let check = |flash: &mut SmallFlash| {
        let outcomes = load_every_pad(flash);
        assert_eq!(
            outcomes[4],
            LoadOutcome::Corrupt(CorruptReason::Record(RecordError::UnsupportedVersion {
                found: 5
            }))
        );
        assert_eq!(
            outcomes[5],
            LoadOutcome::Corrupt(CorruptReason::Record(RecordError::TooLong))
        );
        outcomes
    };
    let outcomes = check(&mut flash);
    assert_eq!(outcomes[0], LoadOutcome::Stored(spec(1)));
    // Records for pad 1 until a save moves (the refused ones and the new one fill most of a
    // small page).
    let mut moved = false;
    for id in 10..20 {
        block_on(small_store(&mut flash).save_for(RecordScope::Pad(1), &spec(id))).unwrap();
        let outcomes = check(&mut flash);
        assert_eq!(outcomes[1], LoadOutcome::Stored(spec(id)));
        assert_eq!(outcomes[0], LoadOutcome::Stored(spec(1)));
        if erased(page(&flash, 0)) {
            moved = true;
            break;
        }
    }
    assert!(moved);
    block_on(small_store(&mut flash).save_for(RecordScope::Pad(4), &spec(30))).unwrap();
    assert_eq!(load_every_pad(&mut flash)[4], LoadOutcome::Stored(spec(30)));
}
