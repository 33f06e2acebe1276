//! Pad force and centre of pressure against analytic scenes: every expectation is computed here
//! from the scene (pressures, centres, areas), never by the code under test. Taxel outputs come
//! from a tared `PadModel`, so faults carry the flags the model really sets.

use model_core::pad_force::{COP_MIN_FORCE_N, MAX_PRESSURE_KPA};
use model_core::pad_geometry::{MAX_CENTRE_OFFSET_MM, MAX_TAXEL_AREA_MM2};
use model_core::reading::SATURATED_HIGH_CODE;
use model_core::{
    pad_force, pad_force_from_pressures, Calibration, CalibrationSpec, CurvePoint, GeometryError,
    PadForce, PadForceFlags, PadGeometry, PadModel, SampleInput, TaxelFlags, TaxelGeometry,
    TaxelOutput, TaxelReading,
};
use proptest::prelude::*;
use std::sync::OnceLock;

const SENSOR_PF: f32 = 4.5;
/// The test calibration is a straight line: dC/C0 = P / 100 kPa up to 100 kPa, so any pressure
/// of a scene is one capacitance away.
const LINEAR_TOP_KPA: f32 = 100.0;
/// The article's pad, written out: C11 top-left, C12 top-right, C21 bottom-left, C22
/// bottom-right, 5 mm x 5 mm electrodes.
const CENTRES_MM: [(f32, f32); 4] = [(-2.75, 2.75), (2.75, 2.75), (-2.75, -2.75), (2.75, -2.75)];
const AREA_MM2: f32 = 25.0;

/// What one taxel does in a scene.
#[derive(Debug, Clone, Copy)]
enum Taxel {
    Kpa(f32),
    Open,
    Saturated,
    Shorted,
    Unavailable,
}

fn tared(calibration: Calibration) -> PadModel {
    let mut pad = PadModel::new(calibration);
    pad.start_tare(4);
    let unloaded = SampleInput::new([TaxelReading::CapacitancePf(SENSOR_PF); 4], Some(25.0));
    for _ in 0..4 {
        pad.process(&unloaded);
    }
    pad
}

/// A tared pad of the linear calibration (built once: building every tier is the slow part).
fn linear_pad() -> PadModel {
    static PAD: OnceLock<PadModel> = OnceLock::new();
    PAD.get_or_init(build_linear_pad).clone()
}

/// A tared pad of the article's calibration, built once.
fn article_pad() -> PadModel {
    static PAD: OnceLock<PadModel> = OnceLock::new();
    PAD.get_or_init(|| tared(Calibration::default())).clone()
}

fn build_linear_pad() -> PadModel {
    let mut spec = CalibrationSpec::default();
    for taxel in spec.taxels.iter_mut() {
        taxel.points.clear();
        assert!(taxel.points.push(CurvePoint::new(0.0, 0.0)).is_ok());
        assert!(taxel
            .points
            .push(CurvePoint::new(LINEAR_TOP_KPA, 1.0))
            .is_ok());
    }
    let calibration = Calibration::new(&spec);
    assert!(calibration.is_ok(), "{calibration:?}");
    tared(calibration.unwrap_or_default())
}

/// The taxel outputs of a scene, checked to read what the scene says.
fn outputs(scene: [Taxel; 4]) -> [TaxelOutput; 4] {
    let readings = scene.map(|taxel| match taxel {
        Taxel::Kpa(pressure_kpa) => {
            TaxelReading::CapacitancePf(SENSOR_PF * (1.0 + pressure_kpa / LINEAR_TOP_KPA))
        }
        Taxel::Open => TaxelReading::CapacitancePf(0.2),
        Taxel::Saturated => TaxelReading::Raw {
            code: SATURATED_HIGH_CODE,
            capdac: 1,
        },
        Taxel::Shorted => TaxelReading::CapacitancePf(-0.8),
        Taxel::Unavailable => TaxelReading::Unavailable,
    });
    let taxels = linear_pad()
        .process(&SampleInput::new(readings, Some(25.0)))
        .taxels;
    for (taxel, output) in scene.iter().zip(&taxels) {
        match taxel {
            Taxel::Kpa(pressure_kpa) => {
                let read_kpa = output.pressure_kpa().unwrap_or(f32::NAN);
                assert!(
                    (read_kpa - pressure_kpa).abs() < 1e-3,
                    "{taxel:?}: {output:?}"
                );
            }
            _ => assert_eq!(output.pressure_kpa(), None, "{taxel:?}: {output:?}"),
        }
    }
    taxels
}

