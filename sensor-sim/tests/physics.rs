//! The result codes against the physics, computed here from the documented law and the
//! article's numbers, never from the simulator's or the pressure model's code:
//! C = Cp + C0 (1 + ε/(1 − ε)) k(T), P(ε) = E0 ε / (1 − ε/εd)^m, k flat to 25 °C then −3.24 %
//! at 55 °C; the CAPDAC offset, the input modes, saturation, the history effects and the noise
//! statistics.

// Taxel indices address several parallel arrays (constants, codes, pressures) at once.
#![allow(clippy::needless_range_loop)]

mod common;

use common::*;
use sensor_sim::{
    Keyframe, PadEffects, ScenePoint, ScriptedScene, SimI2c, Simulation, SimulationConfig,
};

/// The documented default pad, re-declared.
const UNLOADED_PF: [f64; 4] = [4.52, 4.47, 4.55, 4.46];
const PARASITIC_PF: f64 = 1.2;
const MODULUS_KPA: [f64; 4] = [112.6, 110.4, 112.0, 111.0];
const DENSIFICATION_STRAIN: f64 = 0.2464;
const DENSIFICATION_EXPONENT: f64 = 0.444;

/// The article's Table 1: cumulative dC/C0 at 10, 20, 30, 40, 50 kPa.
const TABLE_1: [(f32, f64); 5] = [
    (10.0, 0.0829),
    (20.0, 0.1475),
    (30.0, 0.1981),
    (40.0, 0.2317),
    (50.0, 0.2563),
];

/// The pressure at which a taxel's dielectric is compressed by `strain`: the law in its
/// closed-form direction, so no root finding is shared with the simulator.
fn pressure_for_strain_kpa(taxel: usize, strain: f64) -> f64 {
    MODULUS_KPA[taxel] * strain / (1.0 - strain / DENSIFICATION_STRAIN).powf(DENSIFICATION_EXPONENT)
}

/// Eq. 4 and the capacitance of a taxel compressed by `strain` at a permittivity ratio.
fn capacitance_for_strain_pf(taxel: usize, strain: f64, permittivity_ratio: f64) -> f64 {
    PARASITIC_PF + UNLOADED_PF[taxel] * (1.0 + strain / (1.0 - strain)) * permittivity_ratio
}

fn unloaded_pf(taxel: usize) -> f64 {
    PARASITIC_PF + UNLOADED_PF[taxel]
}

fn simulation_with(
    config: SimulationConfig,
    point: ScenePoint,
) -> TestResult<(Simulation, SimI2c)> {
    let simulation = Simulation::new(config)?;
    simulation.set_scene(ScriptedScene::constant(point));
    simulation.advance_us(POWERED_UP_US);
    let bus = simulation.i2c();
    Ok((simulation, bus))
}

/// Noise-free single-ended codes of all four inputs under a constant scene point.
fn noiseless_codes(pressures_kpa: [f32; 4], temperature_c: f32) -> TestResult<[i32; 4]> {
    let (simulation, mut bus) = simulation_with(
        exact_config(),
        ScenePoint::new(pressures_kpa, temperature_c),
    )?;
    start_all(&mut bus, RATE_400)?;
    simulation.advance_us(10_000);
    let mut codes = [0; 4];
    for (taxel, code) in codes.iter_mut().enumerate() {
        *code = read_result(&mut bus, taxel)?;
    }
    Ok(codes)
}

/// dC/C0 from a noise-free code of an unheated taxel, with the documented C0 and Cp.
fn relative_change_of_code(taxel: usize, code: i32) -> f64 {
    (code as f64 / CODES_PER_PF - PARASITIC_PF) / UNLOADED_PF[taxel] - 1.0
}

fn assert_code_near(code: i32, expected_pf: f64, what: &str) {
    // The scene's pressure is an f32: its rounding moves the capacitance by far less than a code.
    let expected_code = expected_pf * CODES_PER_PF;
    assert!(
        (code as f64 - expected_code).abs() <= 1.0,
        "{what}: code {code}, expected {expected_code:.1}"
    );
}

