//! Tests of the TCA9548A driver against `embedded-hal-mock`, with the addresses and control
//! register values re-declared here from the datasheet (not taken from the driver).

use embassy_futures::block_on;
use embedded_hal_async::i2c::{Error as _, ErrorKind, NoAcknowledgeSource};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cTransaction};
use tca9548a::{Address, Channel, ChannelMask, Error, Tca9548a};

/// Address with A2 = A1 = A0 = low: fixed bits 1110, then A2 A1 A0 = 000.
const DEFAULT_ADDRESS: u8 = 0x70;

/// Every pin combination (A2, A1, A0) and the address it sets, 0x70 | A2 A1 A0.
const PIN_ADDRESSES: [((bool, bool, bool), u8); 8] = [
    ((false, false, false), 0x70),
    ((false, false, true), 0x71),
    ((false, true, false), 0x72),
    ((false, true, true), 0x73),
    ((true, false, false), 0x74),
    ((true, false, true), 0x75),
    ((true, true, false), 0x76),
    ((true, true, true), 0x77),
];

/// Control register value enabling only channel n: bit n.
const ONLY_CHANNEL: [u8; 8] = [
    0b0000_0001,
    0b0000_0010,
    0b0000_0100,
    0b0000_1000,
    0b0001_0000,
    0b0010_0000,
    0b0100_0000,
    0b1000_0000,
];

/// Writing the control register: the address, then the one data byte (no register address).
fn write_control(address: u8, value: u8) -> I2cTransaction {
    I2cTransaction::write(address, vec![value])
}

/// Reading the control register: the address, then one byte from the mux.
fn read_control(address: u8, value: u8) -> I2cTransaction {
    I2cTransaction::read(address, vec![value])
}

/// Runs `operation` on a mux at 0x70 against `expectations` and checks they were all used.
fn with_mux<T>(
    expectations: &[I2cTransaction],
    operation: impl AsyncFnOnce(&mut Tca9548a<I2cMock>) -> T,
) -> T {
    let mut mux = Tca9548a::new(I2cMock::new(expectations), Address::default());
    let result = block_on(operation(&mut mux));
    mux.release().done();
    result
}

#[test]
fn address_pins_select_0x70_to_0x77() {
    for ((a2, a1, a0), seven_bit) in PIN_ADDRESSES {
        let address = Address::from_pins(a2, a1, a0);
        assert_eq!(address.seven_bit(), seven_bit, "A2 {a2} A1 {a1} A0 {a0}");
        assert_eq!(address.pins(), (a2, a1, a0));
        assert_eq!(Address::new(seven_bit), Some(address));
    }
    assert_eq!(Address::default().seven_bit(), DEFAULT_ADDRESS);
}

#[test]
fn address_outside_0x70_to_0x77_is_refused() {
    assert_eq!(Address::new(0x6F), None);
    assert_eq!(Address::new(0x78), None);
    // The FDC1004 behind the mux and the general-call address are not mux addresses either.
    assert_eq!(Address::new(0x50), None);
    assert_eq!(Address::new(0x00), None);
    let accepted: Vec<u8> = (0..=u8::MAX)
        .filter_map(Address::new)
        .map(Address::seven_bit)
        .collect();
    assert_eq!(
        accepted,
        PIN_ADDRESSES.map(|(_, seven_bit)| seven_bit).to_vec()
    );
}

#[test]
fn every_address_is_the_one_on_the_wire() {
    for ((a2, a1, a0), seven_bit) in PIN_ADDRESSES {
        let mut i2c = I2cMock::new(&[
            write_control(seven_bit, ONLY_CHANNEL[0]),
            read_control(seven_bit, ONLY_CHANNEL[0]),
        ]);
        let mut mux = Tca9548a::new(i2c.clone(), Address::from_pins(a2, a1, a0));
        assert_eq!(mux.address().seven_bit(), seven_bit);
        assert_eq!(block_on(mux.select(Channel::Ch0)), Ok(()));
        assert_eq!(block_on(mux.enabled()), Ok(ChannelMask(ONLY_CHANNEL[0])));
        i2c.done();
    }
}

