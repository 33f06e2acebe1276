//! The TCA9548A model and the multiplexed topology: the control register against the datasheet,
//! routing by channel, address conflicts on the open-drain bus, the shared TMP117 and the
//! validation of topologies. The mux is driven by the project's real `tca9548a` driver.

mod common;

use common::*;
use embassy_futures::block_on;
use embedded_hal_async::i2c::I2c;
use sensor_sim::{
    ConfigError, Device, Fault, MultiplexerConfig, PadConfig, SharedTmp117Config, SimI2c,
    SimI2cError, Simulation, SimulationConfig, Tmp117Config, Topology, Window,
};
use tca9548a::{Address, Channel, ChannelMask, Tca9548a};

const MUX: u8 = 0x73;

fn multiplexed(channels: &[u8]) -> SimulationConfig {
    SimulationConfig {
        topology: Topology::Multiplexed(MultiplexerConfig::with_pads_on_channels(MUX, channels)),
        ..exact_config()
    }
}

fn powered(config: SimulationConfig) -> TestResult<(Simulation, SimI2c)> {
    let simulation = Simulation::new(config)?;
    simulation.advance_us(POWERED_UP_US);
    let bus = simulation.i2c();
    Ok((simulation, bus))
}

fn mux(bus: &SimI2c) -> TestResult<Tca9548a<SimI2c>> {
    let address = Address::new(MUX).ok_or("not a TCA9548A address")?;
    Ok(Tca9548a::new(bus.clone(), address))
}

fn select(bus: &SimI2c, mask: u8) -> TestResult<()> {
    block_on(mux(bus)?.select_mask_verified(ChannelMask(mask)))
        .map_err(|error| format!("{error:?}"))?;
    Ok(())
}

#[test]
fn the_control_register_follows_the_datasheet() {
    let (simulation, mut bus) = powered(multiplexed(&[0, 1, 2, 3])).unwrap();
    let mut mux = mux(&bus).unwrap();
    // Power-on: every channel off.
    assert_eq!(block_on(mux.enabled()).unwrap(), ChannelMask::NONE);
    assert_eq!(simulation.multiplexer_control(), Some(0));
    // One channel, several, all, none: each reads back as written.
    for mask in [0b0000_0100, 0b1010_0101, 0xFF, 0x00, 0b1000_0000] {
        block_on(mux.select_mask(ChannelMask(mask))).unwrap();
        assert_eq!(block_on(mux.enabled()).unwrap(), ChannelMask(mask));
    }
    block_on(mux.select_verified(Channel::Ch6)).unwrap();
    assert_eq!(simulation.multiplexer_control(), Some(0b0100_0000));
    // No pointer: of several bytes written, the last one is kept; a longer read repeats it.
    block_on(bus.write(MUX, &[0x01, 0x02, 0x0C])).unwrap();
    let mut two = [0u8; 2];
    block_on(bus.read(MUX, &mut two)).unwrap();
    assert_eq!(two, [0x0C, 0x0C]);
    // The address alone changes nothing.
    block_on(bus.write(MUX, &[])).unwrap();
    assert_eq!(block_on(mux.enabled()).unwrap(), ChannelMask(0x0C));
    // Other mux addresses are empty.
    let mut other = Tca9548a::new(bus.clone(), Address::default());
    assert_eq!(
        block_on(other.enabled()),
        Err(tca9548a::Error::I2c(SimI2cError::ADDRESS_NACK))
    );
    let counters = simulation.counters();
    assert_eq!(counters.multiplexer_transactions, 17);
    assert_eq!(counters.nacks_unknown_address, 1);
    // RESET and a power cycle turn every channel off.
    simulation.reset_multiplexer();
    assert_eq!(block_on(mux.enabled()).unwrap(), ChannelMask::NONE);
    block_on(mux.select(Channel::Ch1)).unwrap();
    simulation.power_cycle();
    assert_eq!(block_on(mux.enabled()).unwrap(), ChannelMask::NONE);
}

