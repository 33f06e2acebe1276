//! The RAM flash model: NOR rules, F4 alignment, and each injected fault.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{OperationKind, PowerLossReport, RamFlash, RamFlashError, Tear};
use common::block_on;
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};

type Flash = RamFlash<256, 64>;

fn read(flash: &mut Flash, offset: u32, length: usize) -> Vec<u8> {
    let mut bytes = vec![0u8; length];
    block_on(flash.read(offset, &mut bytes)).unwrap();
    bytes
}

#[test]
fn geometry_matches_the_f4_driver() {
    assert_eq!(Flash::READ_SIZE, 1);
    assert_eq!(Flash::WRITE_SIZE, 4);
    assert_eq!(Flash::ERASE_SIZE, 64);
    assert_eq!(Flash::new().capacity(), 256);
}

#[test]
fn starts_erased_and_writes_only_clear_bits() {
    let mut flash = Flash::new();
    assert!(flash.as_bytes().iter().all(|&byte| byte == 0xFF));
    block_on(flash.write(8, &[0x0F, 0xF0, 0x00, 0xFF])).unwrap();
    assert_eq!(read(&mut flash, 7, 6), [0xFF, 0x0F, 0xF0, 0x00, 0xFF, 0xFF]);
    // Clearing more bits of a written word is allowed (MultiwriteNorFlash).
    block_on(flash.write(8, &[0x0E, 0x00, 0x00, 0x7F])).unwrap();
    assert_eq!(read(&mut flash, 8, 4), [0x0E, 0x00, 0x00, 0x7F]);
    assert_eq!(flash.write_count(), 2);
}

#[test]
fn setting_a_bit_without_erase_is_refused_and_changes_nothing() {
    let mut flash = Flash::new();
    block_on(flash.write(4, &[0x00, 0x00, 0x00, 0x00, 0xF0, 0xFF, 0xFF, 0xFF])).unwrap();
    let before = flash.snapshot();
    assert_eq!(
        block_on(flash.write(4, &[0x00, 0x00, 0x00, 0x00, 0xF1, 0xFF, 0xFF, 0xFF])),
        Err(RamFlashError::NotErased { address: 8 })
    );
    assert_eq!(flash.as_bytes(), &before);
}