fn assert_close(actual: f32, expected: f64, tolerance: f64, what: &str) {
    assert!(
        (f64::from(actual) - expected).abs() <= tolerance,
        "{what}: {actual}, expected {expected}"
    );
}

fn assert_force(force: &PadForce, expected_n: f64) {
    assert_close(force.force_n.unwrap_or(f32::NAN), expected_n, 1e-5, "force");
}

fn assert_centre(force: &PadForce, expected_mm: (f64, f64)) {
    let (x_mm, y_mm) = force.centre_of_pressure_mm.unwrap_or((f32::NAN, f32::NAN));
    assert_close(x_mm, expected_mm.0, 1e-4, "centre x");
    assert_close(y_mm, expected_mm.1, 1e-4, "centre y");
}

#[test]
fn the_default_geometry_is_the_articles_pad() {
    let geometry = PadGeometry::default();
    for (taxel, (x_mm, y_mm)) in geometry.taxels().iter().zip(CENTRES_MM) {
        assert_eq!(
            (taxel.x_mm, taxel.y_mm, taxel.area_mm2),
            (x_mm, y_mm, AREA_MM2)
        );
        // A 5 mm electrode around this centre lies on the 11 mm pad.
        assert!(taxel.x_mm.abs() + 2.5 <= 5.5 && taxel.y_mm.abs() + 2.5 <= 5.5);
    }
    // Frame: x grows with the column (C11 -> C12), y towards row 1 (C21 -> C11).
    let [c11, c12, c21, _] = geometry.taxels();
    assert!(c12.x_mm > c11.x_mm && c11.y_mm > c21.y_mm);
    assert_eq!(geometry.taxel(4), None);
}

#[test]
fn invalid_geometry_is_refused_with_the_taxel_named() {
    let valid = *PadGeometry::default().taxels();
    let with = |index: usize, taxel: TaxelGeometry| {
        let mut taxels = valid;
        taxels[index] = taxel;
        PadGeometry::new(taxels)
    };
    let cases = [
        (
            1,
            TaxelGeometry::new(f32::NAN, 0.0, 25.0),
            GeometryError::NotFinite { taxel: 1 },
        ),
        (
            2,
            TaxelGeometry::new(0.0, f32::NEG_INFINITY, 25.0),
            GeometryError::NotFinite { taxel: 2 },
        ),
        (
            0,
            TaxelGeometry::new(0.0, 0.0, f32::INFINITY),
            GeometryError::NotFinite { taxel: 0 },
        ),
        (
            3,
            TaxelGeometry::new(0.0, 0.0, 0.0),
            GeometryError::AreaOutOfRange { taxel: 3 },
        ),
        (
            3,
            TaxelGeometry::new(0.0, 0.0, -25.0),
            GeometryError::AreaOutOfRange { taxel: 3 },
        ),
        (
            1,
            TaxelGeometry::new(0.0, 0.0, MAX_TAXEL_AREA_MM2 * 1.01),
            GeometryError::AreaOutOfRange { taxel: 1 },
        ),
        (
            0,
            TaxelGeometry::new(MAX_CENTRE_OFFSET_MM * 1.01, 0.0, 25.0),
            GeometryError::CentreOutOfRange { taxel: 0 },
        ),
        (
            2,
            TaxelGeometry::new(0.0, -MAX_CENTRE_OFFSET_MM * 1.01, 25.0),
            GeometryError::CentreOutOfRange { taxel: 2 },
        ),
    ];
    for (index, taxel, error) in cases {
        assert_eq!(with(index, taxel), Err(error), "{taxel:?}");
    }
    let at_the_bounds = TaxelGeometry::new(
        MAX_CENTRE_OFFSET_MM,
        -MAX_CENTRE_OFFSET_MM,
        MAX_TAXEL_AREA_MM2,
    );
    assert!(with(3, at_the_bounds).is_ok());
}

#[test]
fn a_centred_uniform_press_is_four_taxels_at_the_centre() {
    for pressure_kpa in [10.0f32, 30.0, 50.0] {
        let force = pad_force(
            &outputs([Taxel::Kpa(pressure_kpa); 4]),
            &PadGeometry::default(),
        );
        assert_force(&force, 4.0 * f64::from(pressure_kpa) * 25.0e-3);
        assert_centre(&force, (0.0, 0.0));
        assert_eq!(force.flags, PadForceFlags::empty());
    }
}

