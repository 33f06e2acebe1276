//! Contact on/off per pad from its normal force ([`crate::pad_force`]), with hysteresis and a
//! debounce, reported as events carrying the device timestamp of the sample set that confirmed
//! the change.
//!
//! Contact starts when the force is above the on threshold for `debounce_sets` consecutive sample
//! sets, and ends when it is below the (lower) off threshold for as many. Between the thresholds
//! the state holds; a set that breaks a run restarts its count.
//!
//! What a set without a trustworthy force does: no force ([`PadForceFlags::NO_READING`], or a
//! non-finite one) holds the state and restarts the count, so a fault can never toggle contact.
//! A partial force (some taxels excluded) is the force on the taxels that read, a lower bound of
//! the pad's: enough to start a contact, and enough to end one only when every taxel excluded now
//! was already excluded when the contact started. A taxel that faults during a contact (a
//! saturated or shorted taxel is typically the most loaded one) therefore cannot end it; a taxel
//! that was dead before the contact does not prevent its end. The cost: if a taxel fails during a
//! contact and stays failed, the contact stays on until it reads again or
//! [`ContactDetector::reset`] is called; every such set is flagged [`PadForceFlags::PARTIAL`].

use core::fmt;

use crate::pad_force::{PadForce, PadForceFlags};

/// Default on threshold, N: 2 kPa on one of the article's 25 mm² taxels (0.5 kPa on each of
/// four). The converter's 0.5 fF rms noise is about 0.013 kPa (0.33 mN) per taxel at the bottom
/// of the article's curve, about 0.7 mN on the whole pad: the threshold is some 75x that.
pub const DEFAULT_ON_THRESHOLD_N: f32 = 0.05;

/// Default off threshold, N: 1.2 kPa on one taxel. The 0.02 N between the thresholds is some 30x
/// the pad's noise rms, so noise around either threshold cannot cross both.
pub const DEFAULT_OFF_THRESHOLD_N: f32 = 0.03;

/// Default debounce, sample sets: 30 ms at 100 sets/s (the converter at 400 S/s, four taxels in
/// turn), 120 ms at 25 sets/s (100 S/s). A spike or dropout shorter than three sets changes
/// nothing.
pub const DEFAULT_DEBOUNCE_SETS: u16 = 3;

/// Thresholds and debounce of a [`ContactDetector`], validated.
///
/// Always `0 < off_threshold_n < on_threshold_n`, both finite, and `debounce_sets >= 1`: only
/// [`ContactConfig::new`] (or [`Default`], or deserialization, which goes through `new`) builds
/// one.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(try_from = "UncheckedContactConfig"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ContactConfig {
    on_threshold_n: f32,
    off_threshold_n: f32,
    debounce_sets: u16,
}

impl ContactConfig {
    /// On above [`DEFAULT_ON_THRESHOLD_N`], off below [`DEFAULT_OFF_THRESHOLD_N`], after
    /// [`DEFAULT_DEBOUNCE_SETS`] sets.
    pub const DEFAULT: ContactConfig = ContactConfig {
        on_threshold_n: DEFAULT_ON_THRESHOLD_N,
        off_threshold_n: DEFAULT_OFF_THRESHOLD_N,
        debounce_sets: DEFAULT_DEBOUNCE_SETS,
    };
}

impl Default for ContactConfig {
    /// [`ContactConfig::DEFAULT`].
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a contact configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ContactConfigError {
    /// A threshold is NaN or infinite.
    NotFinite,
    /// The off threshold is not above 0 (a force never goes below 0: contact could not end).
    OffThresholdNotPositive,
    /// The off threshold is not below the on threshold (no hysteresis).
    OffNotBelowOn,
    /// The debounce is 0 sets (1 means: change on the first set that qualifies).
    ZeroDebounce,
}

impl fmt::Display for ContactConfigError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str(match self {
            Self::NotFinite => "a contact threshold is not finite",
            Self::OffThresholdNotPositive => "the contact off threshold must be above 0 N",
            Self::OffNotBelowOn => "the contact off threshold must be below the on threshold",
            Self::ZeroDebounce => "the contact debounce must be at least 1 sample set",
        })
    }
}

impl ContactConfig {
    /// Validates a configuration: both thresholds finite, `0 < off_threshold_n < on_threshold_n`,
    /// `debounce_sets >= 1`.
    pub fn new(
        on_threshold_n: f32,
        off_threshold_n: f32,
        debounce_sets: u16,
    ) -> Result<Self, ContactConfigError> {
        if !(on_threshold_n.is_finite() && off_threshold_n.is_finite()) {
            return Err(ContactConfigError::NotFinite);
        }
        if !(off_threshold_n > 0.0) {
            return Err(ContactConfigError::OffThresholdNotPositive);
        }
        if !(off_threshold_n < on_threshold_n) {
            return Err(ContactConfigError::OffNotBelowOn);
        }
        if debounce_sets == 0 {
            return Err(ContactConfigError::ZeroDebounce);
        }
        Ok(Self {
            on_threshold_n,
            off_threshold_n,
            debounce_sets,
        })
    }