#[test]
fn noiseless_codes_follow_the_compression_law_and_eq_4() {
    // Strains chosen by hand, the pressure computed from them in closed form.
    let strains = [0.05, 0.1, 0.15, 0.2];
    for (temperature_c, ratio) in [
        (25.0, 1.0),
        (10.0, 1.0),
        (40.0, 1.0 - 0.0324 * 15.0 / 30.0),
        (55.0, 1.0 - 0.0324),
        (70.0, 1.0 - 0.0324 * 45.0 / 30.0),
    ] {
        let pressures_kpa: [f32; 4] =
            core::array::from_fn(|taxel| pressure_for_strain_kpa(taxel, strains[taxel]) as f32);
        let codes = noiseless_codes(pressures_kpa, temperature_c).unwrap();
        for taxel in 0..4 {
            assert_code_near(
                codes[taxel],
                capacitance_for_strain_pf(taxel, strains[taxel], ratio),
                &format!("taxel {taxel} at {temperature_c} °C"),
            );
        }
    }
    // A hand-checked number: taxel C11 (E0 = 112.6 kPa) at 10 % strain needs
    // 112.6 x 0.1 / (1 - 0.1/0.2464)^0.444 = 14.188 kPa and reads 1.2 + 4.52 x (1 + 1/9) pF.
    assert!((pressure_for_strain_kpa(0, 0.1) - 14.188).abs() < 1e-3);
    let codes = noiseless_codes([14.188, 0.0, 0.0, 0.0], 25.0).unwrap();
    let expected_pf = 1.2 + 4.52 * 10.0 / 9.0;
    assert!(
        (codes[0] as f64 / CODES_PER_PF - expected_pf).abs() < 2e-5,
        "{}",
        codes[0]
    );
}

#[test]
fn the_true_curve_passes_close_to_the_articles_table_1() {
    let mut sums = [0.0f64; 5];
    for (index, &(pressure_kpa, table)) in TABLE_1.iter().enumerate() {
        let codes = noiseless_codes([pressure_kpa; 4], 25.0).unwrap();
        for taxel in 0..4 {
            let relative_change = relative_change_of_code(taxel, codes[taxel]);
            println!(
                "{pressure_kpa} kPa taxel {taxel}: dC/C0 {relative_change:.5} (Table 1 {table})"
            );
            assert!(
                (relative_change - table).abs() < 0.0025,
                "{pressure_kpa} kPa taxel {taxel}: {relative_change} vs {table}"
            );
            sums[index] += relative_change;
        }
    }
    // The article's Table 1 is the mean of the four taxels' curves.
    for (sum, &(pressure_kpa, table)) in sums.iter().zip(&TABLE_1) {
        let mean = sum / 4.0;
        assert!(
            (mean - table).abs() < 0.001,
            "{pressure_kpa} kPa: mean {mean} vs {table}"
        );
    }
}

#[test]
fn above_50_kpa_the_curve_keeps_rising_ever_more_slowly_towards_its_bound() {
    let pressures_kpa = [50.0, 60.0, 80.0, 100.0, 200.0, 1e4, 1e9];
    let bound = DENSIFICATION_STRAIN / (1.0 - DENSIFICATION_STRAIN);
    let changes: Vec<f64> = pressures_kpa
        .iter()
        .map(|&pressure_kpa| {
            relative_change_of_code(
                0,
                noiseless_codes([pressure_kpa, 0.0, 0.0, 0.0], 25.0).unwrap()[0],
            )
        })
        .collect();
    println!("{changes:?}, bound {bound}");
    for pair in changes.windows(2).take(4) {
        assert!(pair[1] > pair[0], "{changes:?}");
    }
    // Slopes per kPa fall: 50-60, 60-80, 80-100.
    let slope = |a: usize, b: usize| {
        (changes[b] - changes[a]) / (pressures_kpa[b] - pressures_kpa[a]) as f64
    };
    assert!(slope(0, 1) > slope(1, 2) && slope(1, 2) > slope(2, 3));
    // The 40-50 kPa sensitivity of Table 1 is 0.0025/kPa; past it the law flattens further.
    assert!(
        slope(0, 1) < 0.0025 && slope(0, 1) > 0.0005,
        "{}",
        slope(0, 1)
    );
    for change in &changes {
        assert!(*change < bound + 1e-6);
    }
    // Absurd pressures are clamped to 10 MPa: still finite, just below the bound.
    assert!((changes[5] - changes[6]).abs() < 1e-6);
    assert!(bound - changes[6] < 0.002);
}