#[test]
fn misaligned_or_out_of_range_operations_are_refused() {
    let mut flash = Flash::new();
    assert_eq!(
        block_on(flash.write(2, &[0; 4])),
        Err(RamFlashError::NotAligned)
    );
    assert_eq!(
        block_on(flash.write(4, &[0; 6])),
        Err(RamFlashError::NotAligned)
    );
    assert_eq!(
        block_on(flash.write(252, &[0; 8])),
        Err(RamFlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(flash.erase(32, 64)),
        Err(RamFlashError::NotAligned)
    );
    assert_eq!(
        block_on(flash.erase(192, 320)),
        Err(RamFlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(flash.erase(128, 64)),
        Err(RamFlashError::OutOfBounds)
    );
    let mut byte = [0u8; 1];
    assert_eq!(
        block_on(flash.read(256, &mut byte)),
        Err(RamFlashError::OutOfBounds)
    );
    assert!(flash.as_bytes().iter().all(|&byte| byte == 0xFF));
}

#[test]
fn erase_sets_whole_pages_to_ff() {
    let mut flash = Flash::new();
    block_on(flash.write(0, &[0u8; 256])).unwrap();
    block_on(flash.erase(64, 192)).unwrap();
    let bytes = flash.as_bytes();
    assert!(bytes[..64].iter().all(|&byte| byte == 0x00));
    assert!(bytes[64..192].iter().all(|&byte| byte == 0xFF));
    assert!(bytes[192..].iter().all(|&byte| byte == 0x00));
    assert_eq!(flash.erase_count(), 1);
}

#[test]
fn power_loss_tears_a_write_after_the_scheduled_count_and_stays_off() {
    let mut flash = Flash::new();
    flash.schedule_power_loss(1, Tear::words(2));
    block_on(flash.write(0, &[0x11; 4])).unwrap();
    assert_eq!(
        block_on(flash.write(16, &[0x00; 16])),
        Err(RamFlashError::PowerLoss)
    );
    assert_eq!(
        flash.last_power_loss(),
        Some(PowerLossReport {
            kind: OperationKind::Write,
            address: 16,
            words: 4,
            whole_words_done: 2,
        })
    );
    let bytes = flash.snapshot();
    assert_eq!(bytes[..4], [0x11; 4]);
    assert_eq!(bytes[16..24], [0x00; 8]);
    assert_eq!(bytes[24..32], [0xFF; 8]);
    assert!(flash.is_powered_off());
    let mut byte = [0u8; 1];
    assert_eq!(
        block_on(flash.read(0, &mut byte)),
        Err(RamFlashError::PowerLoss)
    );
    assert_eq!(block_on(flash.erase(0, 64)), Err(RamFlashError::PowerLoss));
    assert_eq!(flash.as_bytes(), &bytes);
    flash.power_cycle();
    assert_eq!(read(&mut flash, 16, 16)[..8], [0x00; 8]);
    block_on(flash.write(24, &[0x00; 8])).unwrap();
}

#[test]
fn a_torn_write_never_completes_and_can_half_program_a_word() {
    let mut flash = Flash::new();
    flash.schedule_power_loss(
        0,
        Tear {
            whole_words: usize::MAX,
            partial_word_mask: 0x0000_FF0F,
        },
    );
    assert_eq!(
        block_on(flash.write(0, &[0x00; 12])),
        Err(RamFlashError::PowerLoss)
    );
    assert_eq!(flash.last_power_loss().unwrap().whole_words_done, 2);
    assert_eq!(flash.as_bytes()[..8], [0x00; 8]);
    // Only the masked bits of the last word were programmed.
    assert_eq!(flash.as_bytes()[8..12], [0xF0, 0x00, 0xFF, 0xFF]);
    assert_eq!(flash.write_count(), 0);
}

#[test]
fn a_torn_erase_erases_a_prefix_and_can_half_erase_a_word() {
    let mut flash = Flash::new();
    block_on(flash.write(0, &[0x00; 256])).unwrap();
    flash.schedule_power_loss(
        0,
        Tear {
            whole_words: 5,
            partial_word_mask: 0x8000_0001,
        },
    );
    assert_eq!(
        block_on(flash.erase(64, 192)),
        Err(RamFlashError::PowerLoss)
    );
    assert_eq!(
        flash.last_power_loss(),
        Some(PowerLossReport {
            kind: OperationKind::Erase,
            address: 64,
            words: 32,
            whole_words_done: 5,
        })
    );
    let bytes = flash.as_bytes();
    assert!(bytes[64..84].iter().all(|&byte| byte == 0xFF));
    assert_eq!(bytes[84..88], [0x01, 0x00, 0x00, 0x80]);
    assert!(bytes[88..192].iter().all(|&byte| byte == 0x00));
    assert_eq!(flash.erase_count(), 0);
}

#[test]
fn reads_do_not_count_towards_a_power_loss() {
    let mut flash = Flash::new();
    flash.schedule_power_loss(0, Tear::NOTHING);
    read(&mut flash, 0, 256);
    assert!(!flash.is_powered_off());
    assert_eq!(
        block_on(flash.write(0, &[0; 4])),
        Err(RamFlashError::PowerLoss)
    );
    assert_eq!(flash.as_bytes()[..4], [0xFF; 4]);
}

#[test]
fn bit_flips_snapshots_and_restores() {
    let mut flash = Flash::new();
    let blank = flash.snapshot();
    flash.flip_bit(10, 3).unwrap();
    assert_eq!(flash.as_bytes()[10], 0xF7);
    flash.flip_bit(10, 3).unwrap();
    assert_eq!(flash.as_bytes()[10], 0xFF);
    assert_eq!(flash.flip_bit(256, 0), Err(RamFlashError::OutOfBounds));
    block_on(flash.write(0, &[0; 64])).unwrap();
    let written = flash.clone();
    flash.restore(&blank);
    assert_eq!(flash.as_bytes(), &blank);
    assert_eq!(written.as_bytes()[..64], [0; 64]);
}
