//! Tests of the FDC1004 driver against `embedded-hal-mock`, with the register map and
//! register values re-declared here from the datasheet (not taken from the driver).

use embassy_futures::block_on;
use embedded_hal_async::i2c::{ErrorKind, NoAcknowledgeSource};
use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as DelayTransaction};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cTransaction};
use fdc1004::{
    capacitance_pf, conf_meas_value, decode_result, fdc_conf_value, relative_capacitance_pf,
    Channel, Config, Error, Fdc1004, Measurements, Rate, RawCode,
};

const ADDRESS: u8 = 0x50;

const MEAS1_MSB: u8 = 0x00;
const MEAS1_LSB: u8 = 0x01;
const MEAS2_MSB: u8 = 0x02;
const MEAS2_LSB: u8 = 0x03;
const MEAS3_MSB: u8 = 0x04;
const MEAS3_LSB: u8 = 0x05;
const MEAS4_MSB: u8 = 0x06;
const MEAS4_LSB: u8 = 0x07;
const CONF_MEAS1: u8 = 0x08;
const CONF_MEAS2: u8 = 0x09;
const CONF_MEAS3: u8 = 0x0A;
const CONF_MEAS4: u8 = 0x0B;
const FDC_CONF: u8 = 0x0C;
const MANUFACTURER_ID: u8 = 0xFE;
const DEVICE_ID: u8 = 0xFF;

/// FDC_CONF with only RST (bit 15) set.
const FDC_CONF_RESET: u16 = 0x8000;
/// FDC_CONF for 400 S/s: RATE 11 (bits 11:10), REPEAT (bit 8), MEAS_1..4 (bits 7:4).
const FDC_CONF_400_REPEAT_ALL: u16 = 0x0DF0;
/// FDC_CONF for 100 S/s: RATE 01, REPEAT, MEAS_1..4.
const FDC_CONF_100_REPEAT_ALL: u16 = 0x05F0;

/// CONF_MEASn with CHA = CINn (bits 15:13), CHB = CAPDAC (100, bits 12:10), CAPDAC 0.
const CONF_MEAS_CIN1_CAPDAC0: u16 = 0x1000;
const CONF_MEAS_CIN2_CAPDAC0: u16 = 0x3000;
const CONF_MEAS_CIN3_CAPDAC0: u16 = 0x5000;
const CONF_MEAS_CIN4_CAPDAC0: u16 = 0x7000;
/// The same with the CAPDAC values 0, 5, 17, 31 in bits 9:5.
const CONF_MEAS_CIN2_CAPDAC5: u16 = 0x30A0;
const CONF_MEAS_CIN3_CAPDAC17: u16 = 0x5220;
const CONF_MEAS_CIN4_CAPDAC31: u16 = 0x73E0;

const POWER_UP_DELAY_US: u32 = 5_000;
const RESET_POLL_INTERVAL_US: u32 = 100;
const DONE_POLL_INTERVAL_US: u32 = 500;

fn read(register: u8, value: u16) -> I2cTransaction {
    I2cTransaction::write_read(ADDRESS, vec![register], value.to_be_bytes().to_vec())
}

fn write(register: u8, value: u16) -> I2cTransaction {
    let [high, low] = value.to_be_bytes();
    I2cTransaction::write(ADDRESS, vec![register, high, low])
}

fn config_400_mixed_capdac() -> Config {
    Config {
        rate: Rate::Hz400,
        capdac: [0, 5, 17, 31],
        done_timeout_us: 2_000,
        power_up_delay_us: POWER_UP_DELAY_US,
    }
}

/// The whole bus traffic of a successful `init` with `config_400_mixed_capdac`.
fn successful_init_transactions() -> Vec<I2cTransaction> {
    vec![
        write(FDC_CONF, FDC_CONF_RESET),
        read(FDC_CONF, FDC_CONF_RESET),
        read(FDC_CONF, 0x0000),
        read(MANUFACTURER_ID, 0x5449),
        read(DEVICE_ID, 0x1004),
        write(CONF_MEAS1, CONF_MEAS_CIN1_CAPDAC0),
        read(CONF_MEAS1, CONF_MEAS_CIN1_CAPDAC0),
        write(CONF_MEAS2, CONF_MEAS_CIN2_CAPDAC5),
        read(CONF_MEAS2, CONF_MEAS_CIN2_CAPDAC5),
        write(CONF_MEAS3, CONF_MEAS_CIN3_CAPDAC17),
        read(CONF_MEAS3, CONF_MEAS_CIN3_CAPDAC17),
        write(CONF_MEAS4, CONF_MEAS_CIN4_CAPDAC31),
        read(CONF_MEAS4, CONF_MEAS_CIN4_CAPDAC31),
        write(FDC_CONF, FDC_CONF_400_REPEAT_ALL),
        // DONE_1 and DONE_4 already set: the read-back check must ignore bits 3:0.
        read(FDC_CONF, FDC_CONF_400_REPEAT_ALL | 0b1001),
    ]
}

