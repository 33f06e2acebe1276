//! The store over the RAM flash: round trips, region checks, what corruption gives, wrap-around
//! over many saves, self-healing saves, and the real F411 geometry (2 x 128 KiB).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{
    CalibrationStore, CorruptReason, LoadOutcome, PadRecord, RamFlash, RamFlashError, RecordError,
    RegionError, StoreError, Tear, MAX_BODY_LEN, STM32F411_CALIBRATION_RANGE,
};
use common::layout::{self, EVERY_PAD};
use common::{
    block_on, describe, mixed_spec, reboot_and_load, small_flash, small_store, spec,
    worst_case_spec, F411Flash, SmallFlash, OUTSIDE_RANGE, SMALL_PAGE, SMALL_RANGE,
};
use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use model_core::calibration::{CalibrationError, CalibrationSpec};

fn assert_outside_untouched(flash: &SmallFlash) {
    assert!(
        flash.as_bytes()[OUTSIDE_RANGE]
            .iter()
            .all(|&byte| byte == 0xFF),
        "the store wrote outside its range"
    );
}

/// The record for every pad of `spec` with `save_counter`, as the format documents it.
fn record(spec: &PadRecord, save_counter: u32) -> Vec<u8> {
    layout::record(&layout::body(spec), save_counter, EVERY_PAD)
}

/// Start addresses of every copy of `needle` in the flash, in address order.
fn find_all(flash: &SmallFlash, needle: &[u8]) -> Vec<usize> {
    flash
        .as_bytes()
        .windows(needle.len())
        .enumerate()
        .filter(|(_, window)| *window == needle)
        .map(|(address, _)| address)
        .collect()
}

/// Appends `record` after the records of the region's current page, which must be page 0:
/// an intact record with whatever content.
fn append_raw_record(flash: &mut SmallFlash, record: &[u8]) {
    let first_page = SMALL_RANGE.start as usize..SMALL_RANGE.start as usize + SMALL_PAGE;
    layout::append(&mut flash.as_bytes_mut()[first_page], record);
}

#[test]
fn blank_flash_is_absent() {
    let mut flash = small_flash();
    assert_eq!(
        block_on(small_store(&mut flash).load(0)),
        LoadOutcome::Absent
    );
    assert!(flash.as_bytes().iter().all(|&byte| byte == 0xFF));
}

#[test]
fn save_then_load_returns_the_same_spec_before_and_after_a_reboot() {
    let mut flash = small_flash();
    for saved in [
        spec(1),
        worst_case_spec(u32::MAX),
        PadRecord::new(CalibrationSpec::default()),
    ] {
        let mut store = small_store(&mut flash);
        block_on(store.save(&saved)).unwrap();
        assert_eq!(block_on(store.load(0)), LoadOutcome::Stored(saved.clone()));
        assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(saved));
    }
    assert_outside_untouched(&flash);
}

#[test]
fn the_store_reports_its_range_and_gives_the_flash_back() {
    let mut flash = small_flash();
    let store = small_store(&mut flash);
    assert_eq!(store.range(), SMALL_RANGE);
    let flash_back: &mut SmallFlash = store.into_flash();
    assert_eq!(flash_back.capacity(), 3 * SMALL_PAGE);
}

#[test]
fn unusable_ranges_are_refused() {
    let mut flash = small_flash();
    let page = SMALL_PAGE as u32;
    let refused = |flash: &mut SmallFlash, range| CalibrationStore::new(flash, range).err();
    assert_eq!(
        refused(&mut flash, 100..2 * page + 100),
        Some(RegionError::NotPageAligned)
    );
    assert_eq!(
        refused(&mut flash, page..2 * page + 4),
        Some(RegionError::NotPageAligned)
    );
    assert_eq!(
        refused(&mut flash, page..2 * page),
        Some(RegionError::TooFewPages)
    );
    assert_eq!(
        refused(&mut flash, page..4 * page),
        Some(RegionError::BeyondFlash)
    );
    let mut four_pages = Box::new(RamFlash::<{ 4 * SMALL_PAGE }, SMALL_PAGE>::new());
    assert_eq!(
        CalibrationStore::new(&mut *four_pages, 0..3 * page).err(),
        Some(RegionError::TooManyPages)
    );
}

