//! Power-fail safety, proven on the RAM flash: a power loss at every write/erase of a save, torn
//! at every word boundary (and with half-programmed words), then a reboot, always loads the old
//! or the new calibration, or the defaults flagged as corrupt, and the next save works. The same
//! when the interrupted erase leaves the page in other patterns (erased from its end, random
//! bits), for a second torn save after a torn save, for erase_all (old or nothing), for a second
//! power loss during the recovery at boot, and for bit flips and erased ranges anywhere in the
//! region (proptest).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{LoadOutcome, OperationKind, RamFlashError, Tear};
use common::{
    block_on, config, describe, mixed_spec, reboot_and_load, small_flash, small_store,
    version_2_flash, version_2_flash_newest, worst_case_spec, SmallFlash, OUTSIDE_RANGE,
    SMALL_RANGE,
};
use model_core::calibration::CalibrationSpec;
use proptest::prelude::*;

/// Tears that leave a half-programmed (or half-erased) word: 3 bits of the first byte (below
/// sequential-storage's 4-bit page-marker threshold), 4 bits (at it), all but one bit.
const PARTIAL_MASKS: [u32; 3] = [0x0000_0007, 0x0000_000F, 0xFFFF_FFFE];

/// Histories before the save under test: 0 (blank) to 9 earlier saves, which puts the save under
/// test at every position of a page, including the ones that close a page and migrate.
const MAX_PRIOR_SAVES: u32 = 9;

fn flash_after(prior_saves: u32) -> Box<SmallFlash> {
    let mut flash = small_flash();
    for id in 1..=prior_saves {
        block_on(small_store(&mut flash).save(&mixed_spec(id))).unwrap();
    }
    flash
}

fn old_spec(prior_saves: u32) -> Option<CalibrationSpec> {
    (prior_saves > 0).then(|| mixed_spec(prior_saves))
}

/// What a load after a torn save gave, among the acceptable outcomes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// The calibration saved before (or Absent when there was none).
    Old,
    /// The calibration being saved.
    New,
    /// No calibration, and the load says so: the defaults with the corrupt flag, where there was
    /// no calibration before either (a torn first save).
    FlaggedDefaults,
    /// The defaults with the corrupt flag where a calibration had been saved: acceptable, but
    /// that calibration is lost.
    FlaggedDefaultsAfterASave,
}

/// Old (or Absent when there was none), new, or Corrupt are the only acceptable outcomes: never an
/// older calibration, never an unsaved one, never Absent when a calibration had been saved.
fn verdict(
    outcome: &LoadOutcome<RamFlashError>,
    old: &Option<CalibrationSpec>,
    new: &CalibrationSpec,
) -> Option<Verdict> {
    match (outcome, old) {
        (LoadOutcome::Stored(spec), _) if spec == new => Some(Verdict::New),
        (LoadOutcome::Stored(spec), Some(old)) if spec == old => Some(Verdict::Old),
        (LoadOutcome::Absent, None) => Some(Verdict::Old),
        (LoadOutcome::Corrupt(_), None) => Some(Verdict::FlaggedDefaults),
        (LoadOutcome::Corrupt(_), Some(_)) => Some(Verdict::FlaggedDefaultsAfterASave),
        _ => None,
    }
}

#[derive(Debug, Default)]
struct Tally {
    torn_saves: u32,
    old: u32,
    new: u32,
    flagged_defaults: u32,
    flagged_defaults_after_a_save: u32,
}

impl std::fmt::Display for Tally {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            formatter,
            "{} torn saves: old {}, new {}, defaults flagged where nothing was saved before {}, \
             defaults flagged where a calibration had been saved {}",
            self.torn_saves,
            self.old,
            self.new,
            self.flagged_defaults,
            self.flagged_defaults_after_a_save
        )
    }
}

impl Tally {
    fn count(&mut self, verdict: Verdict) {
        self.torn_saves += 1;
        match verdict {
            Verdict::Old => self.old += 1,
            Verdict::New => self.new += 1,
            Verdict::FlaggedDefaults => self.flagged_defaults += 1,
            Verdict::FlaggedDefaultsAfterASave => self.flagged_defaults_after_a_save += 1,
        }
    }
}

