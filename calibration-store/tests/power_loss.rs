//! Power-fail safety, checked against the guarantee rather than the layout: a save torn at any
//! write or erase, however the torn operation leaves the flash, then a reboot, gives every pad
//! the calibration it had before or (for the pads the save is for, all of them or none) the new
//! one: never an older calibration, never an unsaved one, never nothing where a calibration was
//! saved. A pad that had none may load the defaults flagged as corrupt. The load never writes,
//! loads agree, and the next save works and leaves exactly what the list of completed saves
//! says.
//!
//! Tears: a write stopped after every number of words (and with a half-programmed word), an erase
//! stopped after every number of words from the start of the page, from its end, or leaving
//! random bits set. Saves: the first and second ever, saves for every pad over 0 to 9 earlier
//! ones (appends and moves), saves for one pad interleaved with other pads' and every pad's, a
//! torn save after a torn save, erase_all; then bit flips and erased ranges (proptest).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use std::fmt;

use calibration_store::PadRecord;
use calibration_store::{
    LoadOutcome, OperationKind, PowerLossReport, RamFlash, RamFlashError, RecordScope, Tear,
    MAX_PADS,
};
use common::{
    block_on, config, describe, load_every_pad, mixed_spec, spec, store_of, History, SmallFlash,
    SMALL_PAGE,
};
use proptest::prelude::*;

/// Pages of 4 KiB: fourteen short records, so saves for one pad interleaved with others' append
/// several times and then move with many records to copy.
const TIGHT_PAGE: usize = 4096;
type TightFlash = RamFlash<{ 3 * TIGHT_PAGE }, TIGHT_PAGE>;

/// Half-programmed (or half-erased) words: 3 bits of the first byte, 4 bits, all but one bit.
const PARTIAL_MASKS: [u32; 3] = [0x0000_0007, 0x0000_000F, 0xFFFF_FFFE];

/// A small deterministic generator (xorshift64) for the random erase patterns.
struct Random(u64);

impl Random {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

/// How the interrupted operation leaves the flash.
#[derive(Debug, Clone, Copy)]
enum TearKind {
    /// `RamFlash`'s own: the operation's first words done, some bits of the next one (a write,
    /// or an erase from the start of the page).
    Prefix(Tear),
    /// An erase that reached only the page's last `words` words.
    EraseFromTheEnd { words: usize },
    /// An erase that set each bit of the page with this probability (percent).
    EraseRandomBits { percent: u64 },
}

/// How many tears of an operation to try.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Coverage {
    /// Every word boundary (and half-programmed words at the edges); erases also from the end at
    /// every word and with random bits.
    EveryWord,
    /// The first, second, middle and last word boundary, some half-programmed words, a few erase
    /// patterns.
    Sampled,
    /// Nothing done, half done, all but a half-programmed last word; erases also half from the
    /// end and half of the bits.
    Sparse,
}

/// The tears to try of an operation the probe `report` describes.
fn tears(report: PowerLossReport, coverage: Coverage) -> Vec<TearKind> {
    let words = report.words;
    let edges = [0, 1, 2, words / 2, words.saturating_sub(1)];
    let boundaries: Vec<usize> = match coverage {
        Coverage::EveryWord => (0..words).collect(),
        Coverage::Sampled => edges.to_vec(),
        Coverage::Sparse => {
            return sparse_tears(report);
        }
    };
    let mut tears = Vec::new();
    for whole_words in boundaries {
        tears.push(TearKind::Prefix(Tear::words(whole_words)));
        if edges.contains(&whole_words) {
            for partial_word_mask in PARTIAL_MASKS {
                tears.push(TearKind::Prefix(Tear {
                    whole_words,
                    partial_word_mask,
                }));
            }
        }
    }
    if report.kind == OperationKind::Erase {
        let (from_the_end, percents, repeats): (Vec<usize>, &[u64], usize) = match coverage {
            Coverage::EveryWord => ((1..words).collect(), &[1, 10, 50, 90, 99], 10),
            Coverage::Sampled | Coverage::Sparse => {
                (vec![1, words / 2, words - 1], &[10, 50, 90], 1)
            }
        };
        tears.extend(
            from_the_end
                .into_iter()
                .map(|words| TearKind::EraseFromTheEnd { words }),
        );
        for &percent in percents {
            tears.extend([TearKind::EraseRandomBits { percent }; 1].repeat(repeats));
        }
    }
    tears
}

