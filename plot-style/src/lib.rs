//! What every taxel picture shares, so that a tier or a taxel has the same colour in the
//! command line's plots and in the performance report: the embedded font and the colours.
#![deny(missing_docs)]

use std::sync::OnceLock;

use anyhow::bail;
use model_core::{Tier, TAXEL_COUNT};
use plotters::style::{register_font, FontStyle, RGBColor};

/// The embedded font (DejaVu Sans 2.37, Bitstream Vera license, see assets/).
static EMBEDDED_FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Colours of the four taxels.
pub const TAXEL_COLOURS: [RGBColor; TAXEL_COUNT] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// The colour of a tier in every picture (calibration residuals, the performance report's
/// speed-vs-error plot).
pub const fn tier_colour(tier: Tier) -> RGBColor {
    match tier {
        Tier::Linear => RGBColor(0x7f, 0x7f, 0x7f),
        Tier::PiecewiseLinear => RGBColor(0x2c, 0xa0, 0x2c),
        Tier::MonotoneCubic => RGBColor(0x1f, 0x77, 0xb4),
        Tier::Saturating => RGBColor(0xff, 0x7f, 0x0e),
        Tier::SaturatingMicromath => RGBColor(0xd6, 0x27, 0x28),
        Tier::Table => RGBColor(0x94, 0x67, 0xbd),
        Tier::Polynomial => RGBColor(0x8c, 0x56, 0x4b),
    }
}

/// Registers the embedded font as plotters' "sans-serif" (once per process).
pub fn register_embedded_font() -> anyhow::Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let registered = *REGISTERED
        .get_or_init(|| register_font("sans-serif", FontStyle::Normal, EMBEDDED_FONT).is_ok());
    if registered {
        Ok(())
    } else {
        bail!("the embedded font could not be loaded")
    }
}
