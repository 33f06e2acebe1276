//! Several pads behind the multiplexer: per-pad scenes and faults, converters running in
//! parallel, a pad unplugged and plugged back, stuck multiplexer channels and determinism. The
//! mux and the converters are driven by the project's real drivers where a user would use them.

mod common;

use common::*;
use embassy_futures::block_on;
use fdc1004::{Config, Fdc1004, Rate};
use sensor_sim::{
    Fault, MultiplexerConfig, ScenePoint, ScriptedScene, SimI2c, SimI2cError, Simulation,
    SimulationConfig, Tmp117Config, Topology, Window,
};
use tca9548a::{Address, Channel, ChannelMask, Tca9548a};

const MUX: u8 = 0x70;

fn pads_on(channels: &[u8], seed: u64, noise: bool) -> SimulationConfig {
    let mut multiplexer = MultiplexerConfig::with_pads_on_channels(MUX, channels);
    for pad in &mut multiplexer.pads {
        pad.tmp117 = Some(Tmp117Config::default());
        if !noise {
            pad.fdc1004.noise_rms_pf_at_100_sps = 0.0;
            pad.tmp117 = Some(Tmp117Config {
                noise_rms_c: 0.0,
                ..Tmp117Config::default()
            });
        }
    }
    SimulationConfig {
        seed,
        topology: Topology::Multiplexed(multiplexer),
        ..SimulationConfig::default()
    }
}

fn mux(bus: &SimI2c) -> TestResult<Tca9548a<SimI2c>> {
    let address = Address::new(MUX).ok_or("not a TCA9548A address")?;
    Ok(Tca9548a::new(bus.clone(), address))
}

fn select(bus: &SimI2c, channel: u8) -> TestResult<()> {
    let channel = Channel::new(channel).ok_or("no such channel")?;
    block_on(mux(bus)?.select_verified(channel)).map_err(|error| format!("{error:?}"))?;
    Ok(())
}

fn select_mask(bus: &SimI2c, mask: u8) -> TestResult<()> {
    block_on(mux(bus)?.select_mask_verified(ChannelMask(mask)))
        .map_err(|error| format!("{error:?}"))?;
    Ok(())
}

/// The driver's init on every pad in turn, then one set of measurements from each.
fn measure_every_pad(simulation: &Simulation, channels: &[u8]) -> TestResult<Vec<[i32; 4]>> {
    let bus = simulation.i2c();
    let mut converter = Fdc1004::new(
        simulation.i2c(),
        simulation.delay(),
        Config::new(Rate::Hz400, [0; 4]),
    );
    for &channel in channels {
        select(&bus, channel)?;
        block_on(converter.init()).map_err(|error| format!("{error:?}"))?;
    }
    let mut codes = Vec::with_capacity(channels.len());
    for &channel in channels {
        select(&bus, channel)?;
        let measurements =
            block_on(converter.read_measurements()).map_err(|error| format!("{error:?}"))?;
        codes.push(measurements.codes.map(|code| code.0));
    }
    Ok(codes)
}