fn sparse_tears(report: PowerLossReport) -> Vec<TearKind> {
    let words = report.words;
    let mut tears = vec![
        TearKind::Prefix(Tear::NOTHING),
        TearKind::Prefix(Tear::words(words / 2)),
        TearKind::Prefix(Tear {
            whole_words: words - 1,
            partial_word_mask: 0xFFFF_FFFE,
        }),
    ];
    if report.kind == OperationKind::Erase {
        tears.push(TearKind::EraseFromTheEnd { words: words / 2 });
        tears.push(TearKind::EraseRandomBits { percent: 50 });
    }
    tears
}

/// What one pad loaded after a torn save, against what it had before.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PadVerdict {
    Previous,
    New,
    /// Nothing was saved for the pad before, and it loads nothing.
    AbsentWhereNothingWasSaved,
    /// Nothing was saved for the pad before, and it loads the defaults flagged as corrupt.
    FlaggedWhereNothingWasSaved,
    /// A calibration was saved for the pad, and it loads none.
    Lost,
    /// A calibration saved for the pad before its last completed save.
    Older,
    /// A calibration never saved for the pad.
    Unsaved,
}

fn pad_verdict(
    outcome: &LoadOutcome<RamFlashError>,
    history: &History,
    pad: u8,
    covered: bool,
    new: &PadRecord,
) -> PadVerdict {
    let previous = history.expected(pad);
    match outcome {
        LoadOutcome::Stored(spec) if covered && spec == new => PadVerdict::New,
        LoadOutcome::Stored(spec) if Some(spec) == previous => PadVerdict::Previous,
        LoadOutcome::Stored(spec)
            if history
                .0
                .iter()
                .any(|(scope, saved)| scope.covers(pad) && saved == spec) =>
        {
            PadVerdict::Older
        }
        LoadOutcome::Stored(_) => PadVerdict::Unsaved,
        LoadOutcome::Absent if previous.is_none() => PadVerdict::AbsentWhereNothingWasSaved,
        LoadOutcome::Corrupt(_) if previous.is_none() => PadVerdict::FlaggedWhereNothingWasSaved,
        LoadOutcome::Absent | LoadOutcome::Corrupt(_) => PadVerdict::Lost,
    }
}

/// The figures of a series of torn saves.
#[derive(Debug, Default)]
struct Tally {
    torn_saves: u32,
    /// Torn saves after which the saved pads load the new calibration.
    new_saves: u32,
    pad_loads: u32,
    previous: u32,
    new: u32,
    absent_where_nothing_was_saved: u32,
    flagged_where_nothing_was_saved: u32,
    lost: u32,
    older: u32,
    unsaved: u32,
    /// Saves for several pads that some of them load and others not.
    partial: u32,
    failures: Vec<String>,
}

impl fmt::Display for Tally {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            formatter,
            "{} torn saves ({} of which took effect), {} pad loads: previous {}, new {}, nothing \
             saved and absent {}, nothing saved and flagged corrupt {}; lost {}, older {}, \
             unsaved {}, partly applied {}",
            self.torn_saves,
            self.new_saves,
            self.pad_loads,
            self.previous,
            self.new,
            self.absent_where_nothing_was_saved,
            self.flagged_where_nothing_was_saved,
            self.lost,
            self.older,
            self.unsaved,
            self.partial
        )
    }
}

impl Tally {
    fn fail(&mut self, failure: String) {
        if self.failures.len() < 10 {
            self.failures.push(failure);
        }
    }