/// A page must hold its header (16 bytes), its commit word (4) and two of the longest records:
/// 16-byte header + 692-byte body (calibration, role and geometry), a multiple of the 4-byte
/// word: 708. 20 + 2 x 708 = 1436.
#[test]
fn pages_must_hold_two_records_and_that_is_enough() {
    assert_eq!(MAX_BODY_LEN, 692);
    let mut too_small = Box::new(RamFlash::<{ 2 * 1432 }, 1432>::new());
    assert_eq!(
        CalibrationStore::new(&mut *too_small, 0..2 * 1432).err(),
        Some(RegionError::PagesTooSmall)
    );
    let mut just_enough = Box::new(RamFlash::<{ 2 * 1436 }, 1436>::new());
    let mut store = CalibrationStore::new(&mut *just_enough, 0..2 * 1436).unwrap();
    for id in 0..20 {
        let saved = worst_case_spec(id);
        block_on(store.save(&saved)).unwrap();
        assert_eq!(block_on(store.load(0)), LoadOutcome::Stored(saved));
    }
}

#[test]
fn an_invalid_spec_is_refused_and_nothing_is_written() {
    let mut flash = small_flash();
    let mut invalid = spec(4);
    invalid.calibration.taxels[0].parasitic_pf = -1.0;
    assert_eq!(
        block_on(small_store(&mut flash).save(&invalid)),
        Err(StoreError::Record(RecordError::Invalid(
            CalibrationError::ParasiticOutOfRange { taxel: 0 }
        )))
    );
    assert!(flash.as_bytes().iter().all(|&byte| byte == 0xFF));
}

#[test]
fn erase_all_restores_absent_and_saving_works_afterwards() {
    let mut flash = small_flash();
    let mut store = small_store(&mut flash);
    block_on(store.save(&spec(1))).unwrap();
    block_on(store.erase_all()).unwrap();
    assert_eq!(block_on(store.load(0)), LoadOutcome::Absent);
    block_on(store.save(&spec(2))).unwrap();
    assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(spec(2)));
    assert_outside_untouched(&flash);
}

/// What corruption of the stored bytes gives: a record whose CRC fails is skipped, so a
/// corrupted newest record falls back to the previous record while that is still in the page,
/// and to the defaults flagged as corrupt when it was the only one. Never a crash.
#[test]
fn a_corrupted_newest_record_falls_back_to_the_previous_one_or_is_flagged() {
    let mut flash = small_flash();
    block_on(small_store(&mut flash).save(&spec(1))).unwrap();
    let only = find_all(&flash, &record(&spec(1), 0));
    assert_eq!(only.len(), 1);
    let mut lone = flash.clone();
    lone.flip_bit(only[0] as u32 + 100, 5).unwrap();
    assert_eq!(
        reboot_and_load(&mut lone),
        LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
    );

    block_on(small_store(&mut flash).save(&spec(2))).unwrap();
    let newest = find_all(&flash, &record(&spec(2), 1));
    assert_eq!(newest.len(), 1);
    // The length, its complement, the save counter, the pads byte, the CRC, the body.
    for offset in [0usize, 2, 5, 8, 13, 16, 57, 200] {
        let mut corrupted = flash.clone();
        corrupted.flip_bit((newest[0] + offset) as u32, 0).unwrap();
        assert_eq!(
            reboot_and_load(&mut corrupted),
            LoadOutcome::Stored(spec(1)),
            "flip at record byte {offset}"
        );
        // The next save still works and wins.
        block_on(small_store(&mut corrupted).save(&spec(3))).unwrap();
        assert_eq!(
            reboot_and_load(&mut corrupted),
            LoadOutcome::Stored(spec(3))
        );
    }
}

/// `body` behind a record for every pad with `save_counter`.
fn raw_record(body: &[u8], save_counter: u32) -> Vec<u8> {
    layout::record(body, save_counter, EVERY_PAD)
}