#[test]
fn the_articles_numbers_with_its_own_curve() {
    // Table 1: 50 kPa is dC/C0 = 0.2563. 50 kPa on one taxel is 1.25 N, on all four 5 N.
    let mut pad = article_pad();
    let loaded = TaxelReading::CapacitancePf(SENSOR_PF * 1.2563);
    let unloaded = TaxelReading::CapacitancePf(SENSOR_PF);
    let geometry = PadGeometry::default();
    let one = pad.process(&SampleInput::new(
        [loaded, unloaded, unloaded, unloaded],
        Some(25.0),
    ));
    assert_close(
        pad_force(&one.taxels, &geometry).force_n.unwrap(),
        1.25,
        1e-4,
        "one taxel",
    );
    let all = pad.process(&SampleInput::new([loaded; 4], Some(25.0)));
    assert_close(
        pad_force(&all.taxels, &geometry).force_n.unwrap(),
        5.0,
        1e-4,
        "four taxels",
    );
}

#[test]
fn a_press_on_one_taxel_puts_the_centre_on_that_taxel() {
    for (pressed, centre_mm) in CENTRES_MM.iter().enumerate() {
        let mut scene = [Taxel::Kpa(0.0); 4];
        scene[pressed] = Taxel::Kpa(20.0);
        let force = pad_force(&outputs(scene), &PadGeometry::default());
        assert_force(&force, 20.0 * 25.0e-3);
        // Exactly the centre: one loaded taxel bounds the centre to its own.
        assert_eq!(force.centre_of_pressure_mm, Some(*centre_mm));
        assert_eq!(force.flags, PadForceFlags::empty());
    }
}

#[test]
fn a_linear_sweep_moves_the_centre_linearly_between_two_taxels() {
    let total_kpa = 40.0f64;
    // Along a row, down a column, and across the diagonal.
    for (from, to) in [(0usize, 1usize), (1, 3), (0, 3), (2, 1)] {
        let (from_mm, to_mm) = (CENTRES_MM[from], CENTRES_MM[to]);
        for step in 0..=10 {
            let fraction = f64::from(step) / 10.0;
            let mut scene = [Taxel::Kpa(0.0); 4];
            scene[from] = Taxel::Kpa(((1.0 - fraction) * total_kpa) as f32);
            scene[to] = Taxel::Kpa((fraction * total_kpa) as f32);
            let force = pad_force(&outputs(scene), &PadGeometry::default());
            assert_force(&force, total_kpa * 25.0e-3);
            let expected_mm = (
                f64::from(from_mm.0) + fraction * f64::from(to_mm.0 - from_mm.0),
                f64::from(from_mm.1) + fraction * f64::from(to_mm.1 - from_mm.1),
            );
            assert_centre(&force, expected_mm);
        }
    }
}

#[test]
fn a_faulted_taxel_is_excluded_and_flagged() {
    for fault in [
        Taxel::Open,
        Taxel::Saturated,
        Taxel::Shorted,
        Taxel::Unavailable,
    ] {
        let scene = [Taxel::Kpa(20.0), Taxel::Kpa(20.0), Taxel::Kpa(20.0), fault];
        let force = pad_force(&outputs(scene), &PadGeometry::default());
        assert_force(&force, 3.0 * 20.0 * 25.0e-3);
        // The mean of the three centres that read.
        assert_centre(&force, (-2.75 / 3.0, 2.75 / 3.0));
        assert_eq!(
            force.flags,
            PadForceFlags::EXCLUDED_C22 | PadForceFlags::PARTIAL,
            "{fault:?}"
        );
    }
    // Two faulted: the pressed column on the right only.
    let scene = [
        Taxel::Open,
        Taxel::Kpa(10.0),
        Taxel::Saturated,
        Taxel::Kpa(30.0),
    ];
    let force = pad_force(&outputs(scene), &PadGeometry::default());
    assert_force(&force, 40.0 * 25.0e-3);
    assert_centre(&force, (2.75, (10.0 * 2.75 - 30.0 * 2.75) / 40.0));
    assert_eq!(
        force.flags,
        PadForceFlags::EXCLUDED_C11 | PadForceFlags::EXCLUDED_C21 | PadForceFlags::PARTIAL
    );
}