#[test]
fn a_pads_converter_answers_only_while_its_channel_is_enabled() {
    // Pad k is not on channel k: the routing follows the configuration.
    let channels = [2u8, 0, 5, 7];
    let (simulation, mut bus) = powered(multiplexed(&channels)).unwrap();
    // Nothing enabled: nobody at 0x50.
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    assert_eq!(simulation.counters().nacks_unknown_address, 1);
    // Mark each pad's converter through its own channel.
    for (pad, &channel) in channels.iter().enumerate() {
        select(&bus, 1 << channel).unwrap();
        assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
        write_register(&mut bus, FDC1004, OFFSET_CAL_CIN1, 0x100 + pad as u16).unwrap();
    }
    simulation.reset_counters();
    for (pad, &channel) in channels.iter().enumerate() {
        select(&bus, 1 << channel).unwrap();
        assert_eq!(
            read_register(&mut bus, FDC1004, OFFSET_CAL_CIN1),
            Ok(0x100 + pad as u16)
        );
        assert_eq!(
            simulation.peek_pad_fdc1004_register(pad, OFFSET_CAL_CIN1),
            Some(0x100 + pad as u16)
        );
    }
    let counters = simulation.counters();
    for pad in 0..channels.len() {
        assert_eq!(counters.pads[pad].transactions, 1, "pad {pad}");
    }
    assert_eq!(counters.address_conflicts, 0);
    // A channel without a pad: nobody answers.
    select(&bus, 1 << 1).unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    // Pads have no TMP117 of their own by default.
    select(&bus, 0xFF).unwrap();
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
}

#[test]
fn the_selection_takes_effect_at_the_stop_of_the_write() {
    let (_simulation, mut bus) = powered(multiplexed(&[0])).unwrap();
    // Write then read back in one transaction: the register holds the new value at once, the
    // converter behind it is reachable from the next transaction.
    let mut control = [0u8; 1];
    block_on(bus.write_read(MUX, &[0x01], &mut control)).unwrap();
    assert_eq!(control, [0x01]);
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
}

#[test]
fn two_enabled_devices_at_one_address_read_as_the_and_of_their_bytes() {
    let (simulation, mut bus) = powered(multiplexed(&[0, 1])).unwrap();
    select(&bus, 0b01).unwrap();
    write_register(&mut bus, FDC1004, OFFSET_CAL_CIN1, 0xF0F0).unwrap();
    select(&bus, 0b10).unwrap();
    write_register(&mut bus, FDC1004, OFFSET_CAL_CIN1, 0x3C3C).unwrap();
    select(&bus, 0b11).unwrap();
    simulation.reset_counters();
    // Both acknowledge, both drive the bytes: open drain gives their AND.
    assert_eq!(
        read_register(&mut bus, FDC1004, OFFSET_CAL_CIN1),
        Ok(0xF0F0 & 0x3C3C)
    );
    // The same register on both: the AND is the value itself.
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    // A write reaches both.
    write_register(&mut bus, FDC1004, GAIN_CAL_CIN1, 0x1234).unwrap();
    let counters = simulation.counters();
    assert_eq!(counters.address_conflicts, 3);
    assert_eq!(counters.pads[0].transactions, 3);
    assert_eq!(counters.pads[1].transactions, 3);
    assert_eq!(counters.fdc1004_transactions, 3);
    for channel in [0b01, 0b10] {
        select(&bus, channel).unwrap();
        assert_eq!(read_register(&mut bus, FDC1004, GAIN_CAL_CIN1), Ok(0x1234));
    }
    // One device NACKing (an injected fault) leaves the other alone on the wires.
    select(&bus, 0b11).unwrap();
    simulation
        .inject_on_pad(1, Fault::Nack(Device::Fdc1004), Window::Next(1))
        .unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, OFFSET_CAL_CIN1),
        Ok(0xF0F0)
    );
    assert_eq!(simulation.counters().address_conflicts, 3);
}