#[test]
fn per_pad_scenes_give_per_pad_capacitances() {
    let channels = [1, 3, 4, 6];
    let simulation = Simulation::new(pads_on(&channels, 7, false)).unwrap();
    let pressed = ScenePoint::new([30.0, 30.0, 30.0, 30.0], 25.0);
    simulation
        .set_pad_scene(2, ScriptedScene::constant(pressed))
        .unwrap();
    assert_eq!(simulation.scene_point_of(2), Some(pressed));
    assert_eq!(simulation.scene_point_of(0), Some(ScenePoint::UNLOADED));
    assert_eq!(simulation.scene_point(), ScenePoint::UNLOADED);
    let codes = measure_every_pad(&simulation, &channels).unwrap();
    for (pad, pad_codes) in codes.iter().enumerate() {
        for taxel in 0..4 {
            let truth_pf = simulation.pad_true_capacitance_pf(pad, taxel).unwrap();
            let measured_pf = pad_codes[taxel] as f64 / CODES_PER_PF;
            assert!(
                (measured_pf - truth_pf).abs() < 1e-5,
                "pad {pad} taxel {taxel}: {measured_pf} pF, truth {truth_pf} pF"
            );
            if pad == 2 {
                // 30 kPa: about a fifth more than unloaded.
                assert!(pad_codes[taxel] as f64 > 1.1 * codes[0][taxel] as f64);
            } else {
                assert_eq!(pad_codes[taxel], codes[0][taxel], "pad {pad} taxel {taxel}");
            }
        }
    }
    // The single-pad scene methods act on pad 0.
    simulation.set_scene(ScriptedScene::constant(pressed));
    assert_eq!(simulation.scene_point_of(0), Some(pressed));
    assert_eq!(
        simulation.true_capacitance_pf(0),
        simulation.pad_true_capacitance_pf(0, 0)
    );
    let counters = simulation.counters();
    for pad in 0..channels.len() {
        assert!(counters.pads[pad].conversions >= 4, "pad {pad}");
    }
}

#[test]
fn converters_on_different_pads_convert_in_parallel() {
    let channels = [0, 2, 5, 7];
    let mut config = pads_on(&channels, 3, false);
    config.bus_frequency_hz = None;
    let simulation = Simulation::new(config).unwrap();
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    // Trigger one measurement (CIN1, 100 S/s: 10 ms) on each pad.
    for &channel in &channels {
        select(&bus, channel).unwrap();
        write_register(&mut bus, FDC1004, CONF_MEAS1, conf_meas(0, 0)).unwrap();
        write_register(&mut bus, FDC1004, FDC_CONF, RATE_100 | meas_enable(0)).unwrap();
    }
    simulation.advance_us(9_999);
    for pad in 0..channels.len() {
        assert_eq!(
            simulation.peek_pad_fdc1004_register(pad, FDC_CONF),
            Some(RATE_100 | meas_enable(0))
        );
    }
    // One conversion time later every pad is done, not one after another.
    simulation.advance_us(1);
    for (pad, &channel) in channels.iter().enumerate() {
        select(&bus, channel).unwrap();
        let fdc_conf = read_register(&mut bus, FDC1004, FDC_CONF).unwrap();
        assert_eq!(fdc_conf & DONE_ALL, done_bit(0), "pad {pad}");
        assert_eq!(simulation.counters().pads[pad].conversions, 1);
    }
    assert_eq!(simulation.counters().conversions, 4);
}

#[test]
fn the_driver_can_trigger_all_pads_then_read_them_in_turn() {
    let channels = [0, 1, 2, 3];
    let simulation = Simulation::new(pads_on(&channels, 3, true)).unwrap();
    let codes = measure_every_pad(&simulation, &channels).unwrap();
    assert_eq!(codes.len(), 4);
    // Each pad's converter ran on its own clock while the others were initialised and read.
    let counters = simulation.counters();
    assert!(counters.pads[0].conversions > counters.pads[3].conversions);
    assert_eq!(counters.address_conflicts, 0);
    assert_eq!(counters.nacks, 0);
}

#[test]
fn faults_injected_on_a_pad_act_on_that_pad_only() {
    let channels = [0, 1];
    let simulation = Simulation::new(pads_on(&channels, 3, false)).unwrap();
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    for &channel in &channels {
        select(&bus, channel).unwrap();
        start_all(&mut bus, RATE_400).unwrap();
    }
    simulation
        .inject_on_pad(1, Fault::DoneStuck, Window::From { start_us: 0 })
        .unwrap();
    simulation.reset_counters();
    simulation.advance_us(20_000);
    let counters = simulation.counters();
    assert_eq!(counters.pads[0].conversions, 8);
    assert_eq!(counters.pads[1].conversions, 0);
    assert_eq!(counters.conversions_stalled, 8);
    assert!(simulation
        .inject_on_pad(2, Fault::DoneStuck, Window::Next(1))
        .is_err());
    // `inject` is pad 0.
    simulation.inject(
        Fault::Saturated {
            taxel: 0,
            high: true,
        },
        Window::Next(1),
    );
    simulation.advance_us(10_000);
    assert_eq!(simulation.counters().saturations_injected, 1);
}

