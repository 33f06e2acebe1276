//! Event counters that travel with every sample set, so a consumer sees what the loop went
//! through even when it missed the sets in between.

use fdc1004::Error;

/// Counts since start; every counter saturates at 2^32 - 1 (a count never restarts from 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Converter initialisations: the first one and every one after an error (one that only
    /// applies a requested rate change is not counted).
    pub converter_inits: u32,
    /// Initialisations after an error: every one but each converter's first (summed over pads,
    /// it stays the number of recoveries).
    pub converter_reinits: u32,
    /// I2C transfers to the converter that failed.
    pub i2c_errors: u32,
    /// Converter cycles whose DONE bits did not all set in time.
    pub done_timeouts: u32,
    /// Initialisations refused because the ID or the configuration read back wrong.
    pub converter_check_failures: u32,
    /// Reads that returned zero on all four channels.
    pub zero_reads: u32,
    /// Cycles in which a stuck channel was detected.
    pub stuck_events: u32,
    /// Failed temperature reads (primary or fallback).
    pub temperature_errors: u32,
}

impl Counters {
    /// Counts one converter error by kind.
    pub(crate) fn count_converter_error<E>(&mut self, error: &Error<E>) {
        let counter = match error {
            Error::I2c(_) => &mut self.i2c_errors,
            Error::DoneTimeout { .. } => &mut self.done_timeouts,
            Error::WrongDeviceId { .. }
            | Error::ConfigMismatch { .. }
            | Error::ResetTimeout
            | Error::InvalidConfig => &mut self.converter_check_failures,
        };
        *counter = counter.saturating_add(1);
    }

    /// Adds one to a counter, saturating.
    pub(crate) fn bump(counter: &mut u32) {
        *counter = counter.saturating_add(1);
    }

    /// Both counts added, counter by counter (saturating): several pads' counters as one.
    pub fn plus(&self, other: &Counters) -> Counters {
        Counters {
            converter_inits: self.converter_inits.saturating_add(other.converter_inits),
            converter_reinits: self
                .converter_reinits
                .saturating_add(other.converter_reinits),
            i2c_errors: self.i2c_errors.saturating_add(other.i2c_errors),
            done_timeouts: self.done_timeouts.saturating_add(other.done_timeouts),
            converter_check_failures: self
                .converter_check_failures
                .saturating_add(other.converter_check_failures),
            zero_reads: self.zero_reads.saturating_add(other.zero_reads),
            stuck_events: self.stuck_events.saturating_add(other.stuck_events),
            temperature_errors: self
                .temperature_errors
                .saturating_add(other.temperature_errors),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_saturate_instead_of_wrapping() {
        let mut counters = Counters {
            i2c_errors: u32::MAX,
            ..Counters::default()
        };
        counters.count_converter_error::<()>(&Error::I2c(()));
        assert_eq!(counters.i2c_errors, u32::MAX);
        let mut count = u32::MAX - 1;
        Counters::bump(&mut count);
        Counters::bump(&mut count);
        assert_eq!(count, u32::MAX);
    }

    #[test]
    fn recoveries_add_up_over_pads() {
        // Two pads, each initialised once and recovered twice: 2 + 2 recoveries, not 6 - 1.
        let pad = Counters {
            converter_inits: 3,
            converter_reinits: 2,
            ..Counters::default()
        };
        let total = pad.plus(&pad);
        assert_eq!((total.converter_inits, total.converter_reinits), (6, 4));
    }
}
