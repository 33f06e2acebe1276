//! Where each taxel sits on the pad and how large its electrode is: the data that turns the four
//! pressures into a normal force and a centre of pressure ([`crate::pad_force`]).
//!
//! Geometry is configuration, like the calibration: a pad of another layout is described, not
//! coded. [`TaxelGeometry`] is plain data (files, flash, wire); [`PadGeometry`] is the validated
//! form, and [`PadGeometry::new`] is the only way to build one from data.
//!
//! # Frame
//!
//! Millimetres, origin at the centre of the pad, seen from the side that is touched with row 1
//! at the top: x runs along a row, increasing with the column index (C11 towards C12); y runs
//! across the rows, increasing towards row 1 (C21 towards C11); z (right-handed) points out of
//! the pad towards whatever presses on it. On the article's pad:
//!
//! ```text
//!                      +y
//!                       ^
//!         C11           |           C12
//!   (-2.75, +2.75)      |     (+2.75, +2.75)
//!   --------------------+--------------------> +x
//!         C21           |           C22
//!   (-2.75, -2.75)      |     (+2.75, -2.75)
//! ```

use core::fmt;

use crate::calibration::TAXEL_COUNT;

/// Electrode area of one taxel of the article's pad, mm² (5 mm x 5 mm).
pub const ARTICLE_TAXEL_AREA_MM2: f32 = 25.0;

/// Distance of each electrode centre of the article's pad from the pad centre, along x and along
/// y, mm: a 5 mm electrode then spans 0.25 ..= 5.25 mm from the centre of the 11 mm pad, 0.5 mm
/// from its neighbour and 0.25 mm from the pad's edge.
pub const ARTICLE_CENTRE_OFFSET_MM: f32 = 2.75;

/// Largest electrode area accepted, mm² (a 100 mm x 100 mm electrode; the article's is 25 mm²).
/// Bounded so that the force of a plausible pressure stays finite in f32.
pub const MAX_TAXEL_AREA_MM2: f32 = 10_000.0;

/// Largest distance of a taxel centre from the pad centre along x or y, mm (the article's pad is
/// 11 mm across).
pub const MAX_CENTRE_OFFSET_MM: f32 = 100.0;

/// What a pad is, for the layouts of the host's views (a glove's palm pad is drawn larger than
/// its fingertips, a gripper's jaws side by side). Plain data: it changes no computation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PadRole {
    /// Not said.
    #[default]
    Unspecified,
    /// The tip of a finger (of a glove or a robot hand).
    Fingertip,
    /// A finger's other segments.
    Finger,
    /// The palm.
    Palm,
    /// A jaw of a parallel gripper.
    GripperJaw,
}

impl PadRole {
    /// Every role, in wire order.
    pub const ALL: [PadRole; 5] = [
        PadRole::Unspecified,
        PadRole::Fingertip,
        PadRole::Finger,
        PadRole::Palm,
        PadRole::GripperJaw,
    ];

    /// Its name in files and on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            PadRole::Unspecified => "unspecified",
            PadRole::Fingertip => "fingertip",
            PadRole::Finger => "finger",
            PadRole::Palm => "palm",
            PadRole::GripperJaw => "gripper-jaw",
        }
    }

    /// The role named `name` ([`PadRole::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|role| role.name() == name)
    }
}

/// One taxel's place and size, as plain data.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaxelGeometry {
    /// Electrode centre along x in the pad's frame, mm.
    pub x_mm: f32,
    /// Electrode centre along y in the pad's frame, mm.
    pub y_mm: f32,
    /// Electrode area, mm² (the pressure is the mean over it).
    pub area_mm2: f32,
}

impl TaxelGeometry {
    /// A taxel centred at (`x_mm`, `y_mm`) with an electrode of `area_mm2`.
    pub const fn new(x_mm: f32, y_mm: f32, area_mm2: f32) -> Self {
        Self {
            x_mm,
            y_mm,
            area_mm2,
        }
    }
}

/// Why a geometry was refused. `taxel` is the index in pad order (C11, C12, C21, C22).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GeometryError {
    /// A centre coordinate or an area is NaN or infinite.
    NotFinite {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// The area is not within `0 < area ..= MAX_TAXEL_AREA_MM2`.
    AreaOutOfRange {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// A centre coordinate is further than [`MAX_CENTRE_OFFSET_MM`] from the pad centre.
    CentreOutOfRange {
        /// Taxel index, 0..4.
        taxel: u8,
    },
    /// The taxel's centre is the centre of an earlier taxel: two electrodes cannot sit in one
    /// place (a copy-paste error in a geometry file, typically).
    CentresCoincide {
        /// Taxel index, 0..4 (the later of the two).
        taxel: u8,
        /// The earlier taxel at the same centre.
        earlier: u8,
    },
}

impl fmt::Display for GeometryError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotFinite { taxel } => {
                write!(formatter, "taxel {taxel}: a centre or area is not finite")
            }
            Self::AreaOutOfRange { taxel } => write!(
                formatter,
                "taxel {taxel}: the area must be above 0 and at most {MAX_TAXEL_AREA_MM2} mm²"
            ),
            Self::CentreOutOfRange { taxel } => write!(
                formatter,
                "taxel {taxel}: the centre must be within {MAX_CENTRE_OFFSET_MM} mm of the pad centre"
            ),
            Self::CentresCoincide { taxel, earlier } => write!(
                formatter,
                "taxel {taxel}: its centre is taxel {earlier}'s; every taxel needs a place of its own"
            ),
        }
    }
}