fn with_tmp117s(shared_address: u8) -> SimulationConfig {
    let tmp117 = Some(Tmp117Config {
        noise_rms_c: 0.0,
        ..Tmp117Config::default()
    });
    SimulationConfig {
        topology: Topology::Multiplexed(MultiplexerConfig {
            address: MUX,
            pads: vec![
                PadConfig {
                    tmp117,
                    ..PadConfig::on_channel(4)
                },
                PadConfig::on_channel(5),
            ],
            shared_tmp117: Some(SharedTmp117Config {
                address: shared_address,
                tmp117: Tmp117Config {
                    noise_rms_c: 0.0,
                    ..Tmp117Config::default()
                },
            }),
        }),
        ..exact_config()
    }
}

#[test]
fn the_shared_tmp117_is_upstream_and_a_pads_own_one_behind_its_channel() {
    let (simulation, mut bus) = powered(with_tmp117s(0x49)).unwrap();
    // Upstream: always there.
    assert_eq!(read_register(&mut bus, 0x49, TMP117_DEVICE_ID), Ok(0x0117));
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    select(&bus, 1 << 4).unwrap();
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    assert_eq!(read_register(&mut bus, 0x49, TMP117_DEVICE_ID), Ok(0x0117));
    // Pad 1 has no TMP117.
    select(&bus, 1 << 5).unwrap();
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    // Both convert; pad 0's own one counts for pad 0, the shared one in the totals only.
    simulation.advance_us(20_000);
    let counters = simulation.counters();
    assert_eq!(counters.temperature_conversions, 2);
    assert_eq!(counters.pads[0].temperature_conversions, 1);
    assert_eq!(
        simulation.peek_shared_tmp117_register(TEMP_RESULT),
        Some(25 * 128)
    );
    assert_eq!(
        simulation.peek_pad_tmp117_register(0, TEMP_RESULT),
        Some(25 * 128)
    );
    assert_eq!(simulation.peek_pad_tmp117_register(1, TEMP_RESULT), None);
    // An upstream fault acts on the shared sensor, a pad's fault on the pad's own one.
    simulation.inject_upstream(Fault::Nack(Device::Tmp117), Window::Next(1));
    select(&bus, 1 << 4).unwrap();
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    assert_eq!(
        read_register(&mut bus, 0x49, TMP117_DEVICE_ID),
        Err(SimI2cError::ADDRESS_NACK)
    );
    assert_eq!(simulation.counters().nacks_injected, 1);
}

#[test]
fn a_shared_tmp117_at_0x48_is_alone_on_its_address() {
    let mut config = with_tmp117s(TMP117);
    if let Topology::Multiplexed(multiplexer) = &mut config.topology {
        multiplexer.pads[0].tmp117 = None;
    }
    let (_simulation, mut bus) = powered(config).unwrap();
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    select(&bus, 0xFF).unwrap();
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
}