#[test]
fn new_puts_nothing_on_the_bus() {
    with_mux(&[], async |_| ());
}

#[test]
fn select_writes_only_the_bit_of_the_channel() {
    for (index, only_channel) in (0u8..).zip(ONLY_CHANNEL) {
        let channel = Channel::new(index).expect("0..=7 are channels");
        let result = with_mux(
            &[write_control(DEFAULT_ADDRESS, only_channel)],
            async |mux| mux.select(channel).await,
        );
        assert_eq!(result, Ok(()), "channel {index}");
    }
}

#[test]
fn select_mask_writes_the_mask_as_the_only_byte() {
    for bits in [0b1010_0101, 0b0000_0011, 0xFF, 0x00] {
        let result = with_mux(&[write_control(DEFAULT_ADDRESS, bits)], async |mux| {
            mux.select_mask(ChannelMask(bits)).await
        });
        assert_eq!(result, Ok(()), "mask {bits:#010b}");
    }
}

#[test]
fn disable_all_writes_zero() {
    let result = with_mux(&[write_control(DEFAULT_ADDRESS, 0x00)], async |mux| {
        mux.disable_all().await
    });
    assert_eq!(result, Ok(()));
}

#[test]
fn select_is_written_every_time_because_the_driver_keeps_no_copy() {
    let result = with_mux(
        &[
            write_control(DEFAULT_ADDRESS, ONLY_CHANNEL[5]),
            write_control(DEFAULT_ADDRESS, ONLY_CHANNEL[5]),
        ],
        async |mux| {
            (
                mux.select(Channel::Ch5).await,
                mux.select(Channel::Ch5).await,
            )
        },
    );
    assert_eq!(result, (Ok(()), Ok(())));
}

#[test]
fn enabled_reads_one_byte_of_control_register() {
    let result = with_mux(
        &[
            // Power-on value: all channels off.
            read_control(DEFAULT_ADDRESS, 0x00),
            read_control(DEFAULT_ADDRESS, 0b0010_0100),
        ],
        async |mux| (mux.enabled().await, mux.enabled().await),
    );
    assert_eq!(
        result,
        (Ok(ChannelMask::NONE), Ok(ChannelMask(0b0010_0100)))
    );
}

#[test]
fn select_verified_writes_then_reads_back() {
    let result = with_mux(
        &[
            write_control(DEFAULT_ADDRESS, ONLY_CHANNEL[7]),
            read_control(DEFAULT_ADDRESS, ONLY_CHANNEL[7]),
        ],
        async |mux| mux.select_verified(Channel::Ch7).await,
    );
    assert_eq!(result, Ok(()));
}

#[test]
fn select_verified_reports_a_read_back_mismatch() {
    // A mux reset between write and read reads 0x00; SDA held low reads 0x00 and looks like
    // an ACK; a second channel enabled reads an extra bit.
    for read in [0x00, 0b0000_1100, 0xFF] {
        let result = with_mux(
            &[
                write_control(DEFAULT_ADDRESS, ONLY_CHANNEL[3]),
                read_control(DEFAULT_ADDRESS, read),
            ],
            async |mux| mux.select_verified(Channel::Ch3).await,
        );
        assert_eq!(
            result,
            Err(Error::ReadBack {
                expected: ChannelMask(ONLY_CHANNEL[3]),
                read: ChannelMask(read)
            }),
            "read {read:#04x}"
        );
    }
}

#[test]
fn select_mask_verified_accepts_several_channels_and_reports_a_mismatch() {
    let result = with_mux(
        &[
            write_control(DEFAULT_ADDRESS, 0b1000_0001),
            read_control(DEFAULT_ADDRESS, 0b1000_0001),
            write_control(DEFAULT_ADDRESS, 0x00),
            read_control(DEFAULT_ADDRESS, 0b0000_0001),
        ],
        async |mux| {
            (
                mux.select_mask_verified(ChannelMask(0b1000_0001)).await,
                mux.select_mask_verified(ChannelMask::NONE).await,
            )
        },
    );
    assert_eq!(
        result,
        (
            Ok(()),
            Err(Error::ReadBack {
                expected: ChannelMask::NONE,
                read: ChannelMask(0b0000_0001)
            })
        )
    );
}