#[test]
fn with_every_taxel_faulted_there_is_no_force_at_all() {
    let scene = [
        Taxel::Open,
        Taxel::Saturated,
        Taxel::Shorted,
        Taxel::Unavailable,
    ];
    let none = PadForce {
        force_n: None,
        centre_of_pressure_mm: None,
        flags: PadForceFlags::EXCLUDED | PadForceFlags::NO_READING,
    };
    assert_eq!(pad_force(&outputs(scene), &PadGeometry::default()), none);
    // Before a tare every taxel is NOT_TARED.
    let untared = PadModel::new(Calibration::default()).process(&SampleInput::new(
        [TaxelReading::CapacitancePf(SENSOR_PF); 4],
        Some(25.0),
    ));
    assert_eq!(pad_force(&untared.taxels, &PadGeometry::default()), none);
    assert_eq!(
        pad_force_from_pressures(&[None; 4], &PadGeometry::default()),
        none
    );
}

#[test]
fn unequal_areas_weight_the_force_and_the_centre() {
    let taxels = [
        (-3.0f32, 2.0f32, 10.0f32),
        (4.0, 2.5, 20.0),
        (-2.5, -3.0, 30.0),
        (3.0, -3.5, 40.0),
    ];
    let geometry = PadGeometry::new(
        taxels.map(|(x_mm, y_mm, area_mm2)| TaxelGeometry::new(x_mm, y_mm, area_mm2)),
    )
    .unwrap();
    for pressures_kpa in [
        [10.0f32; 4],
        [10.0, 20.0, 30.0, 40.0],
        [0.0, 5.0, 0.0, 45.0],
    ] {
        let force = pad_force(&outputs(pressures_kpa.map(Taxel::Kpa)), &geometry);
        let forces_mn =
            pressures_kpa
                .iter()
                .zip(&taxels)
                .map(|(pressure_kpa, (_, _, area_mm2))| {
                    f64::from(*pressure_kpa) * f64::from(*area_mm2)
                });
        let total_mn: f64 = forces_mn.clone().sum();
        let moment = |coordinate: fn(&(f32, f32, f32)) -> f32| -> f64 {
            forces_mn
                .clone()
                .zip(&taxels)
                .map(|(force_mn, taxel)| force_mn * f64::from(coordinate(taxel)))
                .sum()
        };
        assert_force(&force, total_mn * 1e-3);
        assert_centre(
            &force,
            (
                moment(|taxel| taxel.0) / total_mn,
                moment(|taxel| taxel.1) / total_mn,
            ),
        );
    }
    // Uniform pressure: the centre is the area-weighted mean of the centres.
    let uniform = pad_force(&outputs([Taxel::Kpa(10.0); 4]), &geometry);
    assert_force(&uniform, 1.0);
    assert_centre(&uniform, (0.95, -1.6));
}

#[test]
fn below_the_floor_there_is_a_force_but_no_centre() {
    let geometry = PadGeometry::default();
    let unloaded = pad_force(&outputs([Taxel::Kpa(0.0); 4]), &geometry);
    assert_eq!(unloaded.force_n, Some(0.0));
    assert_eq!(unloaded.centre_of_pressure_mm, None);
    assert_eq!(unloaded.flags, PadForceFlags::empty());
    // 0.1 kPa on one taxel: 2.5 mN, under the 5 mN floor; 0.3 kPa: 7.5 mN, over it.
    const { assert!(COP_MIN_FORCE_N > 0.0025 && COP_MIN_FORCE_N < 0.0075) };
    let light = [
        Taxel::Kpa(0.0),
        Taxel::Kpa(0.1),
        Taxel::Kpa(0.0),
        Taxel::Kpa(0.0),
    ];
    let below = pad_force(&outputs(light), &geometry);
    assert_force(&below, 0.1 * 25.0e-3);
    assert_eq!(below.centre_of_pressure_mm, None);
    let firmer = [
        Taxel::Kpa(0.0),
        Taxel::Kpa(0.3),
        Taxel::Kpa(0.0),
        Taxel::Kpa(0.0),
    ];
    let above = pad_force(&outputs(firmer), &geometry);
    assert_eq!(above.centre_of_pressure_mm, Some(CENTRES_MM[1]));
}