#[test]
fn capdac_offsets_and_input_modes() {
    let strain = 0.12;
    let pressure_kpa = pressure_for_strain_kpa(1, strain) as f32;
    let point = ScenePoint::new([0.0, pressure_kpa, 0.0, 0.0], 25.0);
    let (simulation, mut bus) = simulation_with(exact_config(), point).unwrap();
    let c1_pf = unloaded_pf(0);
    let c2_pf = capacitance_for_strain_pf(1, strain, 1.0);
    // Measurement 1: CIN1 - 3.125 pF; 2: CIN2 single-ended; 3: CIN2 - CIN1; 4: CIN4 with CAPDAC 31
    // (5.7 pF - 96.875 pF is far below -16 pF: saturated low).
    write_register(&mut bus, FDC1004, CONF_MEAS1, conf_meas(0, 1)).unwrap();
    write_register(&mut bus, FDC1004, CONF_MEAS2, conf_meas_single_ended(1)).unwrap();
    write_register(&mut bus, FDC1004, CONF_MEAS3, conf_meas_differential(1, 0)).unwrap();
    write_register(&mut bus, FDC1004, CONF_MEAS4, conf_meas(3, 31)).unwrap();
    write_register(&mut bus, FDC1004, FDC_CONF, RATE_100 | REPEAT | MEAS_ALL).unwrap();
    simulation.advance_us(40_000);
    assert_eq!(
        read_result(&mut bus, 0),
        Ok(((c1_pf - 3.125) * CODES_PER_PF).round() as i32)
    );
    assert_code_near(read_result(&mut bus, 1).unwrap(), c2_pf, "single-ended");
    assert_code_near(
        read_result(&mut bus, 2).unwrap(),
        c2_pf - c1_pf,
        "differential",
    );
    assert_eq!(read_result(&mut bus, 3), Ok(-0x80_0000));
    assert_eq!(simulation.counters().saturated_codes, 1);
    let truth_pf = simulation.true_capacitance_pf(1).unwrap();
    assert!((truth_pf - c2_pf).abs() < 1e-6, "{truth_pf} vs {c2_pf}");
}

#[test]
fn negative_and_non_finite_scene_values_are_taken_as_unloaded_and_25_c() {
    let (simulation, mut bus) = simulation_with(
        exact_config(),
        ScenePoint::new([-5.0, f32::NAN, 0.0, f32::INFINITY], 25.0),
    )
    .unwrap();
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(10_000);
    for taxel in 0..4 {
        assert_eq!(
            read_result(&mut bus, taxel),
            Ok((unloaded_pf(taxel) * CODES_PER_PF).round() as i32)
        );
    }
    simulation.set_scene(|_time_us: u64| ScenePoint::new([0.0; 4], f32::NAN));
    simulation.advance_us(10_000);
    assert_eq!(
        read_result(&mut bus, 0),
        Ok((unloaded_pf(0) * CODES_PER_PF).round() as i32)
    );
    for taxel in 0..4 {
        assert!(simulation.true_capacitance_pf(taxel).unwrap().is_finite());
    }
}

#[test]
fn the_factory_calibration_is_the_true_curve_every_5_kpa_with_the_pads_parasitic() {
    let calibration = Simulation::default()
        .physics()
        .matching_calibration()
        .unwrap();
    for taxel in 0..4 {
        let taxel_calibration = &calibration.taxels()[taxel];
        assert_eq!(taxel_calibration.parasitic_pf(), 1.2);
        let points = taxel_calibration.curve().points();
        assert_eq!(points.len(), 11);
        for (index, point) in points.iter().enumerate() {
            assert_eq!(point.pressure_kpa, 5.0 * index as f32);
        }
        // Each point is what the converter reads at that pressure (noise-free), and close to
        // Table 1 where the article has a number.
        let codes: Vec<i32> = [10.0, 25.0, 50.0]
            .iter()
            .map(|&pressure_kpa| noiseless_codes([pressure_kpa; 4], 25.0).unwrap()[taxel])
            .collect();
        for (code, index) in codes.iter().zip([2usize, 5, 10]) {
            let from_code = relative_change_of_code(taxel, *code);
            assert!(
                (from_code - points[index].relative_change as f64).abs() < 1e-5,
                "taxel {taxel} point {index}"
            );
        }
        for (pressure_kpa, table) in TABLE_1 {
            let point = points[(pressure_kpa / 5.0) as usize];
            assert!((point.relative_change as f64 - table).abs() < 0.0025);
        }
    }
}

