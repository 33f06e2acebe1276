//! The register-level protocol of both simulated devices, driven by raw I2C transactions.

mod common;

use common::*;
use embassy_futures::block_on;
use embedded_hal_async::i2c::{Error, ErrorKind, I2c, NoAcknowledgeSource, Operation};
use sensor_sim::{ScenePoint, ScriptedScene, Simulation, SimulationConfig};

fn powered_simulation(config: SimulationConfig) -> TestResult<Simulation> {
    let simulation = Simulation::new(config)?;
    simulation.advance_us(POWERED_UP_US);
    Ok(simulation)
}

#[test]
fn fdc1004_identifies_itself_and_starts_at_reset_values() {
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    assert_eq!(
        read_register(&mut bus, FDC1004, MANUFACTURER_ID),
        Ok(0x5449)
    );
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    for pointer in CONF_MEAS {
        assert_eq!(read_register(&mut bus, FDC1004, pointer), Ok(0x1C00));
    }
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x0000));
    for pointer in OFFSET_CAL_CIN1..GAIN_CAL_CIN1 {
        assert_eq!(read_register(&mut bus, FDC1004, pointer), Ok(0x0000));
    }
    for pointer in GAIN_CAL_CIN1..=GAIN_CAL_CIN4 {
        assert_eq!(read_register(&mut bus, FDC1004, pointer), Ok(0x4000));
    }
    for pointer in 0x00..0x08 {
        assert_eq!(read_register(&mut bus, FDC1004, pointer), Ok(0x0000));
    }
    assert_eq!(read_register(&mut bus, FDC1004, 0x80), Ok(0x0000));
}

#[test]
fn pointer_write_then_read_and_three_byte_write() {
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    block_on(bus.write(FDC1004, &[DEVICE_ID])).unwrap();
    let mut buffer = [0u8; 2];
    block_on(bus.read(FDC1004, &mut buffer)).unwrap();
    assert_eq!(buffer, [0x10, 0x04]);
    // Bytes past the register's two repeat it: the pointer does not auto-increment.
    let mut long = [0u8; 4];
    block_on(bus.read(FDC1004, &mut long)).unwrap();
    assert_eq!(long, [0x10, 0x04, 0x10, 0x04]);

    write_register(&mut bus, FDC1004, CONF_MEAS2, conf_meas(1, 7)).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, CONF_MEAS2), Ok(0x30E0));
    // A write of pointer + one byte is incomplete and changes nothing.
    block_on(bus.write(FDC1004, &[CONF_MEAS2, 0x55])).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, CONF_MEAS2), Ok(0x30E0));
    // CONF_MEASn bits 4:0 are reserved.
    write_register(&mut bus, FDC1004, CONF_MEAS3, 0x501F).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, CONF_MEAS3), Ok(0x5000));
    // An explicit multi-operation transaction behaves like write_read.
    let mut id = [0u8; 2];
    block_on(bus.transaction(
        FDC1004,
        &mut [
            Operation::Write(&[MANUFACTURER_ID]),
            Operation::Read(&mut id),
        ],
    ))
    .unwrap();
    assert_eq!(id, [0x54, 0x49]);
}

#[test]
fn writes_to_read_only_registers_are_ignored() {
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    for pointer in [MEAS1_MSB, MEAS1_LSB, MANUFACTURER_ID, DEVICE_ID, 0x40] {
        write_register(&mut bus, FDC1004, pointer, 0xABCD).unwrap();
    }
    assert_eq!(read_register(&mut bus, FDC1004, MEAS1_MSB), Ok(0));
    assert_eq!(
        read_register(&mut bus, FDC1004, MANUFACTURER_ID),
        Ok(0x5449)
    );
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    assert_eq!(simulation.counters().ignored_writes, 5);
    // DONE bits are read-only too.
    write_register(&mut bus, FDC1004, FDC_CONF, DONE_ALL).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0));
}

#[test]
fn software_reset_restores_reset_values_and_rst_self_clears() {
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    write_register(&mut bus, FDC1004, CONF_MEAS1, conf_meas(0, 3)).unwrap();
    write_register(&mut bus, FDC1004, GAIN_CAL_CIN1, 0x5000).unwrap();
    write_register(&mut bus, FDC1004, FDC_CONF, RATE_100 | REPEAT | MEAS_ALL).unwrap();
    simulation.advance_us(50_000);
    assert_ne!(read_register(&mut bus, FDC1004, MEAS1_MSB), Ok(0));

    write_register(&mut bus, FDC1004, FDC_CONF, RST).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(RST));
    simulation.advance_us(50);
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0));
    assert_eq!(read_register(&mut bus, FDC1004, CONF_MEAS1), Ok(0x1C00));
    assert_eq!(read_register(&mut bus, FDC1004, GAIN_CAL_CIN1), Ok(0x4000));
    assert_eq!(read_register(&mut bus, FDC1004, MEAS1_MSB), Ok(0));
    let conversions = simulation.counters().conversions;
    simulation.advance_us(100_000);
    assert_eq!(simulation.counters().conversions, conversions, "stopped");
    assert_eq!(simulation.counters().software_resets, 1);
}