    /// Contact starts when the force is above this, N.
    pub fn on_threshold_n(&self) -> f32 {
        self.on_threshold_n
    }

    /// Contact ends when the force is below this, N.
    pub fn off_threshold_n(&self) -> f32 {
        self.off_threshold_n
    }

    /// Consecutive sample sets a condition must hold before the state changes.
    pub fn debounce_sets(&self) -> u16 {
        self.debounce_sets
    }
}

// Deserialization goes through `ContactConfig::new`, so a stored configuration cannot bypass
// the checks.
#[cfg(feature = "serde")]
#[derive(serde::Deserialize)]
struct UncheckedContactConfig {
    on_threshold_n: f32,
    off_threshold_n: f32,
    debounce_sets: u16,
}

#[cfg(feature = "serde")]
impl TryFrom<UncheckedContactConfig> for ContactConfig {
    type Error = ContactConfigError;

    fn try_from(unchecked: UncheckedContactConfig) -> Result<Self, Self::Error> {
        Self::new(
            unchecked.on_threshold_n,
            unchecked.off_threshold_n,
            unchecked.debounce_sets,
        )
    }
}

/// A confirmed change of the contact state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ContactEvent {
    /// Contact started.
    Started {
        /// Device timestamp of the sample set that confirmed it (the last of the debounce), µs.
        timestamp_us: u64,
    },
    /// Contact ended.
    Ended {
        /// Device timestamp of the sample set that confirmed it (the last of the debounce), µs.
        timestamp_us: u64,
    },
}

/// Contact state of one pad, fed one [`PadForce`] per sample set.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ContactDetector {
    config: ContactConfig,
    in_contact: bool,
    // Consecutive sets so far that point to the other state.
    pending_sets: u16,
    // Taxels excluded in the set that confirmed the current contact.
    excluded_at_start: PadForceFlags,
}

impl ContactDetector {
    /// A detector out of contact.
    pub fn new(config: ContactConfig) -> Self {
        Self {
            config,
            in_contact: false,
            pending_sets: 0,
            excluded_at_start: PadForceFlags::empty(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ContactConfig {
        &self.config
    }

    /// True while in contact.
    pub fn in_contact(&self) -> bool {
        self.in_contact
    }

    /// Back to out of contact with nothing pending, without an event, for a caller that starts
    /// over (the device keeps one detector per pad for as long as it runs: the contact bit of
    /// every sample frame is the state, and a host that connects during a contact sees it set
    /// without having seen the start event).
    pub fn reset(&mut self) {
        *self = Self::new(self.config);
    }

    /// Takes the state as `in_contact`, with nothing pending, as of a set whose force was
    /// `force` (its excluded taxels count as excluded when the contact started): for a host that
    /// starts reading a stream in the middle, from the device's contact bit.
    pub fn assume(&mut self, in_contact: bool, force: &PadForce) {
        self.in_contact = in_contact;
        self.pending_sets = 0;
        self.excluded_at_start = if in_contact {
            force.flags.excluded()
        } else {
            PadForceFlags::empty()
        };
    }

    /// Takes one sample set's force, measured at `timestamp_us` on the device clock, µs. Returns
    /// the event when this set confirms a change of state (see the module for the rules).
    pub fn update(&mut self, force: &PadForce, timestamp_us: u64) -> Option<ContactEvent> {
        let force_n = force.force_n.filter(|force_n| force_n.is_finite());
        let towards_change = match force_n {
            None => false,
            Some(force_n) if !self.in_contact => force_n > self.config.on_threshold_n,
            Some(force_n) => {
                let newly_excluded = force.flags.excluded().difference(self.excluded_at_start);
                newly_excluded.is_empty() && force_n < self.config.off_threshold_n
            }
        };
        if !towards_change {
            self.pending_sets = 0;
            return None;
        }
        self.pending_sets = self.pending_sets.saturating_add(1);
        if self.pending_sets < self.config.debounce_sets {
            return None;
        }
        self.pending_sets = 0;
        self.in_contact = !self.in_contact;
        if self.in_contact {
            self.excluded_at_start = force.flags.excluded();
            Some(ContactEvent::Started { timestamp_us })
        } else {
            self.excluded_at_start = PadForceFlags::empty();
            Some(ContactEvent::Ended { timestamp_us })
        }
    }
}