/// The validated geometry of the pad: per taxel, in pad order, its electrode centre and area.
///
/// Every value held is finite, every area within `0 < area ..= MAX_TAXEL_AREA_MM2` and every
/// centre within [`MAX_CENTRE_OFFSET_MM`] of the pad centre on both axes: only
/// [`PadGeometry::new`] (or [`Default`], or deserialization, which goes through `new`) builds one.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(try_from = "UncheckedPadGeometry"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadGeometry {
    taxels: [TaxelGeometry; TAXEL_COUNT],
}

impl PadGeometry {
    /// The article's pad: 25 mm² electrodes centred at (±2.75 mm, ±2.75 mm), C11 top-left (see
    /// the module's frame).
    pub const ARTICLE: PadGeometry = PadGeometry {
        taxels: [
            TaxelGeometry::new(
                -ARTICLE_CENTRE_OFFSET_MM,
                ARTICLE_CENTRE_OFFSET_MM,
                ARTICLE_TAXEL_AREA_MM2,
            ),
            TaxelGeometry::new(
                ARTICLE_CENTRE_OFFSET_MM,
                ARTICLE_CENTRE_OFFSET_MM,
                ARTICLE_TAXEL_AREA_MM2,
            ),
            TaxelGeometry::new(
                -ARTICLE_CENTRE_OFFSET_MM,
                -ARTICLE_CENTRE_OFFSET_MM,
                ARTICLE_TAXEL_AREA_MM2,
            ),
            TaxelGeometry::new(
                ARTICLE_CENTRE_OFFSET_MM,
                -ARTICLE_CENTRE_OFFSET_MM,
                ARTICLE_TAXEL_AREA_MM2,
            ),
        ],
    };
}

impl Default for PadGeometry {
    /// [`PadGeometry::ARTICLE`].
    fn default() -> Self {
        Self::ARTICLE
    }
}

impl PadGeometry {
    /// Validates four taxels in pad order (C11, C12, C21, C22): every value finite, every area
    /// within `0 < area ..= MAX_TAXEL_AREA_MM2`, every centre coordinate within
    /// ±[`MAX_CENTRE_OFFSET_MM`], no two centres equal. The first taxel that fails is named in
    /// the error.
    pub fn new(taxels: [TaxelGeometry; TAXEL_COUNT]) -> Result<Self, GeometryError> {
        for (index, taxel) in taxels.iter().enumerate() {
            let taxel_index = index as u8;
            if !(taxel.x_mm.is_finite() && taxel.y_mm.is_finite() && taxel.area_mm2.is_finite()) {
                return Err(GeometryError::NotFinite { taxel: taxel_index });
            }
            if !(taxel.area_mm2 > 0.0 && taxel.area_mm2 <= MAX_TAXEL_AREA_MM2) {
                return Err(GeometryError::AreaOutOfRange { taxel: taxel_index });
            }
            let within = |coordinate_mm: f32| {
                (-MAX_CENTRE_OFFSET_MM..=MAX_CENTRE_OFFSET_MM).contains(&coordinate_mm)
            };
            if !(within(taxel.x_mm) && within(taxel.y_mm)) {
                return Err(GeometryError::CentreOutOfRange { taxel: taxel_index });
            }
            let earlier = taxels
                .iter()
                .take(index)
                .position(|other| other.x_mm == taxel.x_mm && other.y_mm == taxel.y_mm);
            if let Some(earlier) = earlier {
                return Err(GeometryError::CentresCoincide {
                    taxel: taxel_index,
                    earlier: earlier as u8,
                });
            }
        }
        Ok(Self { taxels })
    }

    /// The taxels in pad order.
    pub fn taxels(&self) -> &[TaxelGeometry; TAXEL_COUNT] {
        &self.taxels
    }

    /// One taxel (`None` outside 0..4).
    pub fn taxel(&self, index: usize) -> Option<&TaxelGeometry> {
        self.taxels.get(index)
    }
}

// What a file or record holds before validation: deserialization goes through
// `PadGeometry::new`, so a stored geometry cannot bypass the checks.
#[cfg(feature = "serde")]
#[derive(serde::Deserialize)]
struct UncheckedPadGeometry {
    taxels: [TaxelGeometry; TAXEL_COUNT],
}

#[cfg(feature = "serde")]
impl TryFrom<UncheckedPadGeometry> for PadGeometry {
    type Error = GeometryError;

    fn try_from(unchecked: UncheckedPadGeometry) -> Result<Self, Self::Error> {
        Self::new(unchecked.taxels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_taxels_in_one_place_are_refused() {
        let mut taxels = *PadGeometry::ARTICLE.taxels();
        taxels[3] = taxels[1];
        assert_eq!(
            PadGeometry::new(taxels),
            Err(GeometryError::CentresCoincide {
                taxel: 3,
                earlier: 1
            })
        );
        taxels[3].y_mm -= 0.001;
        assert!(PadGeometry::new(taxels).is_ok());
    }

    #[test]
    fn every_role_is_found_by_its_name() {
        for role in PadRole::ALL {
            assert_eq!(PadRole::from_name(role.name()), Some(role));
        }
        assert_eq!(PadRole::from_name("elbow"), None);
    }

    #[test]
    fn the_default_passes_its_own_validation() {
        let default = PadGeometry::default();
        assert_eq!(PadGeometry::new(*default.taxels()), Ok(default));
        assert_eq!(default.taxel(4), None);
    }
}