/// One torn save from `base`: returns None if the save completed before the power loss.
fn torn_save(
    base: &SmallFlash,
    operations: u32,
    tear: Tear,
    new: &CalibrationSpec,
) -> Option<Box<SmallFlash>> {
    let mut flash = Box::new(base.clone());
    flash.schedule_power_loss(operations, tear);
    let result = block_on(small_store(&mut flash).save(new));
    if result.is_ok() {
        assert!(!flash.is_powered_off());
        return None;
    }
    assert!(
        flash.is_powered_off(),
        "save failed without a power loss: {result:?}"
    );
    Some(flash)
}

/// Reboots, loads, checks the outcome is acceptable, that a second load agrees and that the next
/// save works; returns the verdict and what the load gave.
fn check_after_reboot(
    flash: &mut SmallFlash,
    old: &Option<CalibrationSpec>,
    new: &CalibrationSpec,
    context: &str,
) -> (Verdict, LoadOutcome<RamFlashError>) {
    let outcome = reboot_and_load(flash);
    let verdict = verdict(&outcome, old, new)
        .unwrap_or_else(|| panic!("{context}: loaded {}", describe(&outcome)));
    // Loading again (the recovery may have written) gives the same answer.
    assert_eq!(reboot_and_load(flash), outcome, "{context}: second load");
    (verdict, outcome)
}

/// The save after a torn one works and wins; nothing is written outside the range.
fn check_next_save(mut flash: Box<SmallFlash>, context: &str) {
    let next = mixed_spec(7777);
    block_on(small_store(&mut flash).save(&next))
        .unwrap_or_else(|error| panic!("{context}: the save after the reboot failed: {error:?}"));
    assert_eq!(
        reboot_and_load(&mut flash),
        LoadOutcome::Stored(next),
        "{context}: after the next save"
    );
    assert!(flash.as_bytes()[OUTSIDE_RANGE]
        .iter()
        .all(|&byte| byte == 0xFF));
}

#[test]
fn power_loss_at_every_operation_of_a_save_leaves_the_old_or_the_new_spec() {
    let mut tally = Tally::default();
    let (mut torn_writes, mut torn_erases) = (0, 0);
    for prior_saves in 0..=MAX_PRIOR_SAVES {
        let base = flash_after(prior_saves);
        let old = old_spec(prior_saves);
        let new = mixed_spec(1000 + prior_saves);
        let mut operations = 0;
        while let Some(probe) = torn_save(&base, operations, Tear::NOTHING, &new) {
            let report = probe.last_power_loss().unwrap();
            match report.kind {
                OperationKind::Write => torn_writes += 1,
                OperationKind::Erase => torn_erases += 1,
            }
            for whole_words in 0..report.words {
                // Half-programmed words at the edges and the middle of the operation; clean
                // word boundaries everywhere.
                let edges = [0, 1, 2, report.words / 2, report.words - 1];
                let partial_masks = if edges.contains(&whole_words) {
                    &PARTIAL_MASKS[..]
                } else {
                    &[]
                };
                for &partial_word_mask in [0].iter().chain(partial_masks) {
                    let tear = Tear {
                        whole_words,
                        partial_word_mask,
                    };
                    let mut flash = torn_save(&base, operations, tear, &new).unwrap();
                    let context = format!(
                        "{prior_saves} prior saves, operation {operations} ({:?} of {} words \
                         at {:#x}), {tear:?}",
                        report.kind, report.words, report.address
                    );
                    let (verdict, _) = check_after_reboot(&mut flash, &old, &new, &context);
                    tally.count(verdict);
                    check_next_save(flash, &context);
                }
            }
            operations += 1;
        }
        // Uninterrupted, the save takes `operations` writes and erases and succeeds.
        let mut flash = Box::new((*base).clone());
        block_on(small_store(&mut flash).save(&new)).unwrap();
        assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(new));
    }
    println!(
        "erased from the start ({torn_writes} writes and {torn_erases} erases torn at every \
         word): {tally}"
    );
    assert!(tally.old > 0 && tally.new > 0);
    assert!(torn_erases > 0, "no save under test erased a page");
    assert!(
        tally.flagged_defaults > 0,
        "no torn first save left written bytes"
    );
    assert_eq!(
        tally.flagged_defaults_after_a_save, 0,
        "a saved calibration was lost"
    );
}

