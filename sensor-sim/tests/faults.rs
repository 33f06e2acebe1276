//! Every injectable fault, observed through raw register access.

mod common;

use common::*;
use embedded_hal_async::i2c::{Error, ErrorKind, NoAcknowledgeSource};
use sensor_sim::{
    Device, Fault, ScenePoint, ScriptedScene, SimI2c, Simulation, SimulationConfig, Window,
};

fn running(config: SimulationConfig) -> TestResult<(Simulation, SimI2c)> {
    let simulation = Simulation::new(config)?;
    simulation.set_scene(ScriptedScene::constant(ScenePoint::new(
        [0.0, 10.0, 20.0, 30.0],
        25.0,
    )));
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    start_all(&mut bus, RATE_400)?;
    simulation.advance_us(10_000);
    Ok((simulation, bus))
}

fn read_all(bus: &mut SimI2c) -> [i32; 4] {
    core::array::from_fn(|measurement| read_result(bus, measurement).unwrap_or(i32::MIN))
}

#[test]
fn a_nack_burst_fails_the_next_n_transactions_only() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    simulation.inject(Fault::Nack(Device::Fdc1004), Window::Next(3));
    // Transactions to the other device do not count against the burst.
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    for _ in 0..3 {
        let error = read_register(&mut bus, FDC1004, DEVICE_ID).unwrap_err();
        assert_eq!(
            error.kind(),
            ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)
        );
    }
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    let counters = simulation.counters();
    assert_eq!(counters.nacks_injected, 3);
    assert_eq!(counters.nacks, 3);
}

#[test]
fn an_absent_device_nacks_over_its_window_while_conversions_go_on() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    let start_us = simulation.now_us() + 1_000;
    simulation.inject(
        Fault::Nack(Device::Fdc1004),
        Window::Between {
            start_us,
            end_us: start_us + 20_000,
        },
    );
    assert!(read_register(&mut bus, FDC1004, DEVICE_ID).is_ok());
    simulation.advance_us(1_000);
    let conversions = simulation.counters().conversions;
    for _ in 0..10 {
        assert!(read_register(&mut bus, FDC1004, FDC_CONF).is_err());
        simulation.advance_us(1_999);
    }
    assert!(simulation.counters().conversions > conversions);
    simulation.advance_us(10);
    assert!(read_register(&mut bus, FDC1004, DEVICE_ID).is_ok());
}

#[test]
fn done_stuck_stalls_conversions_until_a_software_reset() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    let before = read_all(&mut bus);
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x0DF0));
    simulation.inject(Fault::DoneStuck, Window::UntilSoftwareReset);
    simulation.advance_us(1_000_000);
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x0DF0));
    assert_eq!(read_all(&mut bus), before, "results are stale");
    assert_eq!(simulation.counters().conversions_stalled, 400);
    // Rewriting the configuration does not help; a software reset does.
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x0DF0));
    write_register(&mut bus, FDC1004, FDC_CONF, RST).unwrap();
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF),
        Ok(0x0DF0 | DONE_ALL)
    );
}

#[test]
fn done_stuck_for_a_count_of_conversions() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    read_all(&mut bus);
    simulation.inject(Fault::DoneStuck, Window::Next(2));
    simulation.advance_us(5_000);
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x0DF0));
    simulation.advance_us(5_000);
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF),
        Ok(0x0DF0 | done_bit(2) | done_bit(3))
    );
}

#[test]
fn zero_reads_zero_a_whole_set_of_results() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    simulation.inject(Fault::ZeroReads, Window::Next(4));
    assert_eq!(read_all(&mut bus), [0; 4]);
    assert_eq!(simulation.counters().zero_reads_injected, 4);
    assert!(read_all(&mut bus).iter().all(|&code| code > 2_000_000));
}

#[test]
fn saturation_on_one_channel() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    let id = simulation.inject(
        Fault::Saturated {
            taxel: 2,
            high: true,
        },
        Window::From { start_us: 0 },
    );
    simulation.advance_us(10_000);
    let codes = read_all(&mut bus);
    assert_eq!(codes[2], 0x7F_FFFF);
    assert!(codes[0] > 0 && codes[0] < 0x7F_FFFF && codes[1] < 0x7F_FFFF);
    assert!(simulation.remove_fault(id));
    simulation.inject(
        Fault::Saturated {
            taxel: 1,
            high: false,
        },
        Window::Next(1),
    );
    simulation.advance_us(10_000);
    let codes = read_all(&mut bus);
    assert_eq!(codes[1], -0x80_0000);
    assert!(codes[2] < 0x7F_FFFF);
    simulation.advance_us(10_000);
    assert!(read_all(&mut bus)[1] > 0);
    assert_eq!(simulation.counters().saturations_injected, 2);
}

#[test]
fn a_frozen_channel_repeats_its_code_while_done_still_sets() {
    // With noise, a live channel's code changes at every conversion.
    let config = SimulationConfig {
        bus_frequency_hz: None,
        ..SimulationConfig::default()
    };
    let (simulation, mut bus) = running(config).unwrap();
    let before = read_all(&mut bus);
    let start_us = simulation.now_us();
    simulation.inject(
        Fault::FrozenResult { taxel: 1 },
        Window::Between {
            start_us,
            end_us: start_us + 100_000,
        },
    );
    for _ in 0..5 {
        simulation.advance_us(10_000);
        assert_eq!(
            read_register(&mut bus, FDC1004, FDC_CONF),
            Ok(0x0DF0 | DONE_ALL),
            "DONE sets for the frozen measurement too"
        );
        let codes = read_all(&mut bus);
        assert_eq!(codes[1], before[1]);
        for measurement in [0, 2, 3] {
            assert_ne!(codes[measurement], before[measurement]);
        }
    }
    let counters = simulation.counters();
    assert_eq!(counters.frozen_conversions, 5);
    assert_eq!(
        counters.conversions_per_measurement[1],
        counters.conversions_per_measurement[0]
    );
    // A software reset zeroes the register, which then stays at 0 while the fault lasts.
    write_register(&mut bus, FDC1004, FDC_CONF, RST).unwrap();
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(read_all(&mut bus)[1], 0);
    // Over: the channel converts again.
    simulation.advance_us(100_000);
    assert!(read_all(&mut bus)[1] > 2_000_000);
}

