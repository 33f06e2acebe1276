//! The project's real drivers (FDC1004, TMP117) and model against the simulator: a scripted
//! pressure comes back as the right pressure, and every fault shows up where a user of the
//! drivers would see it.

use embassy_futures::block_on;
use embedded_hal_async::i2c::{Error as _, ErrorKind, NoAcknowledgeSource};
use fdc1004::{capacitance_pf, Config, Error, Fdc1004, Measurements, Rate};
use model_core::{PadModel, PadOutput, SampleInput, TareStatus, TaxelFlags, TaxelReading};
use sensor_sim::{
    Device, Fault, Keyframe, ScenePoint, ScriptedScene, SimDelay, SimI2c, SimI2cError, Simulation,
    SimulationConfig, Window,
};
use tmp117::{Address, Tmp117};

type Converter = Fdc1004<SimI2c, SimDelay>;

fn converter(simulation: &Simulation, rate: Rate) -> Converter {
    let config = Config {
        rate,
        ..Config::default()
    };
    Fdc1004::new(simulation.i2c(), simulation.delay(), config)
}

fn initialised(scene: ScriptedScene) -> Result<(Simulation, Converter), Error<SimI2cError>> {
    let simulation = Simulation::default();
    simulation.set_scene(scene);
    let mut converter = converter(&simulation, Rate::Hz400);
    block_on(converter.init())?;
    Ok((simulation, converter))
}

fn constant(pressure_kpa: [f32; 4], temperature_c: f32) -> ScriptedScene {
    ScriptedScene::constant(ScenePoint::new(pressure_kpa, temperature_c))
}

fn process(
    pad: &mut PadModel,
    measurements: &Measurements,
    temperature_c: Option<f32>,
) -> PadOutput {
    let readings = core::array::from_fn(|taxel| TaxelReading::Raw {
        code: measurements.codes[taxel].0,
        capdac: 0,
    });
    pad.process(&SampleInput::new(readings, temperature_c))
}

fn nack() -> SimI2cError {
    SimI2cError::ADDRESS_NACK
}

#[test]
fn init_succeeds_after_the_power_up_wait() {
    let simulation = Simulation::default();
    let mut converter = converter(&simulation, Rate::Hz400);
    block_on(converter.init()).unwrap();
    let counters = simulation.counters();
    assert_eq!(counters.nacks, 0);
    assert_eq!(counters.software_resets, 1);
    // 5 ms power-up wait, the reset poll and about twenty register accesses at 400 kHz.
    let init_us = simulation.now_us();
    assert!((5_100..8_000).contains(&init_us), "{init_us} µs");
    let measurements = block_on(converter.read_measurements()).unwrap();
    // The first complete set is ready 10 ms after FDC_CONF was written.
    assert!(simulation.now_us() >= init_us + 10_000);
    // DONE is polled every 500 µs plus the 120 µs poll itself; the eight result reads take 960 µs.
    assert!(simulation.now_us() < init_us + 10_000 + 620 + 960);
    for code in measurements.codes {
        let pf = capacitance_pf(code, 0);
        assert!((5.6..5.8).contains(&pf), "{pf} pF");
    }

    let mut sensor = Tmp117::new(simulation.i2c(), Address::Gnd);
    block_on(sensor.init()).unwrap();
    let temperature_c = block_on(sensor.read_temperature_c()).unwrap();
    assert!((temperature_c - 25.0).abs() < 0.05, "{temperature_c}");
}

#[test]
fn init_without_the_power_up_wait_sees_a_nack() {
    let simulation = Simulation::default();
    let config = Config {
        power_up_delay_us: 1_000,
        ..Config::default()
    };
    let mut converter = Fdc1004::new(simulation.i2c(), simulation.delay(), config);
    assert_eq!(block_on(converter.init()), Err(Error::I2c(nack())));
}

/// A stretch of the scene where the pressures hold still.
struct Hold {
    from_s: f64,
    to_s: f64,
    pressure_kpa: [f32; 4],
}

