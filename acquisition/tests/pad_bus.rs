//! Several pads on one bus, against `embedded-hal-mock`: the bytes of the multiplexer's control
//! register (TCA9548A datasheet: one byte, bit n = channel n, no register pointer) and of the
//! identification registers (FDC1004: 0xFE = 0x5449, 0xFF = 0x1004; TMP117: 0x0F = 0x0117),
//! re-declared here rather than taken from the code under test.

// Test helpers may unwrap: a failure is the test failing.
#![allow(clippy::unwrap_used)]

use acquisition::discovery::{discover, PadSlot, PadTemperature};
use acquisition::pad_bus::{MuxedBus, PadBus, PadBusError};
use embassy_futures::block_on;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;
use embedded_hal_async::i2c::{ErrorKind, I2c, NoAcknowledgeSource};
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::i2c::{Mock, Transaction};
use tca9548a::{Address, Channel};

const MUX: u8 = 0x70;
const FDC1004: u8 = 0x50;
const NACK: ErrorKind = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);

fn select(mask: u8) -> Transaction {
    Transaction::write(MUX, vec![mask])
}

fn read_register(address: u8, register: u8, value: u16) -> Transaction {
    Transaction::write_read(address, vec![register], value.to_be_bytes().to_vec())
}

fn absent(address: u8, register: u8) -> Transaction {
    read_register(address, register, 0).with_error(NACK)
}

#[test]
fn a_pad_selects_its_channel_only_when_it_changes_and_again_after_a_failure() {
    let mock = Mock::new(&[
        select(1 << 2),
        read_register(FDC1004, 0xFF, 0x1004),
        read_register(FDC1004, 0xFF, 0x1004),
        select(1 << 5),
        read_register(FDC1004, 0xFE, 0x5449),
        // A failed transfer: the next one selects again (the mux may have reset).
        absent(FDC1004, 0x00),
        select(1 << 5),
        read_register(FDC1004, 0x00, 0x1234),
        // The mux itself does not answer: a selection error, nothing sent to the pad.
        select(1 << 2).with_error(NACK),
    ]);
    let shared = Mutex::<NoopRawMutex, _>::new(MuxedBus::new(mock, Some(Address::default())));
    let mut pad2 = PadBus::new(&shared, Some(Channel::Ch2));
    let mut pad5 = PadBus::new(&shared, Some(Channel::Ch5));
    let mut bytes = [0u8; 2];
    block_on(async {
        pad2.write_read(FDC1004, &[0xFF], &mut bytes).await.unwrap();
        pad2.write_read(FDC1004, &[0xFF], &mut bytes).await.unwrap();
        pad5.write_read(FDC1004, &[0xFE], &mut bytes).await.unwrap();
        assert_eq!(
            pad5.write_read(FDC1004, &[0x00], &mut bytes).await,
            Err(PadBusError::Bus(NACK))
        );
        pad5.write_read(FDC1004, &[0x00], &mut bytes).await.unwrap();
        assert_eq!(bytes, [0x12, 0x34]);
        assert!(matches!(
            pad2.write_read(FDC1004, &[0xFF], &mut bytes).await,
            Err(PadBusError::Select(tca9548a::Error::I2c(NACK)))
        ));
    });
    shared.into_inner().bus_mut().done();
}

#[test]
fn without_a_multiplexer_the_pad_talks_to_the_bus_directly() {
    let mock = Mock::new(&[read_register(FDC1004, 0xFF, 0x1004)]);
    let shared = Mutex::<NoopRawMutex, _>::new(MuxedBus::new(mock, None));
    let mut pad = PadBus::new(&shared, None);
    let mut bytes = [0u8; 2];
    block_on(pad.write_read(FDC1004, &[0xFF], &mut bytes)).unwrap();
    shared.into_inner().bus_mut().done();
}

/// The probe of every TMP117 address (0x48..0x4B), `found` answering.
fn tmp117_probe(found: Option<u8>, except: Option<u8>) -> Vec<Transaction> {
    let mut probe = Vec::new();
    for address in 0x48..=0x4B {
        if Some(address) == except {
            continue;
        }
        if Some(address) == found {
            probe.push(read_register(address, 0x0F, 0x0117));
            return probe;
        }
        probe.push(absent(address, 0x0F));
    }
    probe
}