    /// Panics with the first failures if any load broke the guarantee.
    fn assert_sound(&self, label: &str) {
        println!("{label}: {self}");
        assert!(
            self.failures.is_empty(),
            "{label}: {self}\n{}",
            self.failures.join("\n")
        );
        assert_eq!(
            (self.lost, self.older, self.unsaved, self.partial),
            (0, 0, 0, 0)
        );
    }
}

/// A save of `new` for `scope` over `base`, torn at operation `operation` as `tear` says; none
/// if the save completes before.
fn torn_save<const SIZE: usize, const PAGE: usize>(
    base: &RamFlash<SIZE, PAGE>,
    operation: u32,
    tear: TearKind,
    scope: RecordScope,
    new: &PadRecord,
    random: &mut Random,
) -> Option<Box<RamFlash<SIZE, PAGE>>> {
    let mut flash = Box::new(base.clone());
    let prefix = match tear {
        TearKind::Prefix(tear) => tear,
        TearKind::EraseFromTheEnd { .. } | TearKind::EraseRandomBits { .. } => Tear::NOTHING,
    };
    flash.schedule_power_loss(operation, prefix);
    let result = block_on(store_of(&mut *flash).save_for(scope, new));
    if result.is_ok() {
        assert!(!flash.is_powered_off());
        return None;
    }
    assert!(
        flash.is_powered_off(),
        "failed without a power loss: {result:?}"
    );
    let report = flash.last_power_loss().unwrap();
    let page = report.address as usize..report.address as usize + report.words * 4;
    match tear {
        TearKind::Prefix(_) => {}
        TearKind::EraseFromTheEnd { words } => {
            assert_eq!(report.kind, OperationKind::Erase);
            flash.as_bytes_mut()[page.end - words * 4..page.end].fill(0xFF);
        }
        TearKind::EraseRandomBits { percent } => {
            assert_eq!(report.kind, OperationKind::Erase);
            for byte in &mut flash.as_bytes_mut()[page] {
                for bit in 0..8 {
                    if random.next() % 100 < percent {
                        *byte |= 1 << bit;
                    }
                }
            }
        }
    }
    Some(flash)
}

/// Every tear, as `coverage` says, of every operation of a save of `new` for `scope` over
/// `base`, each with a label.
fn every_torn_save<const SIZE: usize, const PAGE: usize>(
    base: &RamFlash<SIZE, PAGE>,
    scope: RecordScope,
    new: &PadRecord,
    coverage: Coverage,
    random: &mut Random,
) -> Vec<(String, Box<RamFlash<SIZE, PAGE>>)> {
    let mut torn = Vec::new();
    for operation in 0.. {
        let Some(probe) = torn_save(
            base,
            operation,
            TearKind::Prefix(Tear::NOTHING),
            scope,
            new,
            random,
        ) else {
            break;
        };
        let report = probe.last_power_loss().unwrap();
        for tear in tears(report, coverage) {
            let flash = torn_save(base, operation, tear, scope, new, random).unwrap();
            let label = format!(
                "operation {operation} ({:?} of {} words at {:#x}), {tear:?}",
                report.kind, report.words, report.address
            );
            torn.push((label, flash));
        }
    }
    torn
}