#[test]
fn scripted_pressures_come_back_through_driver_and_model() {
    let scene = ScriptedScene::new(vec![
        Keyframe::new(0.0, [0.0; 4], 25.0),
        Keyframe::new(1.0, [0.0; 4], 25.0),
        Keyframe::new(2.0, [10.0, 20.0, 35.0, 48.0], 25.0),
        Keyframe::new(4.0, [10.0, 20.0, 35.0, 48.0], 25.0),
        Keyframe::new(5.0, [5.0, 15.0, 25.0, 45.0], 25.0),
        // Warming at 1 °C/s: the model applies steps of up to 2 °C between sets as measured
        // (larger ones it treats as implausible and follows slowly), and the TMP117 reports one
        // step a second.
        Keyframe::new(20.0, [5.0, 15.0, 25.0, 45.0], 40.0),
        Keyframe::new(23.0, [5.0, 15.0, 25.0, 45.0], 40.0),
    ])
    .unwrap();
    let holds = [
        Hold {
            from_s: 0.6,
            to_s: 1.0,
            pressure_kpa: [0.0; 4],
        },
        Hold {
            from_s: 2.0,
            to_s: 4.0,
            pressure_kpa: [10.0, 20.0, 35.0, 48.0],
        },
        // The TMP117 converts once a second: from 20.0155 s it reports 40 °C.
        Hold {
            from_s: 20.1,
            to_s: 23.0,
            pressure_kpa: [5.0, 15.0, 25.0, 45.0],
        },
    ];
    let (simulation, mut converter) = initialised(scene).unwrap();
    let mut sensor = Tmp117::new(simulation.i2c(), Address::Gnd);
    block_on(sensor.init()).unwrap();
    let mut pad = PadModel::new(simulation.physics().matching_calibration().unwrap());
    pad.start_tare(50);

    let mut sums_kpa = [[0.0f64; 4]; 3];
    let mut counts = [0usize; 3];
    let mut worst_error_kpa = [0.0f32; 3];
    while simulation.now_us() < 23_000_000 {
        let measurements = block_on(converter.read_measurements()).unwrap();
        let temperature_c = block_on(sensor.read_temperature_c()).ok();
        let output = process(&mut pad, &measurements, temperature_c);
        let now_s = simulation.now_us() as f64 * 1e-6;
        if now_s < 0.6 {
            continue;
        }
        assert_eq!(
            pad.tare_status(),
            TareStatus::Finished { tared_mask: 0b1111 }
        );
        let Some(hold) = holds
            .iter()
            .position(|hold| (hold.from_s..hold.to_s).contains(&now_s))
        else {
            continue;
        };
        counts[hold] += 1;
        for (taxel, taxel_output) in output.taxels.iter().enumerate() {
            let pressure_kpa = taxel_output.pressure_kpa().unwrap_or_else(|| {
                panic!("taxel {taxel} at {now_s} s: {:?}", taxel_output.flags())
            });
            let error_kpa = (pressure_kpa - holds[hold].pressure_kpa[taxel]).abs();
            worst_error_kpa[hold] = worst_error_kpa[hold].max(error_kpa);
            sums_kpa[hold][taxel] += pressure_kpa as f64;
        }
    }
    for (hold, expected) in holds.iter().enumerate() {
        let means: Vec<f64> = sums_kpa[hold]
            .iter()
            .map(|sum| sum / counts[hold] as f64)
            .collect();
        println!(
            "hold {hold}: {} sets, mean {means:.3?} kPa, expected {:?}, worst single error {:.3} kPa",
            counts[hold], expected.pressure_kpa, worst_error_kpa[hold]
        );
        assert!(counts[hold] > 35);
        for (taxel, (mean_kpa, expected_kpa)) in means.iter().zip(expected.pressure_kpa).enumerate()
        {
            // The scene is the simulator's own truth; the model's factory calibration samples it
            // every 5 kPa, and its monotone cubic between those points is up to 0.065 kPa off the
            // true curve (near 48 kPa, measured). Noise averages out over a hold.
            assert!(
                (mean_kpa - expected_kpa as f64).abs() < 0.1,
                "hold {hold} taxel {taxel}: mean {mean_kpa} kPa"
            );
        }
        assert!(worst_error_kpa[hold] < 0.5, "hold {hold}");
    }
}