/// Delays of a successful `init` whose RST bit clears on the second poll.
fn successful_init_delays() -> Vec<DelayTransaction> {
    vec![
        DelayTransaction::async_delay_us(POWER_UP_DELAY_US),
        DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US),
        DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US),
    ]
}

/// Reads of the eight result registers, MSB before LSB, measurement 1 first.
fn result_reads(msb_lsb: [(u16, u16); 4]) -> Vec<I2cTransaction> {
    let registers = [
        (MEAS1_MSB, MEAS1_LSB),
        (MEAS2_MSB, MEAS2_LSB),
        (MEAS3_MSB, MEAS3_LSB),
        (MEAS4_MSB, MEAS4_LSB),
    ];
    registers
        .iter()
        .zip(msb_lsb)
        .flat_map(|(&(msb_register, lsb_register), (msb, lsb))| {
            [read(msb_register, msb), read(lsb_register, lsb)]
        })
        .collect()
}

/// Runs `init` against the given expectations, checks every mock is consumed, returns the result.
fn init_with(
    config: Config,
    i2c_expectations: &[I2cTransaction],
    delay_expectations: &[DelayTransaction],
) -> Result<(), Error<ErrorKind>> {
    let mut converter = Fdc1004::new(
        I2cMock::new(i2c_expectations),
        CheckedDelay::new(delay_expectations),
        config,
    );
    let result = block_on(converter.init());
    let (mut i2c, mut delay) = converter.release();
    i2c.done();
    delay.done();
    result
}

#[test]
fn init_resets_checks_ids_and_writes_then_verifies_every_configuration_register() {
    let result = init_with(
        config_400_mixed_capdac(),
        &successful_init_transactions(),
        &successful_init_delays(),
    );
    assert_eq!(result, Ok(()));
}

#[test]
fn reinit_repeats_the_whole_init_sequence() {
    let mut i2c_expectations = successful_init_transactions();
    i2c_expectations.extend(successful_init_transactions());
    let mut delay_expectations = successful_init_delays();
    delay_expectations.extend(successful_init_delays());
    let mut converter = Fdc1004::new(
        I2cMock::new(&i2c_expectations),
        CheckedDelay::new(&delay_expectations),
        config_400_mixed_capdac(),
    );
    assert_eq!(block_on(converter.init()), Ok(()));
    assert_eq!(block_on(converter.reinit()), Ok(()));
    let (mut i2c, mut delay) = converter.release();
    i2c.done();
    delay.done();
}

#[test]
fn nack_on_the_first_write_is_an_i2c_error() {
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    let result = init_with(
        Config::default(),
        &[write(FDC_CONF, FDC_CONF_RESET).with_error(nack)],
        &[DelayTransaction::async_delay_us(POWER_UP_DELAY_US)],
    );
    assert_eq!(result, Err(Error::I2c(nack)));
}

#[test]
fn wrong_manufacturer_id_is_rejected_before_any_configuration_write() {
    let result = init_with(
        Config::default(),
        &[
            write(FDC_CONF, FDC_CONF_RESET),
            read(FDC_CONF, 0x0000),
            read(MANUFACTURER_ID, 0xFFFF),
            read(DEVICE_ID, 0x1004),
        ],
        &[
            DelayTransaction::async_delay_us(POWER_UP_DELAY_US),
            DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US),
        ],
    );
    assert_eq!(
        result,
        Err(Error::WrongDeviceId {
            manufacturer: 0xFFFF,
            device: 0x1004
        })
    );
}