/// The first save after the update to record format version 3, over the flash the previous
/// firmware wrote (version-2 records): torn at every operation and word, the calibration saved
/// with version 2 or the new one loads, never the defaults.
#[test]
fn power_loss_during_the_first_save_over_version_2_records_leaves_the_old_or_the_new_spec() {
    let base = version_2_flash();
    let old = Some(version_2_flash_newest());
    let new = worst_case_spec(3000);
    let mut tally = Tally::default();
    let mut operations = 0;
    while let Some(probe) = torn_save(&base, operations, Tear::NOTHING, &new) {
        let report = probe.last_power_loss().unwrap();
        for whole_words in 0..report.words {
            let edges = [0, 1, 2, report.words / 2, report.words - 1];
            let partial_masks = if edges.contains(&whole_words) {
                &PARTIAL_MASKS[..]
            } else {
                &[]
            };
            for &partial_word_mask in [0].iter().chain(partial_masks) {
                let tear = Tear {
                    whole_words,
                    partial_word_mask,
                };
                let mut flash = torn_save(&base, operations, tear, &new).unwrap();
                let context = format!(
                    "over version 2, operation {operations} ({:?} of {} words), {tear:?}",
                    report.kind, report.words
                );
                let (verdict, _) = check_after_reboot(&mut flash, &old, &new, &context);
                tally.count(verdict);
                check_next_save(flash, &context);
            }
        }
        operations += 1;
    }
    println!("over version-2 records: {tally}");
    assert!(tally.old > 0 && tally.new > 0, "{tally}");
    assert_eq!(
        tally.flagged_defaults_after_a_save, 0,
        "a calibration saved with version 2 was lost"
    );
}

#[test]
fn power_loss_during_erase_all_leaves_the_old_spec_or_nothing() {
    let mut flagged = 0;
    for prior_saves in 1..=MAX_PRIOR_SAVES {
        let base = flash_after(prior_saves);
        let old = old_spec(prior_saves);
        let probe_words = {
            let mut flash = Box::new(base.clone());
            flash.schedule_power_loss(0, Tear::NOTHING);
            assert!(block_on(small_store(&mut flash).erase_all()).is_err());
            flash.last_power_loss().unwrap().words
        };
        for whole_words in 0..probe_words {
            let edges = [0, 1, 2, probe_words / 2, probe_words - 1];
            let partial_masks = if edges.contains(&whole_words) {
                &PARTIAL_MASKS[..]
            } else {
                &[]
            };
            for &partial_word_mask in [0].iter().chain(partial_masks) {
                let mut flash = Box::new(base.clone());
                flash.schedule_power_loss(
                    0,
                    Tear {
                        whole_words,
                        partial_word_mask,
                    },
                );
                assert!(block_on(small_store(&mut flash).erase_all()).is_err());
                let outcome = reboot_and_load(&mut flash);
                // Written bytes without an intact record are flagged: the store cannot tell a
                // torn erase from a damaged record.
                flagged += u32::from(outcome.is_corrupt());
                let acceptable = outcome == LoadOutcome::Absent
                    || outcome.is_corrupt()
                    || outcome.stored() == old.as_ref();
                assert!(
                    acceptable,
                    "{prior_saves} prior saves, erase torn after {whole_words} words, mask \
                     {partial_word_mask:#x}: {}",
                    describe(&outcome)
                );
                let next = mixed_spec(4242);
                block_on(small_store(&mut flash).save(&next)).unwrap();
                assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(next));
            }
        }
    }
    println!("torn erase_all: defaults flagged as corrupt in {flagged} cases");
}