#[test]
fn an_unplugged_pad_nacks_then_comes_back_with_reset_registers() {
    let channels = [4, 5];
    let mut config = pads_on(&channels, 3, false);
    config.bus_frequency_hz = None;
    let simulation = Simulation::new(config).unwrap();
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    select(&bus, 5).unwrap();
    start_all(&mut bus, RATE_400).unwrap();
    write_register(&mut bus, TMP117, TEMP_OFFSET, 0x0100).unwrap();
    simulation.advance_us(30_000);
    assert_eq!(
        read_register(&mut bus, FDC1004, CONF_MEAS2),
        Ok(conf_meas(1, 0))
    );
    let start_us = simulation.now_us() + 1_000;
    let end_us = start_us + 20_000;
    simulation
        .inject_on_pad(1, Fault::Unplugged, Window::Between { start_us, end_us })
        .unwrap();
    simulation.advance_us(1_000);
    assert_eq!(simulation.pad_unplugged(1), Some(true));
    let conversions_at_unplug = simulation.counters().pads[1].conversions;
    simulation.reset_counters();
    // The mux still answers; nothing behind channel 5 does.
    select(&bus, 5).unwrap();
    for (address, pointer) in [(FDC1004, DEVICE_ID), (TMP117, TMP117_DEVICE_ID)] {
        assert_eq!(
            read_register(&mut bus, address, pointer),
            Err(SimI2cError::ADDRESS_NACK)
        );
    }
    assert_eq!(simulation.counters().nacks_unplugged, 2);
    assert_eq!(simulation.counters().pads[1].nacks, 2);
    // The other pad is fine.
    select(&bus, 4).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    // No power, no conversions.
    simulation.advance_us(10_000);
    assert_eq!(simulation.counters().pads[1].conversions, 0);
    assert!(conversions_at_unplug > 0);
    // Plugged back at the end of the window, it powers up like a new board.
    simulation.advance_us(end_us - simulation.now_us());
    assert_eq!(simulation.pad_unplugged(1), Some(false));
    select(&bus, 5).unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    assert_eq!(simulation.counters().nacks_powering_up, 1);
    simulation.advance_us(POWERED_UP_US);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    assert_eq!(read_register(&mut bus, FDC1004, CONF_MEAS2), Ok(0x1C00));
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0));
    assert_eq!(read_register(&mut bus, FDC1004, MEAS1_MSB), Ok(0));
    assert_eq!(read_register(&mut bus, TMP117, CONFIGURATION), Ok(0x0220));
    assert_eq!(read_register(&mut bus, TMP117, TEMP_OFFSET), Ok(0));
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(0x8000));
    // Its TMP117 starts converting again from the re-plug.
    simulation.advance_us(15_500 - POWERED_UP_US);
    assert_eq!(read_register(&mut bus, TMP117, TEMP_RESULT), Ok(25 * 128));
}

#[test]
fn an_unplug_for_a_count_of_transactions_or_until_removed() {
    let channels = [0];
    let mut config = pads_on(&channels, 3, false);
    config.bus_frequency_hz = None;
    let simulation = Simulation::new(config).unwrap();
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    select(&bus, 0).unwrap();
    // Two transactions reach the unplugged board, then it is back (and powering up).
    simulation
        .inject_on_pad(0, Fault::Unplugged, Window::Next(2))
        .unwrap();
    for _ in 0..2 {
        assert_eq!(
            read_register(&mut bus, FDC1004, DEVICE_ID),
            Err(SimI2cError::ADDRESS_NACK)
        );
    }
    assert_eq!(simulation.pad_unplugged(0), Some(false));
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    simulation.advance_us(POWERED_UP_US);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    let counters = simulation.counters();
    assert_eq!(counters.nacks_unplugged, 2);
    assert_eq!(counters.nacks_powering_up, 1);
    // Until removed.
    let unplug = simulation.inject(Fault::Unplugged, Window::UntilSoftwareReset);
    assert_eq!(simulation.pad_unplugged(0), Some(true));
    simulation.advance_us(100_000);
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    assert!(simulation.remove_fault(unplug));
    assert_eq!(simulation.pad_unplugged(0), Some(false));
    simulation.advance_us(POWERED_UP_US);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
}

