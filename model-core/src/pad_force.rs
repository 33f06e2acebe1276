//! What a robot consumes per pad: the total normal force and the centre of pressure, from the
//! four taxels' pressures and the pad's [`PadGeometry`].
//!
//! Each taxel's pressure is the mean over its electrode, so its force is pressure x area
//! (1 kPa x 1 mm² = 1 mN): 50 kPa on one of the article's 25 mm² taxels is 1.25 N, on all four 5 N.
//! The centre of pressure is the force-weighted mean of the centres of the taxels that read, in
//! the geometry's frame (see [`crate::pad_geometry`]); with four taxels it is a coarse estimate
//! (a press inside one electrode reads as that electrode's centre), but it moves continuously
//! as the load moves from one taxel to the next.
//!
//! Rules, each stated where it is applied:
//! - a faulted taxel (any [`TaxelFlags::FAULTS`] bit, so no pressure) is excluded and named in
//!   [`PadForceFlags`], with [`PadForceFlags::PARTIAL`]: the force is then that of the taxels that
//!   read (a lower bound, since the excluded ones may carry load), never silently biased;
//! - when no taxel reads there is no force at all (`None`, [`PadForceFlags::NO_READING`]), so a
//!   dead pad can never read as an unloaded one;
//! - a negative pressure counts as 0 ([`PadForceFlags::NEGATIVE_CLAMPED`]);
//! - below [`COP_MIN_FORCE_N`] there is no centre of pressure.

use bitflags::bitflags;

use crate::bounds::clamp_f32;
use crate::calibration::TAXEL_COUNT;
use crate::flags::TaxelFlags;
use crate::pad_geometry::PadGeometry;
use crate::taxel::TaxelOutput;

/// Force of 1 kPa on 1 mm², N.
const NEWTONS_PER_KPA_MM2: f32 = 1.0e-3;

/// Below this total force, N, no centre of pressure is given. 5 mN is 0.2 kPa on one of the
/// article's taxels: about 15x the pressure noise the converter's 0.5 fF rms causes at the bottom
/// of the article's curve (0.013 kPa, 0.33 mN per taxel), so the centre is not the position of
/// noise, and a tenth of the default contact threshold, so every contact has one.
pub const COP_MIN_FORCE_N: f32 = 0.005;

/// Largest pressure magnitude taken as a reading, kPa (1 GPa, far beyond any elastomer pad; the
/// article's range is 50 kPa). A larger or non-finite value is not a pressure: the taxel is
/// excluded like a faulted one. The bound keeps every sum finite in f32.
pub const MAX_PRESSURE_KPA: f32 = 1.0e6;

bitflags! {
    /// How a [`PadForce`] was formed: which taxels were left out, and what qualifies the result.
    ///
    /// Bits 0..4 name the excluded taxels in pad order (C11, C12, C21, C22). The bit positions
    /// are stable; never renumber them.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
    #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
    pub struct PadForceFlags: u8 {
        /// C11 was excluded: faulted, or its pressure not a plausible number.
        const EXCLUDED_C11 = 1 << 0;
        /// C12 was excluded: faulted, or its pressure not a plausible number.
        const EXCLUDED_C12 = 1 << 1;
        /// C21 was excluded: faulted, or its pressure not a plausible number.
        const EXCLUDED_C21 = 1 << 2;
        /// C22 was excluded: faulted, or its pressure not a plausible number.
        const EXCLUDED_C22 = 1 << 3;
        /// Some taxels, not all, were excluded: the force and centre of pressure are those of the
        /// taxels that read. The force is a lower bound of the pad's.
        const PARTIAL = 1 << 4;
        /// Every taxel was excluded: there is no force and no centre of pressure.
        const NO_READING = 1 << 5;
        /// A taxel that was included is over its calibrated range (its pressure is clamped to the
        /// top of the curve): the force is a lower bound.
        const LOWER_BOUND = 1 << 6;
        /// A taxel that was included gave a negative pressure, counted as 0.
        const NEGATIVE_CLAMPED = 1 << 7;

        /// Every per-taxel exclusion bit.
        const EXCLUDED = Self::EXCLUDED_C11.bits()
            | Self::EXCLUDED_C12.bits()
            | Self::EXCLUDED_C21.bits()
            | Self::EXCLUDED_C22.bits();
    }
}

impl PadForceFlags {
    /// The exclusion bit of taxel `index` in pad order (empty outside 0..4).
    pub const fn excluded_taxel(index: usize) -> Self {
        if index < TAXEL_COUNT {
            Self::from_bits_truncate(1 << index)
        } else {
            Self::empty()
        }
    }