#[test]
fn history_effects_are_off_by_default() {
    let scene = ScriptedScene::new(vec![
        Keyframe::new(0.0, [0.0; 4], 25.0),
        Keyframe::new(0.1, [40.0; 4], 25.0),
        Keyframe::new(0.2, [40.0; 4], 25.0),
        Keyframe::new(0.3, [20.0; 4], 25.0),
    ])
    .unwrap();
    let simulation = Simulation::new(exact_config()).unwrap();
    simulation.set_scene(scene);
    let mut bus = simulation.i2c();
    simulation.advance_us(POWERED_UP_US);
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(400_000);
    // Unloaded from 40 to 20 kPa: the loading curve's value.
    let codes_after = noiseless_codes([20.0; 4], 25.0).unwrap();
    for taxel in 0..4 {
        assert_eq!(read_result(&mut bus, taxel), Ok(codes_after[taxel]));
    }
    assert_eq!(simulation.load_cycles(), [0; 4]);
}

#[test]
fn hysteresis_leaves_the_unloading_branch_above_the_loading_curve() {
    let hysteresis: f32 = 0.05;
    // Strains by hand: load to 16 % strain, unload to half that pressure.
    let peak_strain = 0.16;
    let peak_kpa: [f32; 4] =
        core::array::from_fn(|taxel| pressure_for_strain_kpa(taxel, peak_strain) as f32);
    let half_kpa = peak_kpa.map(|peak| 0.5 * peak);
    let scene = ScriptedScene::new(vec![
        Keyframe::new(0.0, [0.0; 4], 25.0),
        Keyframe::new(0.1, peak_kpa, 25.0),
        Keyframe::new(0.2, peak_kpa, 25.0),
        Keyframe::new(0.3, half_kpa, 25.0),
        Keyframe::new(0.5, half_kpa, 25.0),
        Keyframe::new(0.6, [0.0; 4], 25.0),
        Keyframe::new(0.7, [0.0; 4], 25.0),
        Keyframe::new(0.8, half_kpa, 25.0),
    ])
    .unwrap();
    let simulation = Simulation::new(exact_config()).unwrap();
    simulation
        .set_pad_effects(PadEffects {
            hysteresis,
            ..PadEffects::default()
        })
        .unwrap();
    simulation.set_scene(scene);
    let mut bus = simulation.i2c();
    simulation.advance_us(POWERED_UP_US);
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(450_000 - POWERED_UP_US);
    let loading_codes = noiseless_codes(half_kpa, 25.0).unwrap();
    for taxel in 0..4 {
        let loading_strain = {
            let relative_change = relative_change_of_code(taxel, loading_codes[taxel]);
            relative_change / (1.0 + relative_change)
        };
        // At half the peak the branch is ε(P) + h ε(Pp) 4 x 0.5 x 0.5.
        let expected_pf = capacitance_for_strain_pf(
            taxel,
            loading_strain + f64::from(hysteresis) * peak_strain,
            1.0,
        );
        assert_code_near(
            read_result(&mut bus, taxel).unwrap(),
            expected_pf,
            &format!("unloading, taxel {taxel}"),
        );
    }
    // Fully unloaded: back on the baseline, and the next loading follows the loading curve.
    simulation.advance_us(250_000);
    for taxel in 0..4 {
        assert_eq!(
            read_result(&mut bus, taxel),
            Ok((unloaded_pf(taxel) * CODES_PER_PF).round() as i32)
        );
    }
    simulation.advance_us(200_000);
    for taxel in 0..4 {
        assert_eq!(read_result(&mut bus, taxel), Ok(loading_codes[taxel]));
    }
}