#[test]
fn negative_pressures_count_as_zero_and_are_flagged() {
    let geometry = PadGeometry::default();
    let force =
        pad_force_from_pressures(&[Some(-0.4), Some(20.0), Some(0.0), Some(0.0)], &geometry);
    assert_force(&force, 20.0 * 25.0e-3);
    assert_eq!(force.centre_of_pressure_mm, Some(CENTRES_MM[1]));
    assert_eq!(force.flags, PadForceFlags::NEGATIVE_CLAMPED);
    // All negative is an unloaded pad that read, not a missing one.
    let all_negative = pad_force_from_pressures(&[Some(-5.0); 4], &geometry);
    assert_eq!(all_negative.force_n, Some(0.0));
    assert_eq!(all_negative.centre_of_pressure_mm, None);
    assert_eq!(all_negative.flags, PadForceFlags::NEGATIVE_CLAMPED);
}

#[test]
fn implausible_pressures_are_excluded_like_faults() {
    let pressures = [
        Some(f32::NAN),
        Some(f32::INFINITY),
        Some(MAX_PRESSURE_KPA * 2.0),
        Some(10.0),
    ];
    let force = pad_force_from_pressures(&pressures, &PadGeometry::default());
    assert_force(&force, 10.0 * 25.0e-3);
    assert_eq!(force.centre_of_pressure_mm, Some(CENTRES_MM[3]));
    let excluded =
        PadForceFlags::EXCLUDED_C11 | PadForceFlags::EXCLUDED_C12 | PadForceFlags::EXCLUDED_C21;
    assert_eq!(force.flags, excluded | PadForceFlags::PARTIAL);
}

#[test]
fn an_over_range_taxel_makes_the_force_a_lower_bound() {
    let mut pad = linear_pad();
    let unloaded = TaxelReading::CapacitancePf(SENSOR_PF);
    // dC/C0 = 1.5, beyond the top point (1.0 at 100 kPa): clamped to 100 kPa and flagged.
    let beyond = TaxelReading::CapacitancePf(SENSOR_PF * 2.5);
    let output = pad.process(&SampleInput::new(
        [beyond, unloaded, unloaded, unloaded],
        Some(25.0),
    ));
    assert!(output.taxels[0].flags().contains(TaxelFlags::OVER_RANGE));
    let force = pad_force(&output.taxels, &PadGeometry::default());
    assert_force(&force, f64::from(LINEAR_TOP_KPA) * 25.0e-3);
    assert_eq!(force.flags, PadForceFlags::LOWER_BOUND);
}

#[test]
fn warnings_do_not_exclude_a_taxel() {
    let mut pad = linear_pad();
    let pressed = TaxelReading::CapacitancePf(SENSOR_PF * 1.2);
    // 5 % below the baseline: BELOW_BASELINE, reported as 0 kPa.
    let drifted = TaxelReading::CapacitancePf(SENSOR_PF * 0.95);
    let output = pad.process(&SampleInput::new(
        [pressed, drifted, pressed, pressed],
        Some(25.0),
    ));
    assert_eq!(output.taxels[1].flags(), TaxelFlags::BELOW_BASELINE);
    let force = pad_force(&output.taxels, &PadGeometry::default());
    assert_force(&force, 3.0 * 20.0 * 25.0e-3);
    assert_eq!(force.flags, PadForceFlags::empty());
}

/// Any finite f32, weighted towards the pad's range.
fn finite_pressure_kpa() -> impl Strategy<Value = f32> {
    use proptest::num::f32 as any_f32;
    prop_oneof![
        3 => -1.0f32..60.0,
        1 => any_f32::POSITIVE | any_f32::NEGATIVE | any_f32::NORMAL | any_f32::SUBNORMAL | any_f32::ZERO,
    ]
}

fn valid_taxel() -> impl Strategy<Value = TaxelGeometry> {
    let offset_mm = -MAX_CENTRE_OFFSET_MM..=MAX_CENTRE_OFFSET_MM;
    (offset_mm.clone(), offset_mm, 1.0e-6f32..=MAX_TAXEL_AREA_MM2)
        .prop_map(|(x_mm, y_mm, area_mm2)| TaxelGeometry::new(x_mm, y_mm, area_mm2))
}

