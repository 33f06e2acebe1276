//! Tests of the TMP117 driver against `embedded-hal-mock`, with the register map and
//! register values re-declared here from the datasheet (not taken from the driver).

use embassy_futures::block_on;
use embedded_hal_async::i2c::{ErrorKind, NoAcknowledgeSource};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cTransaction};
use tmp117::{temperature_c_from_register, Address, Error, Tmp117};

const DEFAULT_ADDRESS: u8 = 0x48;

const TEMP_RESULT: u8 = 0x00;
const CONFIGURATION: u8 = 0x01;
const DEVICE_ID: u8 = 0x0F;

fn read(address: u8, register: u8, value: u16) -> I2cTransaction {
    I2cTransaction::write_read(address, vec![register], value.to_be_bytes().to_vec())
}

/// Runs `operation` on a sensor at 0x48 against `expectations` and checks they were all used.
fn with_sensor<T>(
    expectations: &[I2cTransaction],
    operation: impl AsyncFnOnce(&mut Tmp117<I2cMock>) -> T,
) -> T {
    let mut sensor = Tmp117::new(I2cMock::new(expectations), Address::Gnd);
    let result = block_on(operation(&mut sensor));
    sensor.release().done();
    result
}

#[test]
fn init_accepts_the_tmp117_device_id() {
    let result = with_sensor(
        &[read(DEFAULT_ADDRESS, DEVICE_ID, 0x0117)],
        async |sensor| sensor.init().await,
    );
    assert_eq!(result, Ok(()));
}

#[test]
fn init_accepts_any_revision_in_bits_15_to_12() {
    let result = with_sensor(
        &[read(DEFAULT_ADDRESS, DEVICE_ID, 0x2117)],
        async |sensor| sensor.init().await,
    );
    assert_eq!(result, Ok(()));
}

#[test]
fn init_rejects_a_wrong_device_id() {
    // A TMP116 reads 0x1116.
    let result = with_sensor(
        &[read(DEFAULT_ADDRESS, DEVICE_ID, 0x1116)],
        async |sensor| sensor.init().await,
    );
    assert_eq!(result, Err(Error::WrongDeviceId(0x1116)));
}

#[test]
fn nack_is_an_i2c_error() {
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    let result = with_sensor(
        &[read(DEFAULT_ADDRESS, DEVICE_ID, 0).with_error(nack)],
        async |sensor| sensor.init().await,
    );
    assert_eq!(result, Err(Error::I2c(nack)));
}

#[test]
fn address_pin_selects_0x48_to_0x4b() {
    let addresses = [
        (Address::Gnd, 0x48),
        (Address::Vplus, 0x49),
        (Address::Sda, 0x4A),
        (Address::Scl, 0x4B),
    ];
    for (address, seven_bit) in addresses {
        let mut i2c = I2cMock::new(&[read(seven_bit, DEVICE_ID, 0x0117)]);
        let mut sensor = Tmp117::new(i2c.clone(), address);
        assert_eq!(block_on(sensor.init()), Ok(()));
        i2c.done();
    }
    assert_eq!(Address::default(), Address::Gnd);
}

#[test]
fn temperature_conversions() {
    let cases: [(u16, f32); 6] = [
        (0x0C80, 25.0),
        (0x0000, 0.0),
        (0x0001, 0.007_812_5),
        (0xFF80, -1.0),
        (0xFFFF, -0.007_812_5),
        // -55 °C, the bottom of the specified range: -7040 = 0xE480.
        (0xE480, -55.0),
    ];
    for (temp_result, expected_c) in cases {
        let measured_c = with_sensor(
            &[read(DEFAULT_ADDRESS, TEMP_RESULT, temp_result)],
            async |sensor| sensor.read_temperature_c().await,
        );
        assert_eq!(measured_c, Ok(expected_c), "TEMP_RESULT {temp_result:#06x}");
        assert_eq!(temperature_c_from_register(temp_result), Some(expected_c));
    }
}

#[test]
fn reset_value_is_not_ready_rather_than_minus_256_c() {
    let result = with_sensor(
        &[read(DEFAULT_ADDRESS, TEMP_RESULT, 0x8000)],
        async |sensor| sensor.read_temperature_c().await,
    );
    assert_eq!(result, Err(Error::NotReady));
    assert_eq!(temperature_c_from_register(0x8000), None);
    // One LSB above the reset value is a (nonsensical but) real code, not "not ready".
    assert_eq!(temperature_c_from_register(0x8001), Some(-255.992_19));
}

#[test]
fn data_ready_is_bit_13_of_configuration() {
    // Power-on CONFIGURATION is 0x0220; with Data_Ready set it reads 0x2220.
    let result = with_sensor(
        &[
            read(DEFAULT_ADDRESS, CONFIGURATION, 0x2220),
            read(DEFAULT_ADDRESS, CONFIGURATION, 0x0220),
            read(DEFAULT_ADDRESS, CONFIGURATION, 0xDFFF),
        ],
        async |sensor| {
            (
                sensor.data_ready().await,
                sensor.data_ready().await,
                sensor.data_ready().await,
            )
        },
    );
    assert_eq!(result, (Ok(true), Ok(false), Ok(false)));
}