#[test]
fn each_load_cycle_removes_its_share_of_c0_when_the_loss_is_on() {
    let loss: f32 = 0.002;
    let cycles = 10u32;
    let mut keyframes = vec![Keyframe::new(0.0, [0.0; 4], 25.0)];
    for cycle in 0..cycles {
        let start_s = 0.1 + 0.2 * cycle as f64;
        keyframes.push(Keyframe::new(start_s, [0.0; 4], 25.0));
        keyframes.push(Keyframe::new(start_s + 0.05, [5.0; 4], 25.0));
        keyframes.push(Keyframe::new(start_s + 0.1, [5.0; 4], 25.0));
        keyframes.push(Keyframe::new(start_s + 0.15, [0.0; 4], 25.0));
    }
    let simulation = Simulation::new(exact_config()).unwrap();
    simulation
        .set_pad_effects(PadEffects {
            baseline_loss_per_cycle: loss,
            ..PadEffects::default()
        })
        .unwrap();
    simulation.set_scene(ScriptedScene::new(keyframes).unwrap());
    let mut bus = simulation.i2c();
    simulation.advance_us(POWERED_UP_US);
    start_all(&mut bus, RATE_400).unwrap();
    simulation.advance_us(2_500_000);
    assert_eq!(simulation.load_cycles(), [u64::from(cycles); 4]);
    for taxel in 0..4 {
        let expected_pf =
            PARASITIC_PF + UNLOADED_PF[taxel] * (1.0 - f64::from(loss) * f64::from(cycles));
        assert_code_near(
            read_result(&mut bus, taxel).unwrap(),
            expected_pf,
            &format!("taxel {taxel} after {cycles} cycles"),
        );
    }
    // The article's rate: 4.57 pF -> 4.31 pF over 5000 cycles.
    let article = sensor_sim::physics::ARTICLE_BASELINE_LOSS_PER_CYCLE as f64 * 5000.0;
    assert!((article - (1.0 - 4.31 / 4.57)).abs() < 1e-6);
    // Out-of-range effects are refused.
    assert!(simulation
        .set_pad_effects(PadEffects {
            hysteresis: f32::NAN,
            ..PadEffects::default()
        })
        .is_err());
}

/// Mean and standard deviation (pF) of `count` consecutive results of measurement 1.
fn result_statistics(rate: u16, count: usize, seed: u64) -> TestResult<(f64, f64, Vec<i32>)> {
    let config = SimulationConfig {
        seed,
        bus_frequency_hz: None,
        ..SimulationConfig::default()
    };
    let (simulation, mut bus) = simulation_with(config, ScenePoint::UNLOADED)?;
    write_register(&mut bus, FDC1004, CONF_MEAS1, conf_meas(0, 1))?;
    write_register(&mut bus, FDC1004, FDC_CONF, rate | REPEAT | MEAS_ALL)?;
    let mut codes = Vec::with_capacity(count);
    while codes.len() < count {
        // Wait for DONE_1 the way a driver would, polling every 500 µs.
        while read_register(&mut bus, FDC1004, FDC_CONF)? & done_bit(0) == 0 {
            simulation.advance_us(500);
        }
        codes.push(read_result(&mut bus, 0)?);
    }
    assert_eq!(
        simulation.counters().conversions_per_measurement[0] as usize,
        count,
        "no conversion missed"
    );
    let values_pf: Vec<f64> = codes
        .iter()
        .map(|&code| code as f64 / CODES_PER_PF)
        .collect();
    let mean_pf = values_pf.iter().sum::<f64>() / count as f64;
    let variance = values_pf
        .iter()
        .map(|value| (value - mean_pf).powi(2))
        .sum::<f64>()
        / (count - 1) as f64;
    Ok((mean_pf, variance.sqrt(), codes))
}

#[test]
fn noise_is_half_a_femtofarad_rms_at_100_sps_and_scales_with_the_rate() {
    let truth_pf = unloaded_pf(0) - 3.125;
    for (rate, expected_rms_pf) in [
        (RATE_100, 0.0005),
        (RATE_200, 0.0005 * 2f64.sqrt()),
        (RATE_400, 0.0010),
    ] {
        let count = 4_000;
        let (mean_pf, rms_pf, _) = result_statistics(rate, count, 11).unwrap();
        println!(
            "rate field {rate:#06x}: rms {:.4} fF (expected {:.4} fF), mean offset {:.4} fF",
            rms_pf * 1e3,
            expected_rms_pf * 1e3,
            (mean_pf - truth_pf) * 1e3
        );
        assert!(
            (rms_pf / expected_rms_pf - 1.0).abs() < 0.10,
            "rms {rms_pf} pF, expected {expected_rms_pf} pF"
        );
        // The mean is unbiased within 4 standard errors.
        let standard_error_pf = expected_rms_pf / (count as f64).sqrt();
        assert!((mean_pf - truth_pf).abs() < 4.0 * standard_error_pf);
    }
}

#[test]
fn the_same_seed_gives_the_same_codes_and_another_seed_other_codes() {
    let (_, _, first) = result_statistics(RATE_400, 200, 42).unwrap();
    let (_, _, again) = result_statistics(RATE_400, 200, 42).unwrap();
    let (_, _, other) = result_statistics(RATE_400, 200, 43).unwrap();
    assert_eq!(first, again);
    assert_ne!(first, other);
}
