//! Inversion tiers on the article's curve: interpolation, monotonicity, round trips, the top of
//! the curve and the closed form near its asymptote, against f64 references.
//!
//! The research tiers' own tests need the feature `research-tiers`
//! (`cargo test -p model-core --features research-tiers`); without it those tiers fall back to
//! the default tier here, which the tests over every tier still hold to.

use model_core::inverse::{InverseCurve, MonotoneCubicInverse};
#[cfg(feature = "research-tiers")]
use model_core::inverse::{Libm, Micromath, SaturatingFit, SaturatingInverse};
use model_core::{CalibrationCurve, CurvePoint, TaxelInverses, Tier, ARTICLE_TABLE_1};
use proptest::prelude::*;

fn article() -> (CalibrationCurve, TaxelInverses) {
    let curve = CalibrationCurve::article_default();
    let inverses = TaxelInverses::new(&curve);
    (curve, inverses)
}

/// f64 reference of the forward monotone cubic: the same Fritsch–Carlson construction, evaluated
/// in f64, inverted by bisection to full f64 precision.
fn reference_pressure_kpa(inverse: &MonotoneCubicInverse, relative_change: f64) -> f64 {
    let forward = inverse.forward();
    let value = |pressure: f64| -> f64 {
        let segments = forward.segments();
        let mut index = 0;
        while index + 1 < segments.len() && pressure >= segments[index + 1].x_start as f64 {
            index += 1;
        }
        let segment = segments[index];
        let s = pressure - segment.x_start as f64;
        let [c0, c1, c2, c3] = segment.coefficients.map(|c| c as f64);
        c0 + s * (c1 + s * (c2 + s * c3))
    };
    let (mut low, mut high) = (0.0f64, 50.0f64);
    for _ in 0..200 {
        let middle = 0.5 * (low + high);
        if value(middle) < relative_change {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

#[test]
fn interpolating_tiers_reproduce_every_calibration_point() {
    let (_, inverses) = article();
    for tier in Tier::ALL
        .into_iter()
        .filter(|tier| tier.interpolates_points())
    {
        for point in ARTICLE_TABLE_1 {
            let pressure = inverses.pressure_kpa(tier, point.relative_change);
            assert!(
                (pressure - point.pressure_kpa).abs() < 2e-3,
                "{tier:?} at {point:?} gave {pressure}"
            );
        }
    }
}

#[test]
fn every_tier_is_continuous_around_every_calibration_point() {
    let (_, inverses) = article();
    for tier in Tier::ALL {
        for point in ARTICLE_TABLE_1 {
            let at = inverses.pressure_kpa(tier, point.relative_change);
            for neighbour in [
                f32::from_bits(point.relative_change.to_bits().saturating_sub(1)),
                f32::from_bits(point.relative_change.to_bits() + 1),
            ] {
                let near = inverses.pressure_kpa(tier, neighbour);
                assert!(
                    (near - at).abs() < 1e-3,
                    "{tier:?} jumps at {point:?}: {at} vs {near}"
                );
            }
        }
    }
}

#[test]
fn monotone_cubic_matches_its_f64_reference_within_two_hundred_thousandths_of_a_kpa() {
    let (curve, inverses) = article();
    let top = curve.top().relative_change;
    let mut worst = 0.0f64;
    for step in 0..=20_000 {
        let relative_change = top * step as f32 / 20_000.0;
        let got = inverses.monotone_cubic().pressure_kpa(relative_change) as f64;
        let want = reference_pressure_kpa(inverses.monotone_cubic(), relative_change as f64);
        worst = worst.max((got - want).abs());
    }
    // The fast path accepts 1e-5 kPa in exact arithmetic; f32 rounding of dC/C0 adds about as much.
    assert!(worst < 2e-5, "worst error {worst} kPa");
}

#[test]
fn forward_of_inverse_round_trips() {
    let (curve, inverses) = article();
    let top = curve.top().relative_change;
    for step in 0..=10_000 {
        let relative_change = top * step as f32 / 10_000.0;
        let pressure = inverses.pressure_kpa(Tier::MonotoneCubic, relative_change);
        let back = inverses.relative_change_at(pressure);
        assert!(
            (back - relative_change).abs() < 2e-6,
            "{relative_change} -> {pressure} -> {back}"
        );
        let table_pressure = inverses.pressure_kpa(Tier::Table, relative_change);
        assert!((inverses.relative_change_at(table_pressure) - relative_change).abs() < 1e-4);
    }
}

#[test]
fn tiers_stay_close_to_the_reference_where_their_design_says() {
    let (_, inverses) = article();
    let max_deviation = |tier| {
        (0..=5000)
            .map(|step| {
                let pressure = step as f32 * 0.01;
                let relative_change = inverses.relative_change_at(pressure);
                (inverses.pressure_kpa(tier, relative_change) - pressure).abs()
            })
            .fold(0.0f32, f32::max)
    };
    assert!(max_deviation(Tier::MonotoneCubic) < 1e-3);
    assert!(max_deviation(Tier::Table) < 0.02);
    #[cfg(feature = "research-tiers")]
    {
        assert!(max_deviation(Tier::Polynomial) < 0.1);
        assert!(max_deviation(Tier::PiecewiseLinear) < 1.5);
        assert!(max_deviation(Tier::Saturating) < 1.5);
        assert!(max_deviation(Tier::SaturatingMicromath) < 1.6);
    }
    // The linear tier is there to show what ignoring the curvature costs.
    assert!(max_deviation(Tier::Linear) > 5.0);
}

#[test]
fn top_of_the_curve_is_reached_and_never_exceeded() {
    let (curve, inverses) = article();
    let top = curve.top();
    for tier in Tier::ALL {
        let below = inverses.pressure_kpa(tier, f32::from_bits(top.relative_change.to_bits() - 1));
        let at = inverses.pressure_kpa(tier, top.relative_change);
        let above = inverses.pressure_kpa(tier, top.relative_change * 1.5);
        assert!(below <= at && at <= top.pressure_kpa, "{tier:?}");
        assert!(above <= top.pressure_kpa && above.is_finite(), "{tier:?}");
        if tier.interpolates_points() {
            assert!(
                (at - top.pressure_kpa).abs() < 1e-3,
                "{tier:?} at top gave {at}"
            );
        }
    }
}

#[cfg(feature = "research-tiers")]
#[test]
fn saturating_fit_is_sane_and_its_inverse_survives_the_asymptote() {
    let (curve, _) = article();
    let fit = SaturatingFit::new(&curve).expect("the article's curve is concave");
    assert!(fit.asymptote > 0.2563 && fit.asymptote < 1.0, "{fit:?}");
    assert!(fit.scale_kpa > 5.0 && fit.scale_kpa < 200.0, "{fit:?}");
    let inverse = SaturatingInverse::<Libm>::new(&fit, 50.0);
    let asymptote = fit.asymptote;
    for relative_change in [
        asymptote - 1e-3,
        asymptote - 1e-6,
        f32::from_bits(asymptote.to_bits() - 1),
        asymptote,
        f32::from_bits(asymptote.to_bits() + 1),
        asymptote + 1.0,
        f32::INFINITY,
        f32::NAN,
    ] {
        let pressure = inverse.pressure_kpa(relative_change);
        assert!(
            pressure.is_finite() && (0.0..=50.0).contains(&pressure),
            "{relative_change} -> {pressure}"
        );
    }
    // Where the closed form is defined and below the top, it agrees with f64 within f32 rounding.
    for step in 0..=1000 {
        let relative_change = 0.25 * step as f32 / 1000.0;
        let want = fit.scale_kpa as f64
            * (fit.asymptote as f64 / (fit.asymptote as f64 - relative_change as f64)).ln();
        let got = inverse.pressure_kpa(relative_change) as f64;
        assert!(
            (got - want.min(50.0)).abs() < 2e-4,
            "{relative_change}: {got} vs {want}"
        );
    }
}

#[test]
fn a_curve_that_is_not_concave_has_no_saturating_fit() {
    let convex = CalibrationCurve::new(
        &[
            CurvePoint::new(0.0, 0.0),
            CurvePoint::new(10.0, 0.01),
            CurvePoint::new(20.0, 0.05),
            CurvePoint::new(30.0, 0.2),
        ],
        0,
    )
    .unwrap();
    let inverses = TaxelInverses::new(&convex);
    assert!(!inverses.supports(Tier::Saturating));
    // Asking anyway falls back to the reference rather than inventing numbers.
    let relative_change = 0.05;
    assert_eq!(
        inverses.pressure_kpa(Tier::Saturating, relative_change),
        inverses.pressure_kpa(Tier::MonotoneCubic, relative_change)
    );
}

/// micromath's ln is only fed arguments >= 1, where it is usable; below 1 it is not.
#[cfg(feature = "research-tiers")]
#[test]
fn micromath_ln_is_only_used_where_it_is_accurate() {
    let (curve, inverses) = article();
    let fit = inverses.saturating_fit().copied().unwrap();
    let largest_argument = fit.asymptote / (fit.asymptote - curve.top().relative_change);
    let mut worst_absolute = 0.0f64;
    for step in 0..=10_000 {
        let x = 1.0 + (largest_argument - 1.0) * step as f32 / 10_000.0;
        let got = micromath::F32Ext::ln(x) as f64;
        let want = (x as f64).ln();
        worst_absolute = worst_absolute.max((got - want).abs());
    }
    // Times the fitted scale B (tens of kPa) this stays well below 0.1 kPa.
    assert!(
        worst_absolute < 2e-3,
        "micromath ln above 1: {worst_absolute}"
    );
    // The trap this design avoids: the same ln below 1 is grossly wrong.
    let below_one = micromath::F32Ext::ln(0.9f32) as f64;
    assert!((below_one - 0.9f64.ln()).abs() > 0.01);
    let micromath_inverse = SaturatingInverse::<Micromath>::new(&fit, 50.0);
    let libm_inverse = SaturatingInverse::<Libm>::new(&fit, 50.0);
    for step in 0..=1000 {
        let relative_change = curve.top().relative_change * step as f32 / 1000.0;
        let difference = (micromath_inverse.pressure_kpa(relative_change)
            - libm_inverse.pressure_kpa(relative_change))
        .abs();
        assert!(difference < 0.1, "{relative_change}: {difference}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_tier_is_non_decreasing(a in 0.0f32..0.2563, b in 0.0f32..0.2563) {
        let (_, inverses) = article();
        let (low, high) = if a <= b { (a, b) } else { (b, a) };
        for tier in Tier::ALL {
            let (p_low, p_high) = (inverses.pressure_kpa(tier, low), inverses.pressure_kpa(tier, high));
            prop_assert!(p_low <= p_high + 1e-5, "{:?}: f({}) = {} > f({}) = {}", tier, low, p_low, high, p_high);
        }
    }

    #[test]
    fn any_bits_give_a_bounded_finite_pressure(bits in any::<u32>()) {
        let (_, inverses) = article();
        let relative_change = f32::from_bits(bits);
        for tier in Tier::ALL {
            let pressure = inverses.pressure_kpa(tier, relative_change);
            prop_assert!(pressure.is_finite() && (0.0..=50.0).contains(&pressure));
        }
    }
}

/// The polynomial degree: the smallest whose deviation from the reference is well inside the
/// 0.5 kPa the speed tier is allowed (printed with --nocapture).
#[cfg(feature = "research-tiers")]
#[test]
fn polynomial_degree_study() {
    use model_core::inverse::PolynomialInverse;
    let (curve, inverses) = article();
    let cubic = inverses.monotone_cubic();
    let deviation = |coefficients: &[f32]| {
        (0..=5000)
            .map(|step| {
                let pressure = step as f32 * 0.01;
                let u = inverses.relative_change_at(pressure) / curve.top().relative_change;
                let value = coefficients.iter().rev().fold(0.0f32, |acc, c| acc * u + c) * u;
                (value - pressure).abs()
            })
            .fold(0.0f32, f32::max)
    };
    let results = [
        (
            4,
            PolynomialInverse::with_degree::<4>(cubic, &curve).map(|c| deviation(&c)),
        ),
        (
            5,
            PolynomialInverse::with_degree::<5>(cubic, &curve).map(|c| deviation(&c)),
        ),
        (
            6,
            PolynomialInverse::with_degree::<6>(cubic, &curve).map(|c| deviation(&c)),
        ),
        (
            7,
            PolynomialInverse::with_degree::<7>(cubic, &curve).map(|c| deviation(&c)),
        ),
        (
            8,
            PolynomialInverse::with_degree::<8>(cubic, &curve).map(|c| deviation(&c)),
        ),
    ];
    for (degree, result) in results {
        println!("degree {degree}: max deviation from the reference {result:?} kPa");
    }
    let chosen = results
        .iter()
        .find(|(degree, _)| *degree == model_core::inverse::POLYNOMIAL_DEGREE)
        .and_then(|(_, result)| *result)
        .expect("the chosen degree fits");
    assert!(chosen < 0.2, "{chosen}");
}