/// An intact record newer than the valid one whose body this firmware refuses (a later body
/// version, a body that does not parse, is empty, has bytes left over, is longer than any
/// body): Corrupt with the reason, not the older valid record. The next save replaces it.
#[test]
fn an_intact_record_with_a_refused_body_is_corrupt_and_a_save_replaces_it() {
    let valid = layout::body(&spec(5));
    let mut later_version = valid.clone();
    later_version[0] = 3;
    let mut trailing = valid.clone();
    trailing.push(0);
    let cases: [(Vec<u8>, RecordError); 5] = [
        (later_version, RecordError::UnsupportedVersion { found: 3 }),
        (vec![], RecordError::Empty),
        (trailing, RecordError::TrailingBytes),
        (vec![0x42; MAX_BODY_LEN + 57], RecordError::TooLong),
        (
            vec![2, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF],
            RecordError::Postcard(postcard::Error::DeserializeBadVarint),
        ),
    ];
    for (body, error) in cases {
        let mut flash = small_flash();
        block_on(small_store(&mut flash).save(&spec(4))).unwrap();
        append_raw_record(&mut flash, &raw_record(&body, 9));
        let outcome = reboot_and_load(&mut flash);
        assert_eq!(
            outcome,
            LoadOutcome::Corrupt(CorruptReason::Record(error.clone())),
            "{error:?}"
        );
        assert!(outcome.is_corrupt());
        assert_eq!(outcome.stored(), None);
        block_on(small_store(&mut flash).save(&spec(6))).unwrap();
        assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(spec(6)));
        assert_outside_untouched(&flash);
    }
}

/// Many saves cycle through both pages (wear levelling, migration of the newest record, page
/// erases) and every load, with or without a reboot, returns the newest.
#[test]
fn five_hundred_saves_wrap_around_two_small_pages() {
    let mut flash = small_flash();
    for id in 0..500 {
        let saved = mixed_spec(id);
        let mut store = small_store(&mut flash);
        block_on(store.save(&saved)).unwrap();
        assert_eq!(
            block_on(store.load(0)),
            LoadOutcome::Stored(saved.clone()),
            "save {id}"
        );
        if id % 25 == 0 {
            assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(saved));
        }
    }
    assert_eq!(
        reboot_and_load(&mut flash),
        LoadOutcome::Stored(mixed_spec(499))
    );
    // Three records or more fit a page, so 500 saves erased each page dozens of times.
    assert!(flash.erase_count() >= 100, "{} erases", flash.erase_count());
    assert_outside_untouched(&flash);
}

/// A flash whose cells spoil the chosen writes: one bit of the data does not program.
struct WeakCells<'a> {
    flash: &'a mut SmallFlash,
    writes: u32,
    spoiled: fn(u32) -> bool,
}

impl ErrorType for WeakCells<'_> {
    type Error = RamFlashError;
}

impl ReadNorFlash for WeakCells<'_> {
    const READ_SIZE: usize = SmallFlash::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.read(offset, bytes).await
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl NorFlash for WeakCells<'_> {
    const WRITE_SIZE: usize = SmallFlash::WRITE_SIZE;
    const ERASE_SIZE: usize = SmallFlash::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.flash.erase(from, to).await
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let index = self.writes;
        self.writes += 1;
        let mut data = bytes.to_vec();
        if (self.spoiled)(index) && data.len() > 16 {
            // A 0 bit that stays 1: the cell did not program.
            if let Some(byte) = data.iter_mut().skip(12).find(|byte| **byte != 0xFF) {
                *byte |= !*byte & byte.wrapping_add(1);
            }
        }
        self.flash.write(offset, &data).await
    }
}

#[test]
fn a_save_that_does_not_read_back_is_retried_in_the_erased_page() {
    let mut flash = small_flash();
    block_on(small_store(&mut flash).save(&spec(1))).unwrap();
    let writes_before = flash.write_count();
    {
        // The first write is the appended record: spoiling it makes the save move (page
        // header, the new record, commit word).
        let weak = WeakCells {
            flash: &mut flash,
            writes: 0,
            spoiled: |index| index == 0,
        };
        let mut store = CalibrationStore::new(weak, SMALL_RANGE).unwrap();
        block_on(store.save(&spec(2))).unwrap();
    }
    assert_eq!(
        flash.erase_count(),
        1,
        "the move erases the page of the previous record once the new one reads back"
    );
    assert_eq!(flash.write_count(), writes_before + 4);
    assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(spec(2)));

    let weak = WeakCells {
        flash: &mut flash,
        writes: 0,
        spoiled: |_| true,
    };
    let mut store = CalibrationStore::new(weak, SMALL_RANGE).unwrap();
    assert_eq!(
        block_on(store.save(&spec(3))),
        Err(StoreError::VerifyFailed)
    );
    // The move went to the erased page and was never made current: the previous record was
    // never erased.
    let outcome = reboot_and_load(&mut flash);
    assert_eq!(
        outcome,
        LoadOutcome::Stored(spec(2)),
        "after a failed retry in the erased page: {}",
        describe(&outcome)
    );
}

