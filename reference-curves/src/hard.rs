//! A deterministic generator of valid, hard calibration curves: what users can produce when
//! they calibrate their own pads, including the ill-conditioned cases a fixed Newton iteration
//! gets wrong.

/// Most points a generated curve holds (model-core's limit).
pub const HARD_CALIBRATION_POINTS_MAX: usize = 16;

/// The kind of difficulty a generated curve has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CurveShape {
    /// Concave and saturating like the article's, with random spacing.
    Saturating,
    /// Some neighbouring points almost equal in dC/C0 (steps down to 1e-5).
    NearlyEqualNeighbours,
    /// The last steps are tiny: a nearly flat top.
    FlatTop,
    /// A large first step at a small pressure, then slow growth.
    SteepStart,
    /// Every step drawn log-uniformly over four decades, in pressure and in dC/C0.
    Random,
}

impl CurveShape {
    const ALL: [CurveShape; 5] = [
        CurveShape::Saturating,
        CurveShape::NearlyEqualNeighbours,
        CurveShape::FlatTop,
        CurveShape::SteepStart,
        CurveShape::Random,
    ];
}

/// SplitMix64: small, deterministic, good enough to spread seeds.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Log-uniform in [low, high).
    fn log_uniform(&mut self, low: f64, high: f64) -> f64 {
        low * (high / low).powf(self.unit())
    }

    fn below(&mut self, bound: usize) -> usize {
        (self.next() % bound.max(1) as u64) as usize
    }
}

/// The next f32 above `value` (for positive finite values).
fn next_up(value: f32) -> f32 {
    f32::from_bits(value.to_bits() + 1)
}

/// A valid calibration curve for `seed`: (pressure kPa, dC/C0) points as f32, starting at
/// (0, 0), strictly increasing in both after rounding to f32, 2 ..= 16 points, and its shape.
pub fn hard_calibration(seed: u64) -> (Vec<(f32, f32)>, CurveShape) {
    let mut random = SplitMix(seed);
    let shape = CurveShape::ALL[random.below(CurveShape::ALL.len())];
    let count = 2 + random.below(HARD_CALIBRATION_POINTS_MAX - 1);
    let intervals = count - 1;
    let mut pressure_steps_kpa = Vec::with_capacity(intervals);
    let mut relative_steps = Vec::with_capacity(intervals);
    let first_relative = random.log_uniform(0.01, 0.3);
    let decay = random.log_uniform(0.3, 1.0);
    for interval in 0..intervals {
        let pressure_step_kpa = match shape {
            CurveShape::Random => random.log_uniform(0.01, 100.0),
            CurveShape::SteepStart if interval == 0 => random.log_uniform(0.01, 1.0),
            _ => random.log_uniform(1.0, 20.0),
        };
        let relative_step = match shape {
            CurveShape::Saturating => first_relative * decay.powi(interval as i32),
            CurveShape::NearlyEqualNeighbours => {
                if random.unit() < 0.4 {
                    random.log_uniform(1e-5, 1e-4)
                } else {
                    first_relative * decay.powi(interval as i32)
                }
            }
            CurveShape::FlatTop => {
                if interval + 2 >= intervals && interval > 0 {
                    random.log_uniform(1e-5, 1e-3)
                } else {
                    first_relative * decay.powi(interval as i32)
                }
            }
            CurveShape::SteepStart => {
                if interval == 0 {
                    random.log_uniform(0.1, 0.5)
                } else {
                    random.log_uniform(1e-4, 0.02)
                }
            }
            CurveShape::Random => random.log_uniform(1e-5, 0.1),
        };
        pressure_steps_kpa.push(pressure_step_kpa);
        relative_steps.push(relative_step);
    }
    let mut points = vec![(0.0f32, 0.0f32)];
    let (mut pressure_kpa, mut relative_change) = (0.0f64, 0.0f64);
    for (pressure_step_kpa, relative_step) in pressure_steps_kpa.into_iter().zip(relative_steps) {
        pressure_kpa += pressure_step_kpa;
        relative_change += relative_step;
        let (previous_pressure, previous_relative) = points[points.len() - 1];
        let pressure = (pressure_kpa as f32).max(next_up(previous_pressure));
        let relative = (relative_change as f32).max(next_up(previous_relative));
        points.push((pressure, relative));
    }
    (points, shape)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_curve_is_valid_and_every_shape_appears() {
        let mut seen = Vec::new();
        for seed in 0..5000 {
            let (points, shape) = hard_calibration(seed);
            assert!((2..=HARD_CALIBRATION_POINTS_MAX).contains(&points.len()));
            assert_eq!(points[0], (0.0, 0.0));
            for pair in points.windows(2) {
                assert!(
                    pair[1].0 > pair[0].0 && pair[1].1 > pair[0].1,
                    "seed {seed}"
                );
                assert!(pair[1].0.is_finite() && pair[1].1.is_finite());
            }
            if !seen.contains(&shape) {
                seen.push(shape);
            }
        }
        assert_eq!(seen.len(), CurveShape::ALL.len());
    }

    #[test]
    fn is_deterministic() {
        assert_eq!(hard_calibration(42), hard_calibration(42));
        assert_ne!(hard_calibration(42), hard_calibration(43));
    }

    #[test]
    fn nearly_equal_neighbours_reach_1e_5() {
        let smallest = (0..2000)
            .map(hard_calibration)
            .filter(|(_, shape)| *shape == CurveShape::NearlyEqualNeighbours)
            .flat_map(|(points, _)| {
                points
                    .windows(2)
                    .map(|pair| pair[1].1 - pair[0].1)
                    .collect::<Vec<_>>()
            })
            .fold(f32::INFINITY, f32::min);
        assert!(smallest < 2e-5, "{smallest}");
    }
}