/// Reboots `flash` after a torn save of `new` for `scope` over `history`, checks every pad's load
/// (and that loading again agrees) into `tally`, and returns the history of completed saves:
/// `history`, with the new save if the pads it is for load it.
fn check_torn<const SIZE: usize, const PAGE: usize>(
    flash: &mut RamFlash<SIZE, PAGE>,
    history: &History,
    scope: RecordScope,
    new: &PadRecord,
    context: &str,
    tally: &mut Tally,
) -> History {
    let outcomes = load_every_pad(flash);
    tally.torn_saves += 1;
    let mut verdicts = Vec::new();
    for (pad, outcome) in (0..=MAX_PADS).zip(&outcomes) {
        let covered = scope.covers(pad);
        let verdict = pad_verdict(outcome, history, pad, covered, new);
        tally.pad_loads += 1;
        match verdict {
            PadVerdict::Previous => tally.previous += 1,
            PadVerdict::New => tally.new += 1,
            PadVerdict::AbsentWhereNothingWasSaved => tally.absent_where_nothing_was_saved += 1,
            PadVerdict::FlaggedWhereNothingWasSaved => tally.flagged_where_nothing_was_saved += 1,
            PadVerdict::Lost => tally.lost += 1,
            PadVerdict::Older => tally.older += 1,
            PadVerdict::Unsaved => tally.unsaved += 1,
        }
        if matches!(
            verdict,
            PadVerdict::Lost | PadVerdict::Older | PadVerdict::Unsaved
        ) {
            tally.fail(format!(
                "{context}: pad {pad} loaded {} ({verdict:?})",
                describe(outcome)
            ));
        }
        if covered {
            verdicts.push(verdict);
        }
    }
    let took_effect = verdicts.contains(&PadVerdict::New);
    if took_effect && !verdicts.iter().all(|verdict| *verdict == PadVerdict::New) {
        tally.partial += 1;
        tally.fail(format!("{context}: partly applied: {verdicts:?}"));
    }
    if load_every_pad(flash) != outcomes {
        tally.fail(format!("{context}: a second load disagrees"));
    }
    if took_effect {
        tally.new_saves += 1;
        history.with(scope, new)
    } else {
        history.clone()
    }
}

/// The save after a torn one works, and then every pad loads exactly what the completed saves
/// say (the torn save's leftovers are gone); nothing is written outside the range.
fn check_next_save<const SIZE: usize, const PAGE: usize>(
    flash: &mut RamFlash<SIZE, PAGE>,
    history: &History,
    scope: RecordScope,
    context: &str,
    tally: &mut Tally,
) {
    let next = mixed_spec(7777);
    if let Err(error) = block_on(store_of(flash).save_for(scope, &next)) {
        tally.fail(format!("{context}: the next save failed: {error:?}"));
        return;
    }
    if load_every_pad(flash) != history.with(scope, &next).outcomes() {
        tally.fail(format!(
            "{context}: after the next save: {:?}",
            load_every_pad(flash)
                .iter()
                .map(describe)
                .collect::<Vec<_>>()
        ));
    }
    if !flash.as_bytes()[..PAGE].iter().all(|&byte| byte == 0xFF) {
        tally.fail(format!("{context}: written outside the range"));
    }
}

/// Saves for every pad of `mixed_spec(1..=count)` (short and long records), in 2 KiB pages.
fn saves_for_every_pad(count: u32) -> (Box<SmallFlash>, History) {
    let mut flash = Box::new(SmallFlash::new());
    let mut history = History::default();
    for id in 1..=count {
        let spec = mixed_spec(id);
        block_on(store_of(&mut *flash).save(&spec)).unwrap();
        history = history.with(RecordScope::EveryPad, &spec);
    }
    (flash, history)
}

/// 0 to 14 earlier saves put the save under test at every position of a 2 KiB page (the first
/// save, appends, moves); every operation is torn at every word, erases also from the end at
/// every word and with random bits.
#[test]
fn a_save_for_every_pad_torn_anywhere_loads_the_previous_or_the_new_calibration() {
    let mut random = Random(0x1234_5678_9ABC_DEF1);
    let mut tally = Tally::default();
    for prior_saves in 0..=14 {
        let (base, history) = saves_for_every_pad(prior_saves);
        let new = mixed_spec(1000 + prior_saves);
        for (label, mut flash) in every_torn_save(
            &base,
            RecordScope::EveryPad,
            &new,
            Coverage::EveryWord,
            &mut random,
        ) {
            let context = format!("{prior_saves} earlier saves, {label}");
            let completed = check_torn(
                &mut flash,
                &history,
                RecordScope::EveryPad,
                &new,
                &context,
                &mut tally,
            );
            check_next_save(
                &mut flash,
                &completed,
                RecordScope::EveryPad,
                &context,
                &mut tally,
            );
        }
    }
    tally.assert_sound("saves for every pad");
    assert!(tally.torn_saves > 4000 && tally.previous > 0 && tally.new > 0);
}