/// A load never writes: whatever a torn save left (every operation, every erase pattern), a power
/// loss during the boot that follows cannot change anything; the next save cleans the layout up.
#[test]
fn loading_after_a_torn_save_never_writes() {
    let mut random = Random(0x005E_ED0F_B007);
    let mut loads = 0;
    for prior_saves in 0..=MAX_PRIOR_SAVES {
        let base = flash_after(prior_saves);
        let old = old_spec(prior_saves);
        let new = mixed_spec(2000 + prior_saves);
        let mut operations = 0;
        while let Some(untouched) = torn_save(&base, operations, Tear::NOTHING, &new) {
            for (label, mut flash) in
                sampled_tears(&base, operations, &untouched, &new, &mut random)
            {
                flash.power_cycle();
                let before = flash.snapshot();
                flash.schedule_power_loss(0, Tear::words(1));
                let outcome = block_on(small_store(&mut flash).load(0));
                let context = format!("{prior_saves} prior saves, operation {operations}, {label}");
                assert!(
                    !flash.is_powered_off(),
                    "{context}: the load wrote or erased"
                );
                assert!(
                    flash.snapshot() == before,
                    "{context}: the load changed the flash"
                );
                assert!(
                    verdict(&outcome, &old, &new).is_some(),
                    "{context}: {}",
                    describe(&outcome)
                );
                loads += 1;
            }
            operations += 1;
        }
    }
    println!("loads after a torn save, none of which wrote: {loads}");
}

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

/// How an interrupted page erase leaves the page, besides "erased from the start" (which
/// `RamFlash` tears itself).
#[derive(Debug, Clone, Copy)]
enum ErasePattern {
    /// The last `words` words erased, the rest untouched.
    FromTheEnd { words: usize },
    /// Every bit of the page set with this probability (percent).
    RandomBits { percent: u64 },
}

/// `untouched` is the flash right after a power loss that hit an erase before it changed
/// anything; returns it with the page erased as `pattern` says.
fn erase_partly(
    untouched: &SmallFlash,
    pattern: ErasePattern,
    random: &mut Random,
) -> Box<SmallFlash> {
    let report = untouched.last_power_loss().unwrap();
    assert_eq!(report.kind, OperationKind::Erase);
    let page = report.address as usize..report.address as usize + report.words * 4;
    let mut flash = Box::new(untouched.clone());
    match pattern {
        ErasePattern::FromTheEnd { words } => {
            flash.as_bytes_mut()[page.end - words * 4..page.end].fill(0xFF);
        }
        ErasePattern::RandomBits { percent } => {
            for byte in &mut flash.as_bytes_mut()[page] {
                for bit in 0..8 {
                    if random.next() % 100 < percent {
                        *byte |= 1 << bit;
                    }
                }
            }
        }
    }
    flash
}

/// The proofs above tear an erase from the start of the page onwards, which is what
/// sequential-storage assumes (a page whose start marker is erased but whose end marker is not is
/// "an interrupted erase" and is erased again). The F4 reference manual does not say what an
/// interrupted sector erase leaves, so the same guarantee is checked under two other models:
/// erased from the end backwards (every length), and every bit set with some probability.
#[test]
fn other_interrupted_erase_patterns_give_the_old_or_the_new_spec() {
    let mut random = Random(0x1234_5678_9ABC_DEF1);
    let (mut from_the_end, mut random_bits) = (Tally::default(), Tally::default());
    for prior_saves in 0..=MAX_PRIOR_SAVES {
        let base = flash_after(prior_saves);
        let old = old_spec(prior_saves);
        let new = mixed_spec(3000 + prior_saves);
        let mut operations = 0;
        while let Some(untouched) = torn_save(&base, operations, Tear::NOTHING, &new) {
            operations += 1;
            let report = untouched.last_power_loss().unwrap();
            if report.kind != OperationKind::Erase {
                continue;
            }
            let mut patterns: Vec<ErasePattern> = (1..=report.words)
                .map(|words| ErasePattern::FromTheEnd { words })
                .collect();
            for percent in [1, 10, 50, 90, 99] {
                patterns.extend([ErasePattern::RandomBits { percent }; 50]);
            }
            for pattern in patterns {
                let mut flash = erase_partly(&untouched, pattern, &mut random);
                let context = format!("{prior_saves} prior saves, {pattern:?}");
                let (verdict, _) = check_after_reboot(&mut flash, &old, &new, &context);
                match pattern {
                    ErasePattern::FromTheEnd { .. } => from_the_end.count(verdict),
                    ErasePattern::RandomBits { .. } => random_bits.count(verdict),
                }
                check_next_save(flash, &context);
            }
        }
    }
    println!("erased from the end: {from_the_end}");
    println!("random bits erased: {random_bits}");
    assert!(from_the_end.torn_saves > 0 && random_bits.torn_saves > 0);
    for tally in [&from_the_end, &random_bits] {
        assert_eq!(
            tally.flagged_defaults_after_a_save, 0,
            "a saved calibration was lost"
        );
    }
}