#[test]
fn wrong_device_id_is_rejected() {
    let result = init_with(
        Config::default(),
        &[
            write(FDC_CONF, FDC_CONF_RESET),
            read(FDC_CONF, 0x0000),
            read(MANUFACTURER_ID, 0x5449),
            // Another TI part answering at 0x50 (FDC2214-style ID).
            read(DEVICE_ID, 0x3055),
        ],
        &[
            DelayTransaction::async_delay_us(POWER_UP_DELAY_US),
            DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US),
        ],
    );
    assert_eq!(
        result,
        Err(Error::WrongDeviceId {
            manufacturer: 0x5449,
            device: 0x3055
        })
    );
}

#[test]
fn reset_bit_that_never_clears_is_a_reset_timeout_after_ten_polls() {
    let mut i2c_expectations = vec![write(FDC_CONF, FDC_CONF_RESET)];
    let mut delay_expectations = vec![DelayTransaction::async_delay_us(POWER_UP_DELAY_US)];
    for _ in 0..10 {
        delay_expectations.push(DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US));
        i2c_expectations.push(read(FDC_CONF, FDC_CONF_RESET));
    }
    let result = init_with(Config::default(), &i2c_expectations, &delay_expectations);
    assert_eq!(result, Err(Error::ResetTimeout));
}

#[test]
fn shifted_channel_order_is_caught_by_the_configuration_read_back() {
    // After an MCU-only reset users saw measurement n report channel n+1: here CONF_MEAS1
    // reads back what was meant for CONF_MEAS2.
    let result = init_with(
        Config::default(),
        &[
            write(FDC_CONF, FDC_CONF_RESET),
            read(FDC_CONF, 0x0000),
            read(MANUFACTURER_ID, 0x5449),
            read(DEVICE_ID, 0x1004),
            write(CONF_MEAS1, CONF_MEAS_CIN1_CAPDAC0),
            read(CONF_MEAS1, CONF_MEAS_CIN2_CAPDAC0),
        ],
        &[
            DelayTransaction::async_delay_us(POWER_UP_DELAY_US),
            DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US),
        ],
    );
    assert_eq!(
        result,
        Err(Error::ConfigMismatch {
            register: CONF_MEAS1,
            wrote: CONF_MEAS_CIN1_CAPDAC0,
            read: CONF_MEAS_CIN2_CAPDAC0
        })
    );
}

#[test]
fn fdc_conf_read_back_mismatch_is_reported() {
    let result = init_with(
        Config::default(),
        &[
            write(FDC_CONF, FDC_CONF_RESET),
            read(FDC_CONF, 0x0000),
            read(MANUFACTURER_ID, 0x5449),
            read(DEVICE_ID, 0x1004),
            write(CONF_MEAS1, CONF_MEAS_CIN1_CAPDAC0),
            read(CONF_MEAS1, CONF_MEAS_CIN1_CAPDAC0),
            write(CONF_MEAS2, CONF_MEAS_CIN2_CAPDAC0),
            read(CONF_MEAS2, CONF_MEAS_CIN2_CAPDAC0),
            write(CONF_MEAS3, CONF_MEAS_CIN3_CAPDAC0),
            read(CONF_MEAS3, CONF_MEAS_CIN3_CAPDAC0),
            write(CONF_MEAS4, CONF_MEAS_CIN4_CAPDAC0),
            read(CONF_MEAS4, CONF_MEAS_CIN4_CAPDAC0),
            write(FDC_CONF, FDC_CONF_100_REPEAT_ALL),
            // REPEAT did not stick.
            read(FDC_CONF, 0x04F0),
        ],
        &[
            DelayTransaction::async_delay_us(POWER_UP_DELAY_US),
            DelayTransaction::async_delay_us(RESET_POLL_INTERVAL_US),
        ],
    );
    assert_eq!(
        result,
        Err(Error::ConfigMismatch {
            register: FDC_CONF,
            wrote: FDC_CONF_100_REPEAT_ALL,
            read: 0x04F0
        })
    );
}

#[test]
fn capdac_above_31_is_rejected_without_bus_traffic() {
    let config = Config {
        capdac: [0, 0, 32, 0],
        ..Config::default()
    };
    assert_eq!(init_with(config, &[], &[]), Err(Error::InvalidConfig));
    assert!(Config {
        capdac: [31; 4],
        ..Config::default()
    }
    .validate()
    .is_ok());
}

#[test]
fn default_config_matches_the_documented_values() {
    let config = Config::default();
    assert_eq!(config.rate, Rate::Hz100);
    assert_eq!(config.capdac, [0; 4]);
    assert_eq!(config.power_up_delay_us, 5_000);
    // Four measurements at 100 S/s take 40 ms; the timeout must be longer.
    assert!(config.done_timeout_us > 40_000);
}