#[test]
fn shorted_electrodes_read_negative_or_saturate_low_with_a_capdac() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    simulation.inject(Fault::shorted(0), Window::From { start_us: 0 });
    simulation.advance_us(10_000);
    let code = read_result(&mut bus, 0).unwrap();
    assert_eq!(code, (-0.5 * CODES_PER_PF).round() as i32);
    // Against a CAPDAC of 6 (18.75 pF), -0.5 pF is more than 16 pF below the offset.
    write_register(&mut bus, FDC1004, CONF_MEAS1, conf_meas(0, 6)).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(read_result(&mut bus, 0), Ok(-0x80_0000));
    assert_eq!(simulation.counters().shorted_conversions, 2);
}

#[test]
fn an_open_lead_leaves_the_parasitic_capacitance() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    simulation.inject(Fault::open_lead(3), Window::From { start_us: 0 });
    simulation.inject(
        Fault::OpenLead {
            taxel: 1,
            capacitance_pf: Some(0.05),
        },
        Window::From { start_us: 0 },
    );
    simulation.advance_us(10_000);
    let codes = read_all(&mut bus);
    assert_eq!(codes[3], (1.2f32 as f64 * CODES_PER_PF).round() as i32);
    assert_eq!(codes[1], (0.05f32 as f64 * CODES_PER_PF).round() as i32);
    assert!(codes[0] > (5.0 * CODES_PER_PF) as i32);
}

#[test]
fn mcu_only_reset_rotates_the_inputs_until_a_software_reset() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    let normal = read_all(&mut bus);
    simulation.simulate_mcu_only_reset();
    assert!(simulation.channel_shift_active());
    simulation.advance_us(10_000);
    // Measurement n now converts CIN(n+2): the codes rotate by one.
    assert_eq!(
        read_all(&mut bus),
        [normal[1], normal[2], normal[3], normal[0]]
    );
    // The configuration looks right, so a read-back check does not see it.
    for (measurement, &pointer) in CONF_MEAS.iter().enumerate() {
        assert_eq!(
            read_register(&mut bus, FDC1004, pointer),
            Ok(conf_meas(measurement as u16, 0))
        );
    }
    // Rewriting the configuration does not help; RST does.
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(read_all(&mut bus)[0], normal[1]);
    write_register(&mut bus, FDC1004, FDC_CONF, RST).unwrap();
    assert!(!simulation.channel_shift_active());
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(read_all(&mut bus), normal);
}

#[test]
fn the_shift_can_be_made_visible_in_the_configuration_read_back() {
    let mut config = exact_config();
    config.fdc1004.channel_shift_visible_in_readback = true;
    let (simulation, mut bus) = running(config).unwrap();
    simulation.simulate_mcu_only_reset();
    for (measurement, &pointer) in CONF_MEAS.iter().enumerate() {
        let wrote = conf_meas(measurement as u16, 0);
        write_register(&mut bus, FDC1004, pointer, wrote).unwrap();
        assert_eq!(
            read_register(&mut bus, FDC1004, pointer),
            Ok(conf_meas((measurement as u16 + 1) % 4, 0))
        );
    }
}

#[test]
fn tmp117_absent_and_stuck() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    simulation.advance_us(20_000);
    simulation.inject(
        Fault::Nack(Device::Tmp117),
        Window::From {
            start_us: simulation.now_us(),
        },
    );
    assert!(read_register(&mut bus, TMP117, TEMP_RESULT).is_err());
    assert!(read_register(&mut bus, FDC1004, DEVICE_ID).is_ok());
    simulation.clear_faults();
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(25 * 128));

    simulation.set_scene(ScriptedScene::constant(ScenePoint::new([0.0; 4], 40.0)));
    simulation.inject(
        Fault::TemperatureStuck {
            temp_result: 0x0C80,
        },
        Window::UntilSoftwareReset,
    );
    simulation.advance_us(3_000_000);
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(0x0C80));
    assert_eq!(
        read_register(&mut bus, TMP117, CONFIGURATION),
        Ok(0x0220),
        "Data_Ready was cleared by the TEMP_RESULT read"
    );
    // Soft_Reset (CONFIGURATION bit 1) ends it and restarts the conversions.
    write_register(&mut bus, TMP117, CONFIGURATION, 0x0002).unwrap();
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(0x8000));
    simulation.advance_us(15_500);
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(40 * 128));
    assert_eq!(simulation.counters().stuck_temperature_reads, 1);
}

#[test]
fn power_cycle_ends_until_reset_faults_and_restores_reset_values() {
    let (simulation, mut bus) = running(exact_config()).unwrap();
    simulation.inject(Fault::DoneStuck, Window::UntilSoftwareReset);
    simulation.simulate_mcu_only_reset();
    simulation.power_cycle();
    assert!(!simulation.channel_shift_active());
    simulation.advance_us(5_000);
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0));
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF).map(|value| value & DONE_ALL),
        Ok(DONE_ALL)
    );
}