/// A torn save leaves a layout sequential-storage did not expect (a half-erased page next to the
/// page with the newest record); the next save must clean it up without ever exposing an older
/// record, even if it is itself torn, under every erase pattern.
#[test]
fn a_torn_save_after_a_torn_save_gives_what_the_reboot_loaded_or_the_newer_spec() {
    let mut random = Random(0x0DDB_A11C_AFE5_EED5);
    let mut first = Tally::default();
    let mut second = Tally::default();
    let mut second_saves_from_unclean_layouts = 0;
    for prior_saves in 0..=MAX_PRIOR_SAVES {
        let base = flash_after(prior_saves);
        let old = old_spec(prior_saves);
        let new = mixed_spec(6000 + prior_saves);
        let newer = mixed_spec(6100 + prior_saves);
        let mut operations = 0;
        while let Some(untouched) = torn_save(&base, operations, Tear::NOTHING, &new) {
            for (label, mut torn) in sampled_tears(&base, operations, &untouched, &new, &mut random)
            {
                let context = format!(
                    "{prior_saves} prior saves, first save torn at operation \
                                       {operations}: {label}"
                );
                let (verdict, loaded) = check_after_reboot(&mut torn, &old, &new, &context);
                first.count(verdict);
                let unclean = !layout_is_clean(&torn);
                second_saves_from_unclean_layouts += u32::from(unclean);
                // The last completed save: the new spec if it loaded, else the old one.
                let last_saved = if verdict == Verdict::New {
                    Some(new.clone())
                } else {
                    old.clone()
                };
                let mut second_operations = 0;
                while let Some(second_untouched) =
                    torn_save(&torn, second_operations, Tear::NOTHING, &newer)
                {
                    for (second_label, mut twice_torn) in sampled_tears(
                        &torn,
                        second_operations,
                        &second_untouched,
                        &newer,
                        &mut random,
                    ) {
                        let context = format!(
                            "{context}; loaded {}; second save torn at operation \
                             {second_operations}: {second_label}",
                            describe(&loaded)
                        );
                        let (verdict, _) =
                            check_after_reboot(&mut twice_torn, &last_saved, &newer, &context);
                        second.count(verdict);
                        check_next_save(twice_torn, &context);
                    }
                    second_operations += 1;
                }
            }
            operations += 1;
        }
    }
    println!("first torn save: {first}");
    println!(
        "second torn save ({second_saves_from_unclean_layouts} of the first ones left an unclean \
         layout): {second}"
    );
    assert!(second_saves_from_unclean_layouts > 0);
    for tally in [&first, &second] {
        assert_eq!(
            tally.flagged_defaults_after_a_save, 0,
            "a saved calibration was lost"
        );
    }
}