    /// True when taxel `index` was excluded.
    pub const fn is_excluded(self, index: usize) -> bool {
        let bit = Self::excluded_taxel(index);
        !bit.is_empty() && self.contains(bit)
    }

    /// Only the per-taxel exclusion bits.
    pub const fn excluded(self) -> Self {
        self.intersection(Self::EXCLUDED)
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for PadForceFlags {
    fn format(&self, fmt: defmt::Formatter) {
        defmt::write!(fmt, "PadForceFlags({=u8:#x})", self.bits())
    }
}

/// The pad's normal force and centre of pressure for one sample set.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadForce {
    /// Total normal force pressing on the pad, N: finite and >= 0. `None` when no taxel read
    /// ([`PadForceFlags::NO_READING`]). With [`PadForceFlags::PARTIAL`] it is the force on the
    /// taxels that read.
    pub force_n: Option<f32>,
    /// Centre of pressure (x, y) in the geometry's frame, mm: within the bounding box of the
    /// centres of the taxels that carry load. `None` when the force is below [`COP_MIN_FORCE_N`]
    /// or there is none.
    pub centre_of_pressure_mm: Option<(f32, f32)>,
    /// Excluded taxels and qualifiers.
    pub flags: PadForceFlags,
}

/// Force and centre of pressure from one sample set's taxel outputs.
///
/// A taxel with no pressure ([`TaxelOutput::pressure_kpa`] is `None`, i.e. a
/// [`TaxelFlags::FAULTS`] bit is set) is excluded and flagged; warnings do not exclude a taxel
/// (a `below_baseline` taxel reads 0 kPa and counts as 0), but an included `over_range` taxel
/// sets [`PadForceFlags::LOWER_BOUND`]. Otherwise as [`pad_force_from_pressures`].
pub fn pad_force(outputs: &[TaxelOutput; TAXEL_COUNT], geometry: &PadGeometry) -> PadForce {
    force_of(
        outputs.iter().map(|output| {
            (
                output.pressure_kpa(),
                output.flags().contains(TaxelFlags::OVER_RANGE),
            )
        }),
        geometry,
    )
}

/// Force and centre of pressure from pressures in pad order, kPa (`None` = the taxel did not
/// read), e.g. read back from a recording.
///
/// - `None`, a non-finite value or one beyond ±[`MAX_PRESSURE_KPA`] excludes the taxel: its
///   exclusion bit and [`PadForceFlags::PARTIAL`] are set, and the result is that of the others.
/// - No taxel left: `force_n` and `centre_of_pressure_mm` are `None`, with
///   [`PadForceFlags::NO_READING`].
/// - A negative pressure counts as 0, with [`PadForceFlags::NEGATIVE_CLAMPED`]: the pad only
///   senses compression (the model reports any fall below the baseline as 0 kPa), so a negative
///   value is a numerical artefact, and counted as it is it would cancel real load on another
///   taxel and, as a negative weight, could throw the centre of pressure outside the pad.
/// - `force_n` is the sum of pressure x area x 1e-3 (1 kPa on 1 mm² is 1 mN).
/// - The centre of pressure is the mean of the taxel centres weighted by their forces, given when
///   the force is at least [`COP_MIN_FORCE_N`]; it is limited to the bounding box of the centres
///   of the taxels that carry load, so f32 rounding cannot put it outside them.
pub fn pad_force_from_pressures(
    pressures_kpa: &[Option<f32>; TAXEL_COUNT],
    geometry: &PadGeometry,
) -> PadForce {
    force_of(
        pressures_kpa
            .iter()
            .map(|pressure_kpa| (*pressure_kpa, false)),
        geometry,
    )
}

/// [`pad_force_from_pressures`] of the taxels' (pressure, over range) in pad order, with
/// [`PadForceFlags::LOWER_BOUND`] when a taxel over its range is included. Written as selects rather than branches (an excluded taxel adds a
/// force of +0.0, which leaves every sum as it was), so that a host's batch of sets runs it
/// without mispredictions.
#[inline(always)]
fn force_of(taxels: impl Iterator<Item = (Option<f32>, bool)>, geometry: &PadGeometry) -> PadForce {
    let mut excluded_bits = 0u8;
    let mut negative = false;
    let mut lower_bound = false;
    // kPa x mm² = mN, and mN x mm for the moments: scaled to N once at the end.
    let mut force_mn = 0.0f32;
    let mut moment_x_mn_mm = 0.0f32;
    let mut moment_y_mn_mm = 0.0f32;
    // Empty until a taxel carries load (then min <= max).
    let mut loaded_box = BoundingBox::EMPTY;
    for (index, ((pressure_kpa, over_range), taxel)) in taxels.zip(geometry.taxels()).enumerate() {
        let (reads, pressure_kpa) = match pressure_kpa {
            Some(pressure_kpa) if pressure_kpa.abs() <= MAX_PRESSURE_KPA => (true, pressure_kpa),
            _ => (false, 0.0),
        };
        excluded_bits |= u8::from(!reads) << index;
        lower_bound |= reads & over_range;
        negative |= pressure_kpa < 0.0;
        let pressure_kpa = if pressure_kpa < 0.0 {
            0.0
        } else {
            pressure_kpa
        };
        let taxel_force_mn = pressure_kpa * taxel.area_mm2;
        force_mn += taxel_force_mn;
        moment_x_mn_mm += taxel_force_mn * taxel.x_mm;
        moment_y_mn_mm += taxel_force_mn * taxel.y_mm;
        let including = loaded_box.including(taxel.x_mm, taxel.y_mm);
        if taxel_force_mn > 0.0 {
            loaded_box = including;
        }
    }
    let mut flags = PadForceFlags::from_bits_truncate(excluded_bits);
    if negative {
        flags |= PadForceFlags::NEGATIVE_CLAMPED;
    }
    if lower_bound {
        flags |= PadForceFlags::LOWER_BOUND;
    }
    match excluded_bits {
        0 => {}
        0b1111 => {
            return PadForce {
                force_n: None,
                centre_of_pressure_mm: None,
                flags: flags | PadForceFlags::NO_READING,
            }
        }
        _ => flags |= PadForceFlags::PARTIAL,
    }
    let force_n = force_mn * NEWTONS_PER_KPA_MM2;
    // `force_n >= COP_MIN_FORCE_N` implies at least one loaded taxel (a box) and a sum far from 0.
    let centre_of_pressure_mm =
        (force_n >= COP_MIN_FORCE_N && loaded_box.holds_a_centre()).then(|| {
            (
                clamp_f32(
                    moment_x_mn_mm / force_mn,
                    loaded_box.min_x_mm,
                    loaded_box.max_x_mm,
                ),
                clamp_f32(
                    moment_y_mn_mm / force_mn,
                    loaded_box.min_y_mm,
                    loaded_box.max_y_mm,
                ),
            )
        });
    PadForce {
        force_n: Some(force_n),
        centre_of_pressure_mm,
        flags,
    }
}

/// The smallest axis-aligned box holding some taxel centres.
#[derive(Clone, Copy)]
struct BoundingBox {
    min_x_mm: f32,
    max_x_mm: f32,
    min_y_mm: f32,
    max_y_mm: f32,
}

impl BoundingBox {
    /// No centre yet: every centre is inside the range it gives after `including`.
    const EMPTY: Self = Self {
        min_x_mm: f32::INFINITY,
        max_x_mm: f32::NEG_INFINITY,
        min_y_mm: f32::INFINITY,
        max_y_mm: f32::NEG_INFINITY,
    };