#[test]
fn invalid_topologies_are_refused() {
    let refused = |config: SimulationConfig| Simulation::new(config).err();
    let with = |change: &dyn Fn(&mut MultiplexerConfig)| {
        let mut multiplexer = MultiplexerConfig::with_pads_on_channels(MUX, &[0, 1]);
        change(&mut multiplexer);
        refused(SimulationConfig {
            topology: Topology::Multiplexed(multiplexer),
            ..SimulationConfig::default()
        })
    };
    assert_eq!(with(&|_| {}), None);
    assert_eq!(
        with(&|multiplexer| multiplexer.address = 0x6F),
        Some(ConfigError::MultiplexerAddress { address: 0x6F })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.address = 0x78),
        Some(ConfigError::MultiplexerAddress { address: 0x78 })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.pads.clear()),
        Some(ConfigError::PadCount { count: 0 })
    );
    assert_eq!(
        with(&|multiplexer| {
            *multiplexer = MultiplexerConfig::with_pads_on_channels(MUX, &[0, 1, 2, 3, 4, 5, 6, 7]);
            multiplexer.pads.push(PadConfig::on_channel(0));
        }),
        Some(ConfigError::PadCount { count: 9 })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.pads[1].channel = 8),
        Some(ConfigError::Channel { pad: 1, channel: 8 })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.pads[1].channel = 0),
        Some(ConfigError::DuplicateChannel { channel: 0 })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.pads[1].physics.taxels[2].unloaded_pf = f32::NAN),
        Some(ConfigError::PadTaxel { pad: 1, taxel: 2 })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.pads[0].physics.dielectric.densification_strain = 0.0),
        Some(ConfigError::PadDielectric { pad: 0 })
    );
    assert_eq!(
        with(&|multiplexer| multiplexer.pads[1].fdc1004.noise_rms_pf_at_100_sps = -1.0),
        Some(ConfigError::PadNoise { pad: 1 })
    );
    assert_eq!(
        with(&|multiplexer| {
            multiplexer.pads[1].tmp117 = Some(Tmp117Config {
                noise_rms_c: f64::INFINITY,
                ..Tmp117Config::default()
            })
        }),
        Some(ConfigError::PadNoise { pad: 1 })
    );
    assert_eq!(
        with(&|multiplexer| {
            multiplexer.shared_tmp117 = Some(SharedTmp117Config {
                address: 0x4C,
                ..SharedTmp117Config::default()
            })
        }),
        Some(ConfigError::SharedTmp117Address { address: 0x4C })
    );
    // A shared TMP117 at 0x48 and a pad's own one would meet whenever the pad is selected.
    assert_eq!(
        with(&|multiplexer| {
            multiplexer.shared_tmp117 = Some(SharedTmp117Config::default());
            multiplexer.pads[1].tmp117 = Some(Tmp117Config::default());
        }),
        Some(ConfigError::Tmp117AddressClash {
            address: 0x48,
            pad: 1
        })
    );
    assert_eq!(
        with(&|multiplexer| {
            multiplexer.shared_tmp117 = Some(SharedTmp117Config {
                address: 0x4B,
                ..SharedTmp117Config::default()
            });
            multiplexer.pads[1].tmp117 = Some(Tmp117Config::default());
        }),
        None
    );
    // The single-pad checks are unchanged.
    let mut single = SimulationConfig::default();
    single.physics.taxels[1].modulus_kpa = 0.0;
    assert_eq!(refused(single), Some(ConfigError::Taxel { taxel: 1 }));
    assert_eq!(
        refused(SimulationConfig {
            bus_frequency_hz: Some(0),
            ..multiplexed(&[0])
        }),
        Some(ConfigError::BusFrequency)
    );
    // Every error says what is wrong.
    assert!(ConfigError::Tmp117AddressClash {
        address: 0x48,
        pad: 1
    }
    .to_string()
    .contains("pad 1"));
}

#[test]
fn the_default_is_one_pad_without_a_multiplexer() {
    let simulation = Simulation::default();
    assert_eq!(SimulationConfig::default().topology, Topology::SinglePad);
    assert_eq!(simulation.pad_count(), 1);
    assert_eq!(simulation.multiplexer_control(), None);
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    for address in 0x70..=0x77 {
        let mut control = [0u8; 1];
        assert_eq!(
            block_on(bus.read(address, &mut control)),
            Err(SimI2cError::ADDRESS_NACK)
        );
    }
    assert_eq!(read_register(&mut bus, FDC1004, DEVICE_ID), Ok(0x1004));
    assert_eq!(
        read_register(&mut bus, TMP117, TMP117_DEVICE_ID),
        Ok(0x0117)
    );
    assert!(simulation.set_pad_scene(1, |_| Default::default()).is_err());
    assert_eq!(simulation.scene_point_of(1), None);
    let counters = simulation.counters();
    assert_eq!(counters.pads[0].transactions, 2);
    assert_eq!(counters.multiplexer_transactions, 0);
}