/// A history of `length` saves with short records for several pads and for every pad, in 4 KiB
/// pages: the save under test appends at many positions and moves with up to nine records to
/// copy.
fn interleaved(length: u32) -> (Box<TightFlash>, History) {
    let mut flash = Box::new(TightFlash::new());
    let mut history = History::default();
    for index in 0..length {
        let scope = match index % 5 {
            0 => RecordScope::EveryPad,
            other => RecordScope::Pad((index * 3 + other) as u8 % MAX_PADS),
        };
        let spec = spec(index + 1);
        block_on(store_of(&mut *flash).save_for(scope, &spec)).unwrap();
        history = history.with(scope, &spec);
    }
    (flash, history)
}

/// Saves for one pad (or, every seventh, for every pad) after histories of 0 to 119 interleaved
/// saves, torn at every operation (sampled tears): every other pad loads exactly what it did,
/// the saved pads their previous or the new calibration. Every save under test that moves is
/// tried, and every tenth that appends.
#[test]
fn saves_for_pads_interleaved_torn_anywhere_leave_the_other_pads_untouched() {
    let mut random = Random(0x0DDB_A11C_AFE5_EED5);
    let mut tally = Tally::default();
    let (mut moves, mut appends) = (0, 0);
    for length in 0..120 {
        let (base, history) = interleaved(length);
        let scope = if length % 7 == 3 {
            RecordScope::EveryPad
        } else {
            RecordScope::Pad((length % u32::from(MAX_PADS)) as u8)
        };
        let new = mixed_spec(500 + length);
        let mut probe = Box::new((*base).clone());
        block_on(store_of(&mut *probe).save_for(scope, &new)).unwrap();
        if probe.erase_count() > base.erase_count() {
            moves += 1;
        } else if length % 10 == 0 {
            appends += 1;
        } else {
            continue;
        }
        let next_scope = RecordScope::Pad(((length + 1) % u32::from(MAX_PADS)) as u8);
        for (label, mut flash) in
            every_torn_save(&base, scope, &new, Coverage::Sampled, &mut random)
        {
            let context = format!("history of {length}, save for {scope:?}, {label}");
            let completed = check_torn(&mut flash, &history, scope, &new, &context, &mut tally);
            check_next_save(&mut flash, &completed, next_scope, &context, &mut tally);
        }
    }
    tally.assert_sound("saves for pads interleaved");
    println!("saves under test: {moves} moves, {appends} appends");
    assert!(moves >= 10, "only {moves} saves under test moved");
}

/// A torn save leaves a layout no completed save does (a half-erased or half-written other page,
/// a torn record after the last); the next save must clean it up without ever exposing an older
/// record, even when it is torn itself.
#[test]
fn a_torn_save_after_a_torn_save_loads_the_last_completed_save_or_the_newer_one() {
    let mut random = Random(0x005E_ED0F_B007);
    let mut first = Tally::default();
    let mut second = Tally::default();
    for length in [0, 1, 5, 13, 14, 28] {
        let (base, history) = interleaved(length);
        let scope = RecordScope::Pad((length % u32::from(MAX_PADS)) as u8);
        let new = mixed_spec(6000 + length);
        let newer = mixed_spec(6100 + length);
        let second_scope = if length % 2 == 0 {
            RecordScope::EveryPad
        } else {
            RecordScope::Pad(((length + 3) % u32::from(MAX_PADS)) as u8)
        };
        for (label, mut once) in every_torn_save(&base, scope, &new, Coverage::Sampled, &mut random)
        {
            let context = format!("history of {length}, first save torn at {label}");
            let completed = check_torn(&mut once, &history, scope, &new, &context, &mut first);
            for (second_label, mut twice) in
                every_torn_save(&once, second_scope, &newer, Coverage::Sparse, &mut random)
            {
                let context = format!("{context}; second save torn at {second_label}");
                let last = check_torn(
                    &mut twice,
                    &completed,
                    second_scope,
                    &newer,
                    &context,
                    &mut second,
                );
                check_next_save(
                    &mut twice,
                    &last,
                    RecordScope::Pad(1),
                    &context,
                    &mut second,
                );
            }
        }
    }
    first.assert_sound("first torn save");
    second.assert_sound("second torn save, after the first");
}