#[test]
fn a_channel_stuck_closed_stays_on_the_bus() {
    let channels = [0, 1];
    let mut config = pads_on(&channels, 3, false);
    config.bus_frequency_hz = None;
    let simulation = Simulation::new(config).unwrap();
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    select(&bus, 0).unwrap();
    write_register(&mut bus, FDC1004, OFFSET_CAL_CIN1, 0x0FF0).unwrap();
    select(&bus, 1).unwrap();
    write_register(&mut bus, FDC1004, OFFSET_CAL_CIN1, 0x00FF).unwrap();
    let stuck = simulation.inject(
        Fault::MuxChannelStuck {
            channel: 1,
            closed: true,
        },
        Window::From { start_us: 0 },
    );
    // All channels off, and the read-back says so, yet pad 1 answers.
    select_mask(&bus, 0).unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, OFFSET_CAL_CIN1),
        Ok(0x00FF)
    );
    // With channel 0 selected both answer: the AND, and a conflict.
    select(&bus, 0).unwrap();
    simulation.reset_counters();
    assert_eq!(
        read_register(&mut bus, FDC1004, OFFSET_CAL_CIN1),
        Ok(0x00F0)
    );
    assert_eq!(simulation.counters().address_conflicts, 1);
    // Repaired: channel 1 follows the register again.
    simulation.remove_fault(stuck);
    select_mask(&bus, 0).unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
}

#[test]
fn a_channel_stuck_open_stays_off_the_bus() {
    let channels = [3];
    let mut config = pads_on(&channels, 3, false);
    config.bus_frequency_hz = None;
    let simulation = Simulation::new(config).unwrap();
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    let start_us = simulation.now_us();
    simulation
        .inject_on_pad(
            0,
            Fault::MuxChannelStuck {
                channel: 3,
                closed: false,
            },
            Window::Between {
                start_us,
                end_us: start_us + 1_000,
            },
        )
        .unwrap();
    // The driver's read-back check passes: the register is fine, the switch is not.
    select(&bus, 3).unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    assert_eq!(simulation.counters().nacks_unknown_address, 1);
    simulation.advance_us(1_000);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    // Counted by transactions: the next two only.
    simulation.inject_upstream(
        Fault::MuxChannelStuck {
            channel: 3,
            closed: false,
        },
        Window::Next(2),
    );
    for _ in 0..2 {
        assert!(read_register(&mut bus, FDC1004, DEVICE_ID).is_err());
    }
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
}

/// Codes from three pads with identical physics and scenes, noise on.
fn noisy_run(seed: u64) -> TestResult<Vec<[i32; 4]>> {
    let channels = [0, 1, 2];
    let simulation = Simulation::new(pads_on(&channels, seed, true))?;
    for pad in 0..channels.len() {
        simulation.set_pad_scene(
            pad,
            ScriptedScene::constant(ScenePoint::new([5.0, 10.0, 15.0, 20.0], 30.0)),
        )?;
    }
    let mut codes = measure_every_pad(&simulation, &channels)?;
    codes.extend(measure_every_pad(&simulation, &channels)?);
    Ok(codes)
}

#[test]
fn the_same_seed_gives_the_same_run_and_each_pad_its_own_noise() {
    let first = noisy_run(42).unwrap();
    assert_eq!(first, noisy_run(42).unwrap());
    assert_ne!(first, noisy_run(43).unwrap());
    // Same physics, same scene, different noise streams.
    assert_ne!(first[0], first[1]);
    assert_ne!(first[1], first[2]);
}