#[test]
fn no_multiplexer_means_one_pad_on_the_bus_even_if_its_converter_is_silent() {
    let mut expectations = vec![Transaction::write(MUX, vec![0]).with_error(NACK)];
    expectations.extend(tmp117_probe(Some(0x48), None));
    let mut mock = Mock::new(&expectations);
    let topology = block_on(discover(&mut mock, &mut NoopDelay, Address::default()));
    assert_eq!(topology.mux, None);
    assert_eq!(
        topology.pads.as_slice(),
        [PadSlot {
            channel: None,
            temperature: PadTemperature::Shared(tmp117::Address::Gnd)
        }]
    );
    mock.done();
}

#[test]
fn pads_are_the_channels_whose_converter_identifies_itself() {
    // Shared TMP117 at 0x49 on the main bus; pads on channels 1 (with its own TMP117 at 0x48),
    // 4 (without), 6 (a different chip at 0x50: not a pad); channel 7's switch is stuck open
    // (the read-back differs), so it is skipped.
    let mut expectations = vec![select(0), Transaction::read(MUX, vec![0])];
    expectations.extend(tmp117_probe(Some(0x49), None));
    // No converter with every channel off.
    expectations.push(absent(FDC1004, 0xFE));
    expectations.push(absent(FDC1004, 0xFF));
    for channel in 0..8u8 {
        let mask = 1 << channel;
        expectations.push(select(mask));
        if channel == 7 {
            expectations.push(Transaction::read(MUX, vec![0]));
            continue;
        }
        expectations.push(Transaction::read(MUX, vec![mask]));
        match channel {
            1 | 4 => {
                expectations.push(read_register(FDC1004, 0xFE, 0x5449));
                expectations.push(read_register(FDC1004, 0xFF, 0x1004));
                let own = (channel == 1).then_some(0x48);
                expectations.extend(tmp117_probe(own, Some(0x49)));
            }
            6 => {
                expectations.push(read_register(FDC1004, 0xFE, 0x5449));
                expectations.push(read_register(FDC1004, 0xFF, 0x1008));
            }
            _ => {
                expectations.push(absent(FDC1004, 0xFE));
                expectations.push(absent(FDC1004, 0xFF));
            }
        }
    }
    expectations.push(select(0));
    let mut mock = Mock::new(&expectations);
    let topology = block_on(discover(&mut mock, &mut NoopDelay, Address::default()));
    assert_eq!(topology.mux, Some(Address::default()));
    assert_eq!(
        topology.pads.as_slice(),
        [
            PadSlot {
                channel: Some(Channel::Ch1),
                temperature: PadTemperature::Own(tmp117::Address::Gnd)
            },
            PadSlot {
                channel: Some(Channel::Ch4),
                temperature: PadTemperature::Shared(tmp117::Address::Vplus)
            },
        ]
    );
    mock.done();
}

#[test]
fn a_converter_upstream_of_the_multiplexer_is_the_only_pad() {
    // It answers with every channel off, so it would answer on every channel: not 8 pads.
    let mut expectations = vec![select(0), Transaction::read(MUX, vec![0])];
    expectations.extend(tmp117_probe(None, None));
    expectations.push(read_register(FDC1004, 0xFE, 0x5449));
    expectations.push(read_register(FDC1004, 0xFF, 0x1004));
    let mut mock = Mock::new(&expectations);
    let topology = block_on(discover(&mut mock, &mut NoopDelay, Address::default()));
    assert_eq!(
        topology.pads.as_slice(),
        [PadSlot {
            channel: None,
            temperature: PadTemperature::DieOnly
        }]
    );
    mock.done();
}

#[test]
fn pads_can_share_the_bus_by_reference_counting() {
    // The simulated device owns its bus: its pads hold reference-counted handles.
    let mock = Mock::new(&[select(1 << 3), read_register(FDC1004, 0xFF, 0x1004)]);
    let shared = std::rc::Rc::new(Mutex::<NoopRawMutex, _>::new(MuxedBus::new(
        mock,
        Some(Address::default()),
    )));
    let mut pad = PadBus::new(std::rc::Rc::clone(&shared), Some(Channel::Ch3));
    let mut bytes = [0u8; 2];
    block_on(pad.write_read(FDC1004, &[0xFF], &mut bytes)).unwrap();
    assert_eq!(pad.channel(), Some(Channel::Ch3));
    drop(pad);
    std::rc::Rc::try_unwrap(shared)
        .ok()
        .unwrap()
        .into_inner()
        .bus_mut()
        .done();
}