#[test]
fn other_addresses_nack_on_the_address() {
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    let error = read_register(&mut bus, 0x51, 0x00).unwrap_err();
    assert_eq!(
        error.kind(),
        ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)
    );
    let counters = simulation.counters();
    assert_eq!(counters.nacks, 1);
    assert_eq!(counters.nacks_unknown_address, 1);
    assert_eq!(counters.transactions, 1);
}

#[test]
fn devices_nack_until_powered_up() {
    let simulation = Simulation::new(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    simulation.advance_us(1_499);
    assert!(read_register(&mut bus, TMP117, TMP117_DEVICE_ID).is_err());
    simulation.advance_us(1);
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    simulation.advance_us(3_499);
    assert!(read_register(&mut bus, FDC1004, DEVICE_ID).is_err());
    simulation.advance_us(1);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    assert_eq!(simulation.counters().nacks_powering_up, 2);

    simulation.power_cycle();
    assert!(read_register(&mut bus, FDC1004, DEVICE_ID).is_err());
    simulation.advance_us(5_000);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
}

#[test]
fn transactions_take_bus_time_at_400_khz() {
    let simulation = powered_simulation(SimulationConfig::default()).unwrap();
    let mut bus = simulation.i2c();
    let start_ns = simulation.now_ns();
    read_register(&mut bus, FDC1004, DEVICE_ID).unwrap();
    // Start + address + pointer, repeated start + address + 2 bytes, stop: 48 bits.
    assert_eq!(simulation.now_ns() - start_ns, 120_000);
    let start_ns = simulation.now_ns();
    write_register(&mut bus, FDC1004, CONF_MEAS1, 0x1000).unwrap();
    assert_eq!(simulation.now_ns() - start_ns, 95_000);
    let start_ns = simulation.now_ns();
    read_register(&mut bus, 0x22, 0).unwrap_err();
    assert_eq!(simulation.now_ns() - start_ns, 27_500);
}

#[test]
fn msb_read_latches_the_result_for_the_lsb_read() {
    let mut config = SimulationConfig {
        bus_frequency_hz: None,
        ..SimulationConfig::default()
    };
    config.fdc1004.noise_rms_pf_at_100_sps = 0.0005;
    let simulation = powered_simulation(config).unwrap();
    let mut bus = simulation.i2c();
    write_register(&mut bus, FDC1004, CONF_MEAS1, conf_meas(0, 0)).unwrap();
    write_register(
        &mut bus,
        FDC1004,
        FDC_CONF,
        RATE_400 | REPEAT | meas_enable(0),
    )
    .unwrap();
    simulation.advance_us(2_500);
    let msb = read_register(&mut bus, FDC1004, MEAS1_MSB).unwrap();
    let latched = simulation.peek_fdc1004_register(MEAS1_LSB);
    // A new conversion completes between the two reads; the LSB still belongs to the first.
    simulation.advance_us(2_500);
    assert_eq!(simulation.counters().conversions, 2);
    let newest_lsb = {
        let lsb = read_register(&mut bus, FDC1004, MEAS1_LSB).unwrap();
        assert_eq!(lsb, latched);
        simulation.peek_fdc1004_register(MEAS1_LSB)
    };
    let newest_msb = simulation.peek_fdc1004_register(MEAS1_MSB);
    assert_ne!(
        (msb, latched),
        (newest_msb, newest_lsb),
        "noise makes them differ"
    );
    // Without a latch the LSB read gives the newest result; bits 7:0 are always 0.
    assert_eq!(read_register(&mut bus, FDC1004, MEAS1_LSB), Ok(newest_lsb));
    assert_eq!(newest_lsb & 0x00FF, 0);
}

#[test]
fn tmp117_reads_0x8000_until_the_first_conversion_then_the_scene_temperature() {
    let simulation = Simulation::new(exact_config()).unwrap();
    simulation.set_scene(ScriptedScene::constant(ScenePoint::new([0.0; 4], 31.3)));
    let mut bus = simulation.i2c();
    simulation.advance_us(1_500);
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    assert_eq!(read_register(&mut bus, TMP117, CONFIGURATION), Ok(0x0220));
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(0x8000));
    simulation.advance_us(15_500 - 1_500 - 1);
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(0x8000));
    simulation.advance_us(1);
    // 31.3 °C x 128 = 4006.4 -> 4006.
    assert_eq!(
        read_register(&mut bus, TMP117, CONFIGURATION),
        Ok(0x0220 | DATA_READY)
    );
    assert_eq!(read_register(&mut bus, TMP117, CONFIGURATION), Ok(0x0220));
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(4006));
    assert_eq!(simulation.counters().temperature_conversions, 1);
}