#[test]
fn a_nack_burst_is_a_bus_error_and_the_next_read_succeeds() {
    let (simulation, mut converter) = initialised(constant([0.0; 4], 25.0)).unwrap();
    simulation.inject(Fault::Nack(Device::Fdc1004), Window::Next(1));
    let error = block_on(converter.read_measurements()).unwrap_err();
    let Error::I2c(bus_error) = error else {
        panic!("{error:?}");
    };
    assert_eq!(
        bus_error.kind(),
        ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)
    );
    assert!(block_on(converter.read_measurements()).is_ok());
}

#[test]
fn an_absent_converter_fails_init() {
    let simulation = Simulation::default();
    simulation.inject(Fault::Nack(Device::Fdc1004), Window::From { start_us: 0 });
    let mut converter = converter(&simulation, Rate::Hz400);
    assert_eq!(block_on(converter.init()), Err(Error::I2c(nack())));
}

#[test]
fn done_stuck_times_out_and_reinit_recovers() {
    let (simulation, mut converter) = initialised(constant([0.0; 4], 25.0)).unwrap();
    block_on(converter.read_measurements()).unwrap();
    simulation.inject(Fault::DoneStuck, Window::UntilSoftwareReset);
    let start_us = simulation.now_us();
    assert_eq!(
        block_on(converter.read_measurements()),
        Err(Error::DoneTimeout { done_bits: 0 })
    );
    // The default timeout is 100 ms of delays; the 200 polls add 120 µs of bus time each.
    let waited_us = simulation.now_us() - start_us;
    assert!((100_000..126_000).contains(&waited_us), "{waited_us} µs");
    block_on(converter.reinit()).unwrap();
    assert!(block_on(converter.read_measurements()).is_ok());
}

#[test]
fn channel_shift_moves_pressures_to_the_wrong_taxel_until_reinit() {
    let (simulation, mut converter) = initialised(constant([0.0, 30.0, 0.0, 0.0], 25.0)).unwrap();
    let mut pad = PadModel::new(simulation.physics().matching_calibration().unwrap());
    // Tared on the loaded taxel's own values, so the shift shows as pressure on its neighbour.
    simulation.set_scene(constant([0.0; 4], 25.0));
    pad.start_tare(10);
    for _ in 0..10 {
        let measurements = block_on(converter.read_measurements()).unwrap();
        process(&mut pad, &measurements, Some(25.0));
    }
    simulation.set_scene(constant([0.0, 30.0, 0.0, 0.0], 25.0));
    block_on(converter.read_measurements()).unwrap();
    let measurements = block_on(converter.read_measurements()).unwrap();
    let output = process(&mut pad, &measurements, Some(25.0));
    assert!((output.taxels[1].pressure_kpa().unwrap() - 30.0).abs() < 0.5);

    simulation.simulate_mcu_only_reset();
    block_on(converter.read_measurements()).unwrap();
    let measurements = block_on(converter.read_measurements()).unwrap();
    let output = process(&mut pad, &measurements, Some(25.0));
    // Measurement 1 now converts CIN2: the press shows on C11, and C12 reads C21's unloaded
    // input, a few kPa off because the taxels' C0 differ.
    let shifted_kpa = output.taxels[0].pressure_kpa().unwrap_or(f32::NAN);
    assert!(shifted_kpa > 25.0, "{:?}", output.taxels);
    assert!(output.taxels[1].pressure_kpa().unwrap_or(0.0) < 5.0);

    block_on(converter.reinit()).unwrap();
    assert!(!simulation.channel_shift_active());
    let measurements = block_on(converter.read_measurements()).unwrap();
    let output = process(&mut pad, &measurements, Some(25.0));
    assert!((output.taxels[1].pressure_kpa().unwrap() - 30.0).abs() < 0.5);
    assert!(output.taxels[0].pressure_kpa().unwrap() < 0.5);
}

