//! Conversion timing of the simulated FDC1004: DONE appears after the right simulated time for
//! each rate, measurements complete in sequence, and DONE clears when the result is read.

mod common;

use common::*;
use sensor_sim::{SimI2c, Simulation};

fn started(rate: u16, fdc_conf_extra: u16) -> TestResult<(Simulation, SimI2c)> {
    let simulation = Simulation::new(exact_config())?;
    simulation.advance_us(POWERED_UP_US);
    let mut bus = simulation.i2c();
    for (measurement, &pointer) in CONF_MEAS.iter().enumerate() {
        write_register(&mut bus, FDC1004, pointer, conf_meas(measurement as u16, 0))?;
    }
    write_register(&mut bus, FDC1004, FDC_CONF, rate | fdc_conf_extra)?;
    Ok((simulation, bus))
}

#[test]
fn four_repeated_measurements_complete_one_after_another_at_each_rate() {
    for (rate, period_us) in [(RATE_100, 10_000u64), (RATE_200, 5_000), (RATE_400, 2_500)] {
        let (simulation, _bus) = started(rate, REPEAT | MEAS_ALL).unwrap();
        let mut expected_done = 0u16;
        for measurement in 0..4 {
            simulation.advance_us(period_us - 1);
            assert_eq!(
                simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
                expected_done,
                "rate {rate:#x}, just before measurement {measurement} completes"
            );
            simulation.advance_us(1);
            expected_done |= done_bit(measurement);
            assert_eq!(
                simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
                expected_done,
                "rate {rate:#x}, measurement {measurement} completed"
            );
        }
        assert_eq!(simulation.counters().conversions_per_measurement, [1; 4]);
        // Each measurement refreshes every 4 / R: 100 Hz per taxel at 400 S/s.
        simulation.advance_us(100 * 4 * period_us);
        assert_eq!(simulation.counters().conversions_per_measurement, [101; 4]);
    }
}

#[test]
fn done_clears_when_the_result_is_read_and_sets_again_on_the_next_conversion() {
    let (simulation, mut bus) = started(RATE_400, REPEAT | MEAS_ALL).unwrap();
    simulation.advance_us(10_000);
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF),
        Ok(0x0DF0 | DONE_ALL)
    );
    // Reading FDC_CONF does not clear DONE; reading MEAS1_MSB clears DONE_1 only.
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF),
        Ok(0x0DF0 | DONE_ALL)
    );
    read_register(&mut bus, FDC1004, MEAS1_MSB).unwrap();
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF),
        Ok(0x0DF0 | (DONE_ALL & !done_bit(0)))
    );
    // The LSB read does not touch DONE.
    read_register(&mut bus, FDC1004, MEAS1_LSB).unwrap();
    for measurement in 1..4 {
        read_result(&mut bus, measurement).unwrap();
    }
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x0DF0));
    simulation.advance_us(2_500);
    assert_eq!(
        read_register(&mut bus, FDC1004, FDC_CONF),
        Ok(0x0DF0 | done_bit(0))
    );
}

#[test]
fn single_measurement_mode_runs_once() {
    let (simulation, _bus) = started(RATE_100, meas_enable(2)).unwrap();
    simulation.advance_us(9_999);
    assert_eq!(simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL, 0);
    simulation.advance_us(1);
    assert_eq!(
        simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
        done_bit(2)
    );
    simulation.advance_us(1_000_000);
    assert_eq!(
        simulation.counters().conversions_per_measurement,
        [0, 0, 1, 0]
    );
}

#[test]
fn fewer_enabled_measurements_refresh_faster() {
    let (simulation, _bus) = started(RATE_400, REPEAT | meas_enable(0) | meas_enable(3)).unwrap();
    simulation.advance_us(2_500);
    assert_eq!(
        simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
        done_bit(0)
    );
    simulation.advance_us(2_500);
    assert_eq!(
        simulation.peek_fdc1004_register(FDC_CONF) & DONE_ALL,
        done_bit(0) | done_bit(3)
    );
    simulation.advance_us(1_000_000 - 5_000);
    assert_eq!(
        simulation.counters().conversions_per_measurement,
        [200, 0, 0, 200]
    );
}

#[test]
fn rewriting_fdc_conf_restarts_the_sequence_and_reserved_rate_runs_nothing() {
    let (simulation, mut bus) = started(RATE_100, REPEAT | MEAS_ALL).unwrap();
    simulation.advance_us(15_000);
    assert_eq!(simulation.counters().conversions, 1);
    write_register(&mut bus, FDC1004, FDC_CONF, RATE_100 | REPEAT | MEAS_ALL).unwrap();
    assert_eq!(read_register(&mut bus, FDC1004, FDC_CONF), Ok(0x05F0));
    simulation.advance_us(9_999);
    assert_eq!(simulation.counters().conversions, 1);
    simulation.advance_us(1);
    assert_eq!(simulation.counters().conversions, 2);

    write_register(&mut bus, FDC1004, FDC_CONF, REPEAT | MEAS_ALL).unwrap();
    simulation.advance_us(1_000_000);
    assert_eq!(simulation.counters().conversions, 2);
}

#[test]
fn delays_advance_simulated_time_exactly() {
    use embedded_hal_async::delay::DelayNs;
    let simulation = Simulation::new(exact_config()).unwrap();
    let mut delay = simulation.delay();
    embassy_futures::block_on(async {
        delay.delay_ns(1_500).await;
        delay.delay_us(2_000).await;
        delay.delay_ms(3).await;
        delay.delay_ms(600_000).await;
    });
    assert_eq!(
        simulation.now_ns(),
        1_500 + 2_000_000 + 3_000_000 + 600_000_000_000
    );
}

#[test]
fn minutes_of_simulated_time_complete_every_conversion() {
    let (simulation, _bus) = started(RATE_400, REPEAT | MEAS_ALL).unwrap();
    simulation.advance_us(10 * 60 * 1_000_000);
    // 400 conversions per second for ten minutes.
    assert_eq!(simulation.counters().conversions, 240_000);
    // The TMP117 converted once at 15.5 ms and then every second.
    assert_eq!(simulation.counters().temperature_conversions, 600);
}