    /// Whether a centre was included (the centres are validated finite).
    fn holds_a_centre(&self) -> bool {
        self.min_x_mm <= self.max_x_mm
    }

    // Compares rather than `f32::min`/`max`, which cost a libm call each on the M4F (see
    // `bounds`); the centres are validated finite.
    fn including(self, x_mm: f32, y_mm: f32) -> Self {
        Self {
            min_x_mm: if x_mm < self.min_x_mm {
                x_mm
            } else {
                self.min_x_mm
            },
            max_x_mm: if x_mm > self.max_x_mm {
                x_mm
            } else {
                self.max_x_mm
            },
            min_y_mm: if y_mm < self.min_y_mm {
                y_mm
            } else {
                self.min_y_mm
            },
            max_y_mm: if y_mm > self.max_y_mm {
                y_mm
            } else {
                self.max_y_mm
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exclusion_bits_follow_pad_order() {
        assert_eq!(
            PadForceFlags::excluded_taxel(0),
            PadForceFlags::EXCLUDED_C11
        );
        assert_eq!(
            PadForceFlags::excluded_taxel(3),
            PadForceFlags::EXCLUDED_C22
        );
        assert_eq!(PadForceFlags::excluded_taxel(4), PadForceFlags::empty());
        assert!(!PadForceFlags::all().is_excluded(4));
        assert!((PadForceFlags::EXCLUDED_C21 | PadForceFlags::PARTIAL).is_excluded(2));
        assert_eq!(
            (PadForceFlags::EXCLUDED_C21 | PadForceFlags::PARTIAL).excluded(),
            PadForceFlags::EXCLUDED_C21
        );
    }
}