/// erase_all torn anywhere: every pad loads its calibration, none, or the defaults flagged as
/// corrupt; never an older one. The next save works.
#[test]
fn a_torn_erase_all_leaves_each_pad_its_calibration_or_nothing() {
    let mut random = Random(0xE2A5_E0A1_1000_0001);
    let (mut torn, mut flagged, mut kept) = (0, 0, 0);
    for length in [1, 4, 9, 14, 30] {
        let (base, history) = interleaved(length);
        for operation in 0.. {
            let mut probe = Box::new((*base).clone());
            probe.schedule_power_loss(operation, Tear::NOTHING);
            if block_on(store_of(&mut *probe).erase_all()).is_ok() {
                break;
            }
            let report = probe.last_power_loss().unwrap();
            for tear in tears(report, Coverage::Sampled) {
                let mut flash = Box::new((*base).clone());
                let prefix = match tear {
                    TearKind::Prefix(tear) => tear,
                    _ => Tear::NOTHING,
                };
                flash.schedule_power_loss(operation, prefix);
                assert!(block_on(store_of(&mut *flash).erase_all()).is_err());
                let page = report.address as usize..report.address as usize + report.words * 4;
                match tear {
                    TearKind::Prefix(_) => {}
                    TearKind::EraseFromTheEnd { words } => {
                        flash.as_bytes_mut()[page.end - words * 4..page.end].fill(0xFF);
                    }
                    TearKind::EraseRandomBits { percent } => {
                        for byte in &mut flash.as_bytes_mut()[page] {
                            for bit in 0..8 {
                                if random.next() % 100 < percent {
                                    *byte |= 1 << bit;
                                }
                            }
                        }
                    }
                }
                torn += 1;
                for (pad, outcome) in (0..=MAX_PADS).zip(load_every_pad(&mut flash)) {
                    flagged += u32::from(outcome.is_corrupt());
                    kept += u32::from(outcome.stored().is_some());
                    assert!(
                        outcome == LoadOutcome::Absent
                            || outcome.is_corrupt()
                            || outcome.stored() == history.expected(pad),
                        "history of {length}, operation {operation}, {tear:?}: pad {pad} loaded {}",
                        describe(&outcome)
                    );
                }
                let next = mixed_spec(4242);
                block_on(store_of(&mut *flash).save(&next)).unwrap();
                assert!(load_every_pad(&mut flash)
                    .iter()
                    .all(|outcome| *outcome == LoadOutcome::Stored(next.clone())));
            }
        }
    }
    println!(
        "{torn} torn erase_all: pad loads with the calibration kept {kept}, flagged corrupt \
         {flagged}, the rest absent"
    );
}

/// A load never writes: whatever a torn save left, a power loss during the boot that follows
/// cannot change anything.
#[test]
fn loading_after_a_torn_save_never_writes() {
    let mut random = Random(0x0B00_7B00_7B00_7B00);
    let mut loads = 0;
    for length in [0, 3, 13, 14, 28] {
        let (base, _) = interleaved(length);
        let scope = RecordScope::Pad(2);
        for (label, mut flash) in
            every_torn_save(&base, scope, &spec(77), Coverage::Sampled, &mut random)
        {
            flash.power_cycle();
            let before = flash.snapshot();
            flash.schedule_power_loss(0, Tear::words(1));
            for pad in 0..=MAX_PADS {
                block_on(store_of(&mut *flash).load(pad));
                loads += 1;
            }
            assert!(!flash.is_powered_off(), "{label}: a load wrote or erased");
            assert!(
                flash.snapshot() == before,
                "{label}: a load changed the flash"
            );
        }
    }
    println!("{loads} loads after a torn save, none of which wrote");
}