/// Samples per second of each rate and the time four measurements take at it in repeat mode
/// (datasheet: each conversion takes 1/rate), re-declared here.
const RATES_AND_FOUR_CONVERSIONS_US: [(Rate, u32); 3] = [
    (Rate::Hz100, 4 * 1_000_000 / 100),
    (Rate::Hz200, 4 * 1_000_000 / 200),
    (Rate::Hz400, 4 * 1_000_000 / 400),
];

#[test]
fn every_rate_has_a_done_timeout_longer_than_four_conversions() {
    assert_eq!(
        Rate::ALL.to_vec(),
        RATES_AND_FOUR_CONVERSIONS_US.map(|(rate, _)| rate).to_vec()
    );
    for (rate, four_conversions_us) in RATES_AND_FOUR_CONVERSIONS_US {
        assert_eq!(rate.cycle_time_us(), four_conversions_us, "{rate:?}");
        let timeout_us = rate.done_timeout_us();
        // At least a quarter more than the cycle, for the converter's oscillator tolerance and
        // the bus traffic between polls; at most four cycles, so a lock-up is seen quickly.
        assert!(
            timeout_us >= four_conversions_us * 5 / 4,
            "{rate:?}: {timeout_us} us"
        );
        assert!(
            timeout_us <= four_conversions_us * 4,
            "{rate:?}: {timeout_us} us"
        );
    }
}

#[test]
fn the_done_timeout_follows_the_rate_however_the_config_is_made() {
    for rate in Rate::ALL {
        assert_eq!(
            Config::new(rate, [3; 4]).done_timeout_us,
            rate.done_timeout_us()
        );
        for from in Rate::ALL {
            let config = Config::new(from, [0, 5, 17, 31]).with_rate(rate);
            assert_eq!(config.rate, rate);
            assert_eq!(config.done_timeout_us, rate.done_timeout_us());
            assert_eq!(config.capdac, [0, 5, 17, 31]);
            assert_eq!(config.power_up_delay_us, POWER_UP_DELAY_US);
        }
    }
    assert_eq!(Config::default(), Config::new(Rate::Hz100, [0; 4]));
}

#[test]
fn reading_waits_for_done_up_to_the_timeout_of_the_rate() {
    // DONE_1..3 set, DONE_4 never: reads every 500 us until the rate's whole timeout has passed.
    for rate in Rate::ALL {
        let config = Config::new(rate, [0; 4]);
        let polls = (config.done_timeout_us / DONE_POLL_INTERVAL_US) as usize;
        let fdc_conf = fdc_conf_value(rate) | 0b1110;
        let result = read_measurements_with(
            config,
            &vec![read(FDC_CONF, fdc_conf); polls + 1],
            &vec![DelayTransaction::async_delay_us(DONE_POLL_INTERVAL_US); polls],
        );
        assert_eq!(
            result,
            Err(Error::DoneTimeout { done_bits: 0b1110 }),
            "{rate:?}"
        );
    }
}

/// Runs `read_measurements` against the given expectations and checks every mock is consumed.
fn read_measurements_with(
    config: Config,
    i2c_expectations: &[I2cTransaction],
    delay_expectations: &[DelayTransaction],
) -> Result<Measurements, Error<ErrorKind>> {
    let mut converter = Fdc1004::new(
        I2cMock::new(i2c_expectations),
        CheckedDelay::new(delay_expectations),
        config,
    );
    let result = block_on(converter.read_measurements());
    let (mut i2c, mut delay) = converter.release();
    i2c.done();
    delay.done();
    result
}

#[test]
fn done_never_set_is_a_done_timeout_after_exactly_the_configured_time() {
    // Timeout 2000 us, poll every 500 us: reads at 0, 500, 1000, 1500 and 2000 us.
    let only_done_1_and_3 = FDC_CONF_400_REPEAT_ALL | 0b1010;
    let i2c_expectations = vec![read(FDC_CONF, only_done_1_and_3); 5];
    let delay_expectations = vec![DelayTransaction::async_delay_us(DONE_POLL_INTERVAL_US); 4];
    let result = read_measurements_with(
        config_400_mixed_capdac(),
        &i2c_expectations,
        &delay_expectations,
    );
    assert_eq!(result, Err(Error::DoneTimeout { done_bits: 0b1010 }));
}