#[test]
fn zero_reads_and_saturation_are_visible_in_the_measurements() {
    let (simulation, mut converter) = initialised(constant([0.0; 4], 25.0)).unwrap();
    simulation.inject(Fault::ZeroReads, Window::Next(4));
    assert!(block_on(converter.read_measurements()).unwrap().all_zero());
    assert!(!block_on(converter.read_measurements()).unwrap().all_zero());

    simulation.inject(
        Fault::Saturated {
            taxel: 3,
            high: true,
        },
        Window::Next(1),
    );
    let measurements = block_on(converter.read_measurements()).unwrap();
    assert!(measurements.any_saturated());
    assert!(measurements.codes[3].is_saturated());
    let mut pad = PadModel::new(simulation.physics().matching_calibration().unwrap());
    let output = process(&mut pad, &measurements, Some(25.0));
    assert!(output.taxels[3].flags().contains(TaxelFlags::SATURATED));
    assert_eq!(output.taxels[3].pressure_kpa(), None);
}

#[test]
fn shorted_and_open_taxels_are_flagged_by_the_model() {
    let (simulation, mut converter) = initialised(constant([5.0; 4], 25.0)).unwrap();
    let mut pad = PadModel::new(simulation.physics().matching_calibration().unwrap());
    simulation.inject(Fault::shorted(0), Window::From { start_us: 0 });
    simulation.inject(Fault::open_lead(2), Window::From { start_us: 0 });
    block_on(converter.read_measurements()).unwrap();
    let measurements = block_on(converter.read_measurements()).unwrap();
    let shorted_pf = capacitance_pf(measurements.codes[0], 0);
    let open_pf = capacitance_pf(measurements.codes[2], 0);
    println!("shorted taxel reads {shorted_pf} pF, open taxel {open_pf} pF");
    assert!((shorted_pf + 0.5).abs() < 0.01);
    assert!((open_pf - 1.2).abs() < 0.01);
    let output = process(&mut pad, &measurements, Some(25.0));
    assert!(output.taxels[0].flags().contains(TaxelFlags::SHORTED));
    assert!(output.taxels[2].flags().contains(TaxelFlags::OPEN));
    assert_eq!(output.taxels[0].pressure_kpa(), None);
    assert_eq!(output.taxels[2].pressure_kpa(), None);
}

#[test]
fn temperature_sensor_faults_through_the_driver() {
    let simulation = Simulation::new(SimulationConfig::default()).unwrap();
    simulation.set_scene(|time_us: u64| ScenePoint::new([0.0; 4], 20.0 + (time_us as f32 * 1e-6)));
    let mut sensor = Tmp117::new(simulation.i2c(), Address::Gnd);
    assert_eq!(block_on(sensor.init()), Err(tmp117::Error::I2c(nack())));
    simulation.advance_us(1_500);
    block_on(sensor.init()).unwrap();
    assert_eq!(
        block_on(sensor.read_temperature_c()),
        Err(tmp117::Error::NotReady)
    );
    simulation.advance_us(15_500);
    assert!(block_on(sensor.data_ready()).unwrap());
    let first_c = block_on(sensor.read_temperature_c()).unwrap();
    assert!((first_c - 20.0155).abs() < 0.03, "{first_c}");

    simulation.inject(
        Fault::TemperatureStuck {
            temp_result: 0x0A00,
        },
        Window::From {
            start_us: simulation.now_us(),
        },
    );
    for _ in 0..3 {
        simulation.advance_us(1_000_000);
        assert_eq!(block_on(sensor.read_temperature_c()), Ok(20.0));
    }
    simulation.clear_faults();
    let moved_c = block_on(sensor.read_temperature_c()).unwrap();
    assert!((moved_c - 23.0155).abs() < 0.03, "{moved_c}");

    simulation.inject(Fault::Nack(Device::Tmp117), Window::Next(1));
    assert_eq!(
        block_on(sensor.read_temperature_c()),
        Err(tmp117::Error::I2c(nack()))
    );
}