#[test]
fn tmp117_converts_every_cycle_of_its_configuration_and_applies_the_offset() {
    let simulation = Simulation::new(exact_config()).unwrap();
    simulation.set_scene(|time_us: u64| ScenePoint::new([0.0; 4], 20.0 + time_us as f32 * 1e-6));
    let mut bus = simulation.i2c();
    simulation.advance_us(15_500);
    assert_eq!(simulation.counters().temperature_conversions, 1);
    // Reset configuration: CONV = 100, AVG = 01, a 1 s cycle.
    simulation.advance_us(999_999);
    assert_eq!(simulation.counters().temperature_conversions, 1);
    simulation.advance_us(1);
    assert_eq!(simulation.counters().temperature_conversions, 2);
    let expected = ((20.0 + 1.0155f64) * 128.0).round() as u16;
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(expected));

    // CONV = 000, AVG = 00: 15.5 ms cycle; TEMP_OFFSET of +1 °C.
    write_register(&mut bus, TMP117, TEMP_OFFSET, 128).unwrap();
    write_register(&mut bus, TMP117, CONFIGURATION, 0x0000).unwrap();
    // The conversion already scheduled (at 2.0155 s) keeps its time.
    simulation.advance_us(1_000_000 - 1);
    assert_eq!(simulation.counters().temperature_conversions, 2);
    simulation.advance_us(1);
    assert_eq!(simulation.counters().temperature_conversions, 3);
    simulation.advance_us(15_500 * 10);
    assert_eq!(simulation.counters().temperature_conversions, 13);
    let now_s = simulation.now_us() as f64 * 1e-6;
    let last_conversion_s = 2.0155 + 10.0 * 0.0155;
    assert!(now_s >= last_conversion_s);
    let expected = ((20.0 + last_conversion_s) * 128.0).round() as u16 + 128;
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(expected));

    // Shutdown stops conversions; one-shot runs one, then shuts down.
    write_register(&mut bus, TMP117, CONFIGURATION, 0b01 << 10).unwrap();
    simulation.advance_us(1_000_000);
    assert_eq!(simulation.counters().temperature_conversions, 13);
    write_register(&mut bus, TMP117, CONFIGURATION, 0b11 << 10).unwrap();
    simulation.advance_us(15_500);
    assert_eq!(simulation.counters().temperature_conversions, 14);
    assert_eq!(
        read_register(&mut bus, TMP117, CONFIGURATION),
        Ok((0b01 << 10) | DATA_READY)
    );
    simulation.advance_us(1_000_000);
    assert_eq!(simulation.counters().temperature_conversions, 14);
}

#[test]
fn peeking_has_no_side_effects() {
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(
        simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
        DONE_ALL
    );
    let msb = simulation.peek_fdc1004_register(MEAS1_MSB);
    assert_eq!(
        simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
        DONE_ALL
    );
    assert_eq!(read_register(&mut bus, FDC1004, MEAS1_MSB), Ok(msb));
    assert_eq!(
        simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
        DONE_ALL & !done_bit(0)
    );
    assert_eq!(simulation.peek_tmp117_register(TMP117_DEVICE_ID), 0x0117);
}

#[test]
fn invalid_configurations_are_refused_and_handles_cross_threads() {
    use sensor_sim::{ConfigError, SimDelay, SimI2c};
    let mut config = SimulationConfig::default();
    config.physics.taxels[2].unloaded_pf = 0.0;
    assert_eq!(
        Simulation::new(config).unwrap_err(),
        ConfigError::Taxel { taxel: 2 }
    );
    let mut config = SimulationConfig::default();
    config.physics.taxels[1].parasitic_pf = f32::NAN;
    assert_eq!(
        Simulation::new(config).unwrap_err(),
        ConfigError::Taxel { taxel: 1 }
    );
    let mut config = SimulationConfig::default();
    config.physics.taxels[3].modulus_kpa = -5.0;
    assert_eq!(
        Simulation::new(config).unwrap_err(),
        ConfigError::Taxel { taxel: 3 }
    );
    let changes: [fn(&mut SimulationConfig); 4] = [
        |config: &mut SimulationConfig| config.physics.dielectric.densification_strain = 1.0,
        |config: &mut SimulationConfig| config.physics.dielectric.densification_exponent = 0.0,
        |config: &mut SimulationConfig| config.physics.effects.hysteresis = 0.6,
        |config: &mut SimulationConfig| config.physics.effects.cycle_threshold_kpa = f32::NAN,
    ];
    for change in changes {
        let mut config = SimulationConfig::default();
        change(&mut config);
        assert_eq!(Simulation::new(config).unwrap_err(), ConfigError::Pad);
    }
    let mut config = SimulationConfig::default();
    config.fdc1004.noise_rms_pf_at_100_sps = -1.0;
    assert_eq!(Simulation::new(config).unwrap_err(), ConfigError::Noise);
    let config = SimulationConfig {
        bus_frequency_hz: Some(0),
        ..SimulationConfig::default()
    };
    assert_eq!(
        Simulation::new(config).unwrap_err(),
        ConfigError::BusFrequency
    );

    fn send_and_sync<T: Send + Sync>() {}
    send_and_sync::<Simulation>();
    send_and_sync::<SimI2c>();
    send_and_sync::<SimDelay>();
    let simulation = powered_simulation(exact_config()).unwrap();
    let mut bus = simulation.i2c();
    let id = std::thread::spawn(move || read_register(&mut bus, FDC1004, DEVICE_ID))
        .join()
        .unwrap();
    assert_eq!(id, Ok(0x1004));
}