#[test]
fn done_timeout_that_is_not_a_multiple_of_the_poll_interval_is_not_overshot() {
    let config = Config {
        done_timeout_us: 1_200,
        ..config_400_mixed_capdac()
    };
    let result = read_measurements_with(
        config,
        &vec![read(FDC_CONF, FDC_CONF_400_REPEAT_ALL); 4],
        &[
            DelayTransaction::async_delay_us(500),
            DelayTransaction::async_delay_us(500),
            DelayTransaction::async_delay_us(200),
        ],
    );
    assert_eq!(result, Err(Error::DoneTimeout { done_bits: 0 }));
}

#[test]
fn full_read_waits_for_all_done_bits_and_sign_extends_every_result() {
    let mut i2c_expectations = vec![
        read(FDC_CONF, FDC_CONF_400_REPEAT_ALL | 0b1110),
        read(FDC_CONF, FDC_CONF_400_REPEAT_ALL | 0b1111),
    ];
    i2c_expectations.extend(result_reads([
        // 0x7FFFFF: saturated high.
        (0x7FFF, 0xFF00),
        // 0x800000: saturated low.
        (0x8000, 0x0000),
        // 0xFFFFFF = -1; the low byte of the LSB register is not part of the result.
        (0xFFFF, 0xFF5A),
        // 0x240000 = 2359296 = 4.5 pF x 2^19.
        (0x2400, 0x0000),
    ]));
    let measurements = read_measurements_with(
        config_400_mixed_capdac(),
        &i2c_expectations,
        &[DelayTransaction::async_delay_us(DONE_POLL_INTERVAL_US)],
    )
    .expect("all four DONE bits were set");
    assert_eq!(
        measurements.codes,
        [
            RawCode(8_388_607),
            RawCode(-8_388_608),
            RawCode(-1),
            RawCode(2_359_296)
        ]
    );
    let saturated: Vec<bool> = measurements
        .codes
        .iter()
        .map(|code| code.is_saturated())
        .collect();
    assert_eq!(saturated, [true, true, false, false]);
    assert!(measurements.any_saturated());
    assert!(!measurements.all_zero());
    assert_eq!(capacitance_pf(measurements.codes[3], 0), 4.5);
}

#[test]
fn all_zero_read_is_detected() {
    let mut i2c_expectations = vec![read(FDC_CONF, FDC_CONF_400_REPEAT_ALL | 0b1111)];
    i2c_expectations.extend(result_reads([(0, 0); 4]));
    let measurements = read_measurements_with(config_400_mixed_capdac(), &i2c_expectations, &[])
        .expect("all four DONE bits were set");
    assert!(measurements.all_zero());
    assert!(!measurements.any_saturated());

    let one_nonzero = Measurements {
        codes: [RawCode(0), RawCode(0), RawCode(1), RawCode(0)],
    };
    assert!(!one_nonzero.all_zero());
}

#[test]
fn i2c_error_while_reading_results_is_reported() {
    let mut i2c_expectations = vec![read(FDC_CONF, FDC_CONF_400_REPEAT_ALL | 0b1111)];
    i2c_expectations.push(read(MEAS1_MSB, 0x1234));
    i2c_expectations.push(read(MEAS1_LSB, 0).with_error(ErrorKind::ArbitrationLoss));
    let result = read_measurements_with(config_400_mixed_capdac(), &i2c_expectations, &[]);
    assert_eq!(result, Err(Error::I2c(ErrorKind::ArbitrationLoss)));
}

#[test]
fn decode_result_assembles_and_sign_extends_24_bits() {
    assert_eq!(decode_result(0x7FFF, 0xFF00), RawCode(0x7F_FFFF));
    assert_eq!(decode_result(0x8000, 0x0000), RawCode(-8_388_608));
    assert_eq!(decode_result(0xFFFF, 0xFF00), RawCode(-1));
    assert_eq!(decode_result(0x0000, 0x0000), RawCode(0));
    assert_eq!(decode_result(0x0000, 0x0100), RawCode(1));
    assert_eq!(decode_result(0x1234, 0x5600), RawCode(0x12_3456));
    assert_eq!(decode_result(0x0000, 0x00FF), RawCode(0));
    assert!(RawCode(0x7F_FFFF).is_saturated());
    assert!(RawCode(-8_388_608).is_saturated());
    assert!(!RawCode(0x7F_FFFE).is_saturated());
    assert!(!RawCode(-8_388_607).is_saturated());
}