#[test]
fn nack_on_write_is_an_i2c_error_and_nothing_is_read_back() {
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    let result = with_mux(
        &[write_control(DEFAULT_ADDRESS, ONLY_CHANNEL[2]).with_error(nack)],
        async |mux| mux.select_verified(Channel::Ch2).await,
    );
    assert_eq!(result, Err(Error::I2c(nack)));

    let result = with_mux(
        &[write_control(DEFAULT_ADDRESS, 0x00).with_error(nack)],
        async |mux| mux.disable_all().await,
    );
    assert_eq!(result, Err(Error::I2c(nack)));
}

#[test]
fn nack_on_read_is_an_i2c_error() {
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    let result = with_mux(
        &[read_control(DEFAULT_ADDRESS, 0x00).with_error(nack)],
        async |mux| mux.enabled().await,
    );
    assert_eq!(result, Err(Error::I2c(nack)));

    let result = with_mux(
        &[
            write_control(DEFAULT_ADDRESS, ONLY_CHANNEL[4]),
            read_control(DEFAULT_ADDRESS, 0x00).with_error(nack),
        ],
        async |mux| mux.select_verified(Channel::Ch4).await,
    );
    assert_eq!(result, Err(Error::I2c(nack)));
}

#[test]
fn error_kind_is_the_bus_kind_or_other_for_a_read_back_mismatch() {
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data);
    assert_eq!(Error::I2c(nack).kind(), nack);
    assert_eq!(
        Error::I2c(ErrorKind::ArbitrationLoss).kind(),
        ErrorKind::ArbitrationLoss
    );
    let read_back: Error<ErrorKind> = Error::ReadBack {
        expected: ChannelMask(ONLY_CHANNEL[1]),
        read: ChannelMask::NONE,
    };
    assert_eq!(read_back.kind(), ErrorKind::Other);
}

#[test]
fn channels_are_0_to_7_and_nothing_else() {
    let indices: Vec<u8> = Channel::ALL.iter().map(|channel| channel.index()).collect();
    assert_eq!(indices, (0..8).collect::<Vec<u8>>());
    for index in 0..=u8::MAX {
        let channel = Channel::new(index);
        assert_eq!(channel.is_some(), index <= 7, "index {index}");
        assert_eq!(channel.map(Channel::index), (index <= 7).then_some(index));
    }
    for (channel, only_channel) in Channel::ALL.into_iter().zip(ONLY_CHANNEL) {
        assert_eq!(channel.mask(), ChannelMask(only_channel));
        assert_eq!(ChannelMask::from(channel), ChannelMask(only_channel));
    }
}

#[test]
fn channel_mask_helpers() {
    assert_eq!(ChannelMask::default(), ChannelMask::NONE);
    assert!(ChannelMask::NONE.is_empty());
    assert!(!ChannelMask::ALL.is_empty());
    assert_eq!(ChannelMask::ALL, ChannelMask(0xFF));

    let mask = ChannelMask::NONE.with(Channel::Ch1).with(Channel::Ch6);
    assert_eq!(mask, ChannelMask(0b0100_0010));
    assert!(mask.contains(Channel::Ch1) && mask.contains(Channel::Ch6));
    assert!(!mask.contains(Channel::Ch0));
    assert_eq!(
        mask.channels().collect::<Vec<_>>(),
        [Channel::Ch1, Channel::Ch6]
    );
    assert_eq!(mask.single_channel(), None);
    assert_eq!(
        mask.without(Channel::Ch1).single_channel(),
        Some(Channel::Ch6)
    );
    assert_eq!(mask.without(Channel::Ch0), mask);
    assert_eq!(ChannelMask::NONE.single_channel(), None);
    assert_eq!(
        ChannelMask::ALL.channels().collect::<Vec<_>>(),
        Channel::ALL
    );
    for channel in Channel::ALL {
        assert_eq!(channel.mask().single_channel(), Some(channel));
    }
}