/// Checks a result against the taxels the test itself takes as reading (`Some` centre).
fn check_against_valid_centres(
    force: &PadForce,
    valid: &[Option<(f32, f32)>; 4],
    expected_force_n: f64,
) -> Result<(), TestCaseError> {
    for (index, centre) in valid.iter().enumerate() {
        prop_assert_eq!(force.flags.is_excluded(index), centre.is_none());
    }
    let Some(force_n) = force.force_n else {
        prop_assert!(valid.iter().all(Option::is_none));
        prop_assert!(force.flags.contains(PadForceFlags::NO_READING));
        prop_assert_eq!(force.centre_of_pressure_mm, None);
        return Ok(());
    };
    prop_assert!(force_n.is_finite() && force_n >= 0.0, "{:?}", force);
    prop_assert!((f64::from(force_n) - expected_force_n).abs() <= 1e-5 * expected_force_n + 1e-30);
    prop_assert_eq!(
        force.centre_of_pressure_mm.is_some(),
        force_n >= COP_MIN_FORCE_N
    );
    if let Some((x_mm, y_mm)) = force.centre_of_pressure_mm {
        let centres = valid.iter().flatten();
        let inside_x = centres.clone().any(|centre| centre.0 <= x_mm)
            && centres.clone().any(|centre| centre.0 >= x_mm);
        let inside_y = centres.clone().any(|centre| centre.1 <= y_mm)
            && centres.clone().any(|centre| centre.1 >= y_mm);
        prop_assert!(inside_x && inside_y, "{:?} outside {:?}", force, valid);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Any finite pressures on any valid geometry: the force is finite and non-negative, is the
    /// sum the test forms itself, and the centre lies in the bounding box of the centres of the
    /// taxels that read.
    #[test]
    fn force_is_finite_and_the_centre_inside_the_valid_centres(
        taxels in [valid_taxel(), valid_taxel(), valid_taxel(), valid_taxel()],
        pressures_kpa in [
            proptest::option::weighted(0.85, finite_pressure_kpa()),
            proptest::option::weighted(0.85, finite_pressure_kpa()),
            proptest::option::weighted(0.85, finite_pressure_kpa()),
            proptest::option::weighted(0.85, finite_pressure_kpa()),
        ],
    ) {
        let geometry = PadGeometry::new(taxels).unwrap();
        let force = pad_force_from_pressures(&pressures_kpa, &geometry);
        let mut valid = [None; 4];
        let mut expected_force_n = 0.0f64;
        for ((slot, pressure_kpa), taxel) in valid.iter_mut().zip(pressures_kpa).zip(&taxels) {
            if let Some(pressure_kpa) = pressure_kpa.filter(|pressure_kpa| pressure_kpa.abs() <= MAX_PRESSURE_KPA) {
                *slot = Some((taxel.x_mm, taxel.y_mm));
                expected_force_n += f64::from(pressure_kpa.max(0.0)) * f64::from(taxel.area_mm2) * 1e-3;
            }
        }
        check_against_valid_centres(&force, &valid, expected_force_n)?;
    }

    /// Any converter readings through the model: faulted taxels are the excluded ones, and the
    /// same properties hold.
    #[test]
    fn any_readings_give_a_finite_force_from_the_taxels_that_read(
        readings_pf in [
            prop_oneof![3.0f32..12.0, -1.0f32..3.0, Just(f32::NAN)],
            prop_oneof![3.0f32..12.0, -1.0f32..3.0, Just(f32::NAN)],
            prop_oneof![3.0f32..12.0, -1.0f32..3.0, Just(f32::NAN)],
            prop_oneof![3.0f32..12.0, -1.0f32..3.0, Just(f32::NAN)],
        ],
    ) {
        let output = article_pad().process(&SampleInput::new(readings_pf.map(TaxelReading::CapacitancePf), Some(25.0)));
        let force = pad_force(&output.taxels, &PadGeometry::default());
        let mut valid = [None; 4];
        let mut expected_force_n = 0.0f64;
        for ((slot, taxel), centre) in valid.iter_mut().zip(&output.taxels).zip(CENTRES_MM) {
            if let Some(pressure_kpa) = taxel.pressure_kpa() {
                *slot = Some(centre);
                expected_force_n += f64::from(pressure_kpa) * f64::from(AREA_MM2) * 1e-3;
            }
        }
        check_against_valid_centres(&force, &valid, expected_force_n)?;
    }
}