fn base_with_history(prior_saves: u32) -> (Box<SmallFlash>, Vec<PadRecord>) {
    let (flash, history) = saves_for_every_pad(prior_saves + 1);
    (flash, history.0.into_iter().map(|(_, spec)| spec).collect())
}

/// An address of the range: a written byte if `written` and there is one, else any.
fn region_address(flash: &SmallFlash, written: bool, seed: usize) -> usize {
    let region = SMALL_PAGE..3 * SMALL_PAGE;
    let written_addresses: Vec<usize> = region
        .clone()
        .filter(|&address| flash.as_bytes()[address] != 0xFF)
        .collect();
    if written && !written_addresses.is_empty() {
        written_addresses[seed % written_addresses.len()]
    } else {
        region.start + seed % region.len()
    }
}

/// After any corruption the next save must still succeed and win.
fn next_save_heals(flash: &mut SmallFlash) -> Result<(), TestCaseError> {
    let next = mixed_spec(9999);
    let saved = block_on(store_of(flash).save(&next));
    prop_assert!(saved.is_ok(), "save after corruption: {:?}", saved);
    prop_assert_eq!(load_every_pad(flash)[0].clone(), LoadOutcome::Stored(next));
    Ok(())
}

proptest! {
    #![proptest_config(config(400))]

    /// One flipped bit anywhere: the newest or the previous calibration, or the defaults flagged
    /// as corrupt; never another calibration, never a crash.
    #[test]
    fn a_single_bit_flip_gives_the_newest_the_previous_or_a_flag(
        prior_saves in 1..12u32,
        written in any::<bool>(),
        seed in any::<usize>(),
        bit in 0u8..8,
    ) {
        let (mut flash, history) = base_with_history(prior_saves);
        let address = region_address(&flash, written, seed);
        flash.flip_bit(address as u32, bit).unwrap();
        let outcome = load_every_pad(&mut flash)[0].clone();
        let acceptable = outcome.is_corrupt()
            || outcome.stored() == history.last()
            || outcome.stored() == history.get(history.len() - 2);
        prop_assert!(acceptable, "bit {} of {:#x}: {}", bit, address, describe(&outcome));
        next_save_heals(&mut flash)?;
    }

    /// Several flips, or an erased range: some calibration that was saved at some point, Absent
    /// or Corrupt; never an unsaved spec, never a crash.
    #[test]
    fn heavier_corruption_gives_a_saved_spec_absent_or_corrupt(
        prior_saves in 1..12u32,
        flips in proptest::collection::vec((any::<bool>(), any::<usize>(), 0u8..8), 2..10),
        erased in proptest::option::of((any::<usize>(), 1usize..700)),
    ) {
        let (mut flash, history) = base_with_history(prior_saves);
        for (written, seed, bit) in flips {
            let address = region_address(&flash, written, seed);
            flash.flip_bit(address as u32, bit).unwrap();
        }
        if let Some((seed, length)) = erased {
            let start = region_address(&flash, true, seed);
            let end = (start + length).min(3 * SMALL_PAGE);
            flash.as_bytes_mut()[start..end].fill(0xFF);
        }
        let outcome = load_every_pad(&mut flash)[0].clone();
        if let LoadOutcome::Stored(spec) = &outcome {
            prop_assert!(history.contains(spec), "an unsaved spec: {}", describe(&outcome));
        }
        next_save_heals(&mut flash)?;
    }
}