/// The firmware's geometry: sectors 6 and 7 of a 512 KiB F411, 128 KiB each. 198 of the longest
/// records fit a sector, so 450 saves fill the first, move to the second, fill it and move back
/// (erasing the first again).
#[test]
fn the_f411_region_of_two_128_kib_sectors_wraps_and_loads_the_newest() {
    let mut flash = Box::new(F411Flash::new());
    let range = STM32F411_CALIBRATION_RANGE;
    assert_eq!(range, 0x4_0000..0x8_0000);
    assert_eq!(
        CalibrationStore::new(&mut *flash, range.clone()).err(),
        None
    );
    assert_eq!(
        block_on(
            CalibrationStore::new(&mut *flash, range.clone())
                .unwrap()
                .load(0)
        ),
        LoadOutcome::Absent
    );
    for id in 0..450 {
        let saved = worst_case_spec(id);
        let mut store = CalibrationStore::new(&mut *flash, range.clone()).unwrap();
        block_on(store.save(&saved)).unwrap();
        if id % 50 == 0 || id == 449 {
            flash.power_cycle();
            let mut rebooted = CalibrationStore::new(&mut *flash, range.clone()).unwrap();
            assert_eq!(block_on(rebooted.load(0)), LoadOutcome::Stored(saved));
        }
    }
    assert!(flash.erase_count() >= 2, "{} erases", flash.erase_count());
    assert!(
        flash.as_bytes()[..range.start as usize]
            .iter()
            .all(|&byte| byte == 0xFF),
        "the store wrote below its range"
    );
}

/// Every save takes the highest save counter in the region plus one, also across reboots.
#[test]
fn save_counters_count_up_from_zero_across_reboots() {
    let mut flash = small_flash();
    for (save_counter, id) in (0..6).zip(20..) {
        block_on(small_store(&mut flash).save(&mixed_spec(id))).unwrap();
        let copies = find_all(&flash, &record(&mixed_spec(id), save_counter));
        assert!(!copies.is_empty(), "save {save_counter} not found");
        flash.power_cycle();
    }
}

/// The intact record with the highest save counter wins wherever it is in the page: here the
/// later record holds the older counter. The next save takes counter 8, and neither it nor a
/// save torn at any of its operations ever brings back the older record.
#[test]
fn the_highest_save_counter_wins_over_the_position() {
    let mut layout = small_flash();
    let first_page = SMALL_RANGE.start as usize..SMALL_RANGE.start as usize + SMALL_PAGE;
    layout::write_page(
        &mut layout.as_bytes_mut()[first_page],
        1,
        0,
        &[record(&spec(5), 7), record(&spec(6), 3)],
    );
    assert_eq!(reboot_and_load(&mut layout), LoadOutcome::Stored(spec(5)));

    let mut saved = layout.clone();
    block_on(small_store(&mut saved).save(&spec(9))).unwrap();
    assert!(!find_all(&saved, &record(&spec(9), 8)).is_empty());
    assert_eq!(reboot_and_load(&mut saved), LoadOutcome::Stored(spec(9)));

    let mut torn_saves = 0;
    for operations in 0.. {
        let mut torn = layout.clone();
        torn.schedule_power_loss(operations, Tear::NOTHING);
        if block_on(small_store(&mut torn).save(&spec(9))).is_ok() {
            break;
        }
        let words = torn.last_power_loss().unwrap().words;
        for whole_words in [0, words / 2, words - 1] {
            let mut torn = layout.clone();
            torn.schedule_power_loss(operations, Tear::words(whole_words));
            assert!(block_on(small_store(&mut torn).save(&spec(9))).is_err());
            let outcome = reboot_and_load(&mut torn);
            assert!(
                outcome == LoadOutcome::Stored(spec(5)) || outcome == LoadOutcome::Stored(spec(9)),
                "operation {operations} torn after {whole_words} words: {}",
                describe(&outcome)
            );
            torn_saves += 1;
        }
    }
    assert!(torn_saves > 0);
}

/// A first save torn after its page header: no complete page, written bytes: flagged.
#[test]
fn a_region_with_written_bytes_but_no_complete_page_is_corrupt() {
    let mut flash = small_flash();
    flash.schedule_power_loss(1, Tear::NOTHING);
    assert!(block_on(small_store(&mut flash).save(&spec(1))).is_err());
    assert!(flash.as_bytes()[SMALL_RANGE.start as usize] != 0xFF);
    assert_eq!(
        reboot_and_load(&mut flash),
        LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
    );
    block_on(small_store(&mut flash).save(&spec(2))).unwrap();
    assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(spec(2)));
}
