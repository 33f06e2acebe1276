//! Detects a converter channel that repeats one code for many consecutive cycles, whatever the
//! other channels do: the "bouncing values / locked channel" failure users of the FDC1004 report
//! in repeat mode (one channel frozen, or the whole converter returning stale results).

use model_core::reading::{SATURATED_HIGH_CODE, SATURATED_LOW_CODE};
use model_core::TAXEL_COUNT;

/// Counts, per channel, how many consecutive cycles repeated the previous code.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StuckDetector {
    previous_codes: Option<[i32; TAXEL_COUNT]>,
    repeats: [u16; TAXEL_COUNT],
    stuck_after_cycles: u16,
}

impl StuckDetector {
    /// A detector that calls a channel stuck after `stuck_after_cycles` repeats (0 disables it).
    pub fn new(stuck_after_cycles: u16) -> Self {
        Self {
            previous_codes: None,
            repeats: [0; TAXEL_COUNT],
            stuck_after_cycles,
        }
    }

    /// Forgets history (after a re-initialisation).
    pub fn reset(&mut self) {
        self.previous_codes = None;
        self.repeats = [0; TAXEL_COUNT];
    }

    /// Feeds one cycle's codes; returns which channels are stuck. With 0.5 fF rms noise over a
    /// 1.9 aF step, a live channel repeats one code for a few cycles at most, so a long run of
    /// repeats is a fault, not a quiet pad: one channel frozen while the others move, or the whole
    /// converter returning stale results.
    pub fn update(&mut self, codes: &[i32; TAXEL_COUNT]) -> [bool; TAXEL_COUNT] {
        if let Some(previous_codes) = self.previous_codes {
            let channels = self.repeats.iter_mut().zip(codes).zip(previous_codes);
            for ((repeats, &code), previous_code) in channels {
                // A saturation code repeats by nature and is flagged as saturated already.
                let saturated = matches!(code, SATURATED_HIGH_CODE | SATURATED_LOW_CODE);
                if code == previous_code && !saturated {
                    *repeats = repeats.saturating_add(1);
                } else {
                    *repeats = 0;
                }
            }
        }
        self.previous_codes = Some(*codes);
        if self.stuck_after_cycles == 0 {
            return [false; TAXEL_COUNT];
        }
        self.repeats
            .map(|repeats| repeats >= self.stuck_after_cycles)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frozen_channel_among_moving_ones_is_stuck() {
        let mut detector = StuckDetector::new(3);
        let mut flagged = [false; TAXEL_COUNT];
        for cycle in 0..5 {
            flagged = detector.update(&[cycle, 7, cycle * 2, -cycle]);
        }
        assert_eq!(flagged, [false, true, false, false]);
    }

    #[test]
    fn a_saturated_channel_is_not_also_stuck() {
        let mut detector = StuckDetector::new(3);
        let mut flagged = [true; TAXEL_COUNT];
        for cycle in 0..10 {
            flagged = detector.update(&[SATURATED_HIGH_CODE, SATURATED_LOW_CODE, cycle, -cycle]);
        }
        assert_eq!(flagged, [false; TAXEL_COUNT]);
    }

    #[test]
    fn a_frozen_converter_is_stuck_on_every_channel() {
        let mut detector = StuckDetector::new(3);
        let mut flagged = [false; TAXEL_COUNT];
        for _ in 0..4 {
            flagged = detector.update(&[1, 2, 3, 4]);
        }
        assert_eq!(flagged, [true; TAXEL_COUNT]);
        detector.reset();
        assert_eq!(detector.update(&[1, 2, 3, 4]), [false; TAXEL_COUNT]);
    }
}