#[test]
fn register_values_match_the_datasheet_layout() {
    assert_eq!(conf_meas_value(Channel::Cin1, 0), CONF_MEAS_CIN1_CAPDAC0);
    assert_eq!(conf_meas_value(Channel::Cin2, 0), CONF_MEAS_CIN2_CAPDAC0);
    assert_eq!(conf_meas_value(Channel::Cin3, 0), CONF_MEAS_CIN3_CAPDAC0);
    assert_eq!(conf_meas_value(Channel::Cin4, 0), CONF_MEAS_CIN4_CAPDAC0);
    assert_eq!(conf_meas_value(Channel::Cin2, 5), CONF_MEAS_CIN2_CAPDAC5);
    assert_eq!(conf_meas_value(Channel::Cin3, 17), CONF_MEAS_CIN3_CAPDAC17);
    assert_eq!(conf_meas_value(Channel::Cin4, 31), CONF_MEAS_CIN4_CAPDAC31);
    assert_eq!(fdc_conf_value(Rate::Hz100), FDC_CONF_100_REPEAT_ALL);
    assert_eq!(fdc_conf_value(Rate::Hz200), 0x09F0);
    assert_eq!(fdc_conf_value(Rate::Hz400), FDC_CONF_400_REPEAT_ALL);
}

#[test]
fn capacitance_conversion_matches_hand_computed_values() {
    // 1 code = 2^-19 pF = 1.907 aF.
    let one_code_pf = capacitance_pf(RawCode(1), 0);
    assert_eq!(one_code_pf, 1.0 / 524_288.0);
    assert!((one_code_pf * 1.0e6 - 1.907).abs() < 0.0005);

    assert_eq!(capacitance_pf(RawCode(0), 0), 0.0);
    // 8388607 / 524288 = 15.999998092651367, the f32 nearest to the literal below.
    assert_eq!(capacitance_pf(RawCode(0x7F_FFFF), 0), 15.999_998);
    assert_eq!(capacitance_pf(RawCode(-8_388_608), 0), -16.0);
    // -1048576 / 524288 + 4 x 3.125 = -2 + 12.5.
    assert_eq!(capacitance_pf(RawCode(-1_048_576), 4), 10.5);
    assert_eq!(capacitance_pf(RawCode(0), 31), 96.875);
    assert_eq!(capacitance_pf(RawCode(-8_388_608), 31), 80.875);
    // 1572864 / 524288 + 3.125 = 3 + 3.125.
    assert_eq!(capacitance_pf(RawCode(1_572_864), 1), 6.125);
}

#[test]
fn one_code_at_capdac_31_is_resolved_in_the_code_domain_not_in_absolute_f32_picofarads() {
    let base = RawCode(0);
    let next = RawCode(1);
    assert_ne!(base, next);
    assert_eq!(next.0 - base.0, 1);
    // Relative to the offset the step is exact: 2^-19 pF.
    assert_eq!(
        relative_capacitance_pf(next) - relative_capacitance_pf(base),
        1.0 / 524_288.0
    );
    // Near 96.875 pF one f32 step is 2^-17 pF = 4 codes, so one code vanishes in the sum...
    assert_eq!(capacitance_pf(next, 31), capacitance_pf(base, 31));
    // ...while four codes are still one f32 step.
    assert_eq!(
        capacitance_pf(RawCode(4), 31) - capacitance_pf(base, 31),
        1.0 / 131_072.0
    );
}

/// `answers` is one read of the manufacturer ID, with no wait: true for Texas Instruments'
/// 0x5449, false for another value, the bus error for a NACK.
#[test]
fn answers_reads_the_manufacturer_id_without_waiting() {
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    let mut converter = Fdc1004::new(
        I2cMock::new(&[
            read(MANUFACTURER_ID, 0x5449),
            read(MANUFACTURER_ID, 0xFFFF),
            read(MANUFACTURER_ID, 0).with_error(nack),
        ]),
        CheckedDelay::new(&[]),
        Config::default(),
    );
    assert_eq!(block_on(converter.answers()), Ok(true));
    assert_eq!(block_on(converter.answers()), Ok(false));
    assert_eq!(block_on(converter.answers()), Err(Error::I2c(nack)));
    let (mut i2c, mut delay) = converter.release();
    i2c.done();
    delay.done();
}
