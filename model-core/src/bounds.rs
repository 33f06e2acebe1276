//! Clamping by comparison. The Cortex-M4F's FPU has no minimum or maximum instruction, so
//! `f32::min`, `f32::max` and `f32::clamp` compile to calls of `fminf`/`fmaxf` (about 14
//! instructions each, measured under QEMU); two compares and selects do the same here, and send
//! NaN to the lower bound, which is the safe side for every caller.

/// `value` limited to `low ..= high` (NaN gives `low`); requires `low <= high`.
#[inline(always)]
pub(crate) fn clamp_f32(value: f32, low: f32, high: f32) -> f32 {
    if !(value > low) {
        low
    } else if value > high {
        high
    } else {
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn behaves_like_clamp_and_sends_nan_low() {
        for value in [
            -2.0f32,
            -1.0,
            -0.5,
            0.0,
            0.25,
            1.0,
            3.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            assert_eq!(clamp_f32(value, -1.0, 1.0), value.clamp(-1.0, 1.0));
        }
        assert_eq!(clamp_f32(f32::NAN, -1.0, 1.0), -1.0);
    }
}