/// A few tears of operation `operations` of a save of `new` from `base` (`untouched`: torn before
/// anything changed): for a write, nothing, half, and all but a half-programmed last word; for an
/// erase, from the start (1 word, half), from the end (1 word, half, all but one word) and random
/// bits (10, 50, 90 %).
fn sampled_tears(
    base: &SmallFlash,
    operations: u32,
    untouched: &SmallFlash,
    new: &CalibrationSpec,
    random: &mut Random,
) -> Vec<(String, Box<SmallFlash>)> {
    let report = untouched.last_power_loss().unwrap();
    let words = report.words;
    let mut tears = vec![Tear::NOTHING, Tear::words(words / 2)];
    let mut patterns = Vec::new();
    match report.kind {
        OperationKind::Write => tears.push(Tear {
            whole_words: words - 1,
            partial_word_mask: 0xFFFF_FFFE,
        }),
        OperationKind::Erase => {
            tears.push(Tear::words(1));
            patterns
                .extend([1, words / 2, words - 1].map(|words| ErasePattern::FromTheEnd { words }));
            patterns.extend([10, 50, 90].map(|percent| ErasePattern::RandomBits { percent }));
        }
    }
    let mut torn: Vec<(String, Box<SmallFlash>)> = tears
        .into_iter()
        .map(|tear| {
            let flash = torn_save(base, operations, tear, new).unwrap();
            (
                format!("{:?} of {words} words, {tear:?}", report.kind),
                flash,
            )
        })
        .collect();
    for pattern in patterns {
        torn.push((
            format!("erase of {words} words, {pattern:?}"),
            erase_partly(untouched, pattern, random),
        ));
    }
    torn
}

/// Whether every byte of one of the two pages is erased (the layout a save leaves when it
/// completes).
fn layout_is_clean(flash: &SmallFlash) -> bool {
    let region = SMALL_RANGE.start as usize..SMALL_RANGE.end as usize;
    let (first, second) = flash.as_bytes()[region].split_at(SMALL_RANGE.len() / 2);
    [first, second]
        .iter()
        .any(|page| page.iter().all(|&byte| byte == 0xFF))
}

fn base_with_history(prior_saves: u32) -> (Box<SmallFlash>, Vec<CalibrationSpec>) {
    let mut flash = small_flash();
    let history: Vec<CalibrationSpec> = (1..=prior_saves + 1).map(mixed_spec).collect();
    for spec in &history {
        block_on(small_store(&mut flash).save(spec)).unwrap();
    }
    (flash, history)
}

fn region_address(flash: &SmallFlash, written: bool, seed: usize) -> usize {
    let region = SMALL_RANGE.start as usize..SMALL_RANGE.end as usize;
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
    let saved = block_on(small_store(flash).save(&next));
    prop_assert!(saved.is_ok(), "save after corruption: {:?}", saved);
    prop_assert_eq!(reboot_and_load(flash), LoadOutcome::Stored(next));
    Ok(())
}

proptest! {
    #![proptest_config(config(400))]

    /// One flipped bit anywhere: the old or the new calibration, or the defaults flagged as
    /// corrupt; never another calibration, never a crash.
    #[test]
    fn a_single_bit_flip_gives_the_old_or_the_new_spec(
        prior_saves in 1..12u32,
        written in any::<bool>(),
        seed in any::<usize>(),
        bit in 0u8..8,
    ) {
        let (mut flash, history) = base_with_history(prior_saves);
        let address = region_address(&flash, written, seed);
        flash.flip_bit(address as u32, bit).unwrap();
        let outcome = reboot_and_load(&mut flash);
        let old = Some(history[history.len() - 2].clone());
        let new = &history[history.len() - 1];
        prop_assert!(
            verdict(&outcome, &old, new).is_some(),
            "bit {} of {:#x}: {}", bit, address, describe(&outcome)
        );
        next_save_heals(&mut flash)?;
    }

    /// Several flips, or an erased range (a truncation-like loss): some calibration that was
    /// saved at some point, Absent or Corrupt; never an unsaved spec, never a crash.
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
            let end = (start + length).min(SMALL_RANGE.end as usize);
            flash.as_bytes_mut()[start..end].fill(0xFF);
        }
        let outcome = reboot_and_load(&mut flash);
        if let LoadOutcome::Stored(spec) = &outcome {
            prop_assert!(history.contains(spec), "an unsaved spec: {}", describe(&outcome));
        }
        next_save_heals(&mut flash)?;
    }
}
