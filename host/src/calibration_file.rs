//! The versioned calibration file: JSON of
//! `{ "format": "taxel-calibration", "version": 1, "calibration": CalibrationSpec }`.
//!
//! Reading checks the format name and version before anything else, then validates the data
//! with `Calibration::new`, so a file that loads is a calibration the model accepts.
//!
//! Each taxel's `unloaded_sensor_pf` (C0 - Cp at 25 °C when calibrated, or `null`) was added to
//! version 1 without changing the version: a file written before it has no such key and loads
//! with none, and a tool that predates it ignores the key.

use std::path::{Path, PathBuf};

use anyhow::Context;
use model_core::reading::MAX_MEASURABLE_PF;
use model_core::{Calibration, CalibrationError, CalibrationSpec, TAXEL_NAMES};
use serde::{Deserialize, Serialize};

/// The `format` field of every calibration file.
pub const FORMAT_NAME: &str = "taxel-calibration";

/// The `version` this tool writes and reads.
pub const FORMAT_VERSION: u64 = 1;

/// The file's content as plain data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// Always [`FORMAT_VERSION`] for files written by this tool.
    pub version: u64,
    /// The calibration.
    pub calibration: CalibrationSpec,
}

/// Why a calibration file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationFileError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON, or the calibration does not have the expected fields.
    #[error("not a calibration file: {0}")]
    Json(#[from] serde_json::Error),
    /// The `format` field is missing or names another format.
    #[error("not a calibration file: \"format\" is {found}, expected \"{FORMAT_NAME}\"")]
    WrongFormat {
        /// What the file says, as JSON text.
        found: String,
    },
    /// The `version` field is missing or not one this tool reads.
    #[error("calibration file version {found} is not supported (this tool reads version {FORMAT_VERSION})")]
    UnsupportedVersion {
        /// What the file says, as JSON text.
        found: String,
    },
    /// The data is well formed but not a valid calibration.
    #[error("invalid calibration: {0}")]
    Invalid(String),
}

/// A calibration error in words, naming the taxel (c11 .. c22) and the point.
pub fn describe_calibration_error(error: &CalibrationError) -> String {
    let taxel_name = |taxel: u8| {
        TAXEL_NAMES
            .get(usize::from(taxel))
            .map(|name| format!("taxel {name}"))
            .unwrap_or_else(|| "the temperature law or thresholds".to_owned())
    };
    match *error {
        CalibrationError::TooFewPoints { taxel } => {
            format!("{}: a curve needs at least two points", taxel_name(taxel))
        }
        CalibrationError::DoesNotStartAtOrigin { taxel } => format!(
            "{}: the curve must start at (0 kPa, dC/C0 = 0)",
            taxel_name(taxel)
        ),
        CalibrationError::NotFinite { taxel } => {
            format!("{}: a value is NaN or infinite", taxel_name(taxel))
        }
        CalibrationError::NotStrictlyIncreasing { taxel, point } => format!(
            "{}: point {point} does not strictly increase in both pressure and dC/C0 over the point before it",
            taxel_name(taxel)
        ),
        CalibrationError::ParasiticOutOfRange { taxel } => format!(
            "{}: the parasitic capacitance must be within 0 ..= 100 pF",
            taxel_name(taxel)
        ),
        CalibrationError::UnloadedOutOfRange { taxel } => format!(
            "{}: the unloaded capacitance C0 - Cp must be above 0 and at most {MAX_MEASURABLE_PF} pF (what the converter can measure)",
            taxel_name(taxel)
        ),
        CalibrationError::InvalidTemperatureLaw => {
            "the temperature law is empty, not increasing in temperature, or has a ratio outside 0.5 ..= 2"
                .to_owned()
        }
        CalibrationError::InvalidThresholds => {
            "a fault threshold is out of its documented range".to_owned()
        }
    }
}

/// The file's JSON text for a calibration (pretty-printed, ends with a newline).
pub fn to_json(calibration: &Calibration) -> Result<String, CalibrationFileError> {
    let file = CalibrationFile {
        format: FORMAT_NAME.to_owned(),
        version: FORMAT_VERSION,
        calibration: calibration.to_spec(),
    };
    let mut text = serde_json::to_string_pretty(&file)?;
    text.push('\n');
    Ok(text)
}

/// Reads a calibration from the file's JSON text: format, then version, then the data, then
/// validation.
pub fn from_json(text: &str) -> Result<Calibration, CalibrationFileError> {
    let mut value: serde_json::Value = serde_json::from_str(text)?;
    let field_text = |value: &serde_json::Value, name: &str| {
        value
            .get(name)
            .map(|field| field.to_string())
            .unwrap_or_else(|| "missing".to_owned())
    };
    if value.get("format").and_then(serde_json::Value::as_str) != Some(FORMAT_NAME) {
        return Err(CalibrationFileError::WrongFormat {
            found: field_text(&value, "format"),
        });
    }
    if value.get("version").and_then(serde_json::Value::as_u64) != Some(FORMAT_VERSION) {
        return Err(CalibrationFileError::UnsupportedVersion {
            found: field_text(&value, "version"),
        });
    }
    let spec_value = value
        .get_mut("calibration")
        .map(serde_json::Value::take)
        .unwrap_or(serde_json::Value::Null);
    let spec: CalibrationSpec = serde_json::from_value(spec_value)?;
    Calibration::new(&spec)
        .map_err(|error| CalibrationFileError::Invalid(describe_calibration_error(&error)))
}

/// Reads and validates a calibration file.
pub fn read(path: &Path) -> Result<Calibration, CalibrationFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| CalibrationFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    from_json(&text)
}

/// Writes a calibration file (under a temporary name, renamed when complete: an existing file
/// is replaced only by a complete one).
pub fn write(path: &Path, calibration: &Calibration) -> anyhow::Result<()> {
    let text = to_json(calibration)?;
    let mut file = crate::output_file::OutputFile::create(path)?;
    std::io::Write::write_all(&mut file, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_calibration_round_trips() {
        let calibration = Calibration::default();
        let text = to_json(&calibration).unwrap();
        assert!(text.contains("\"format\": \"taxel-calibration\""));
        assert!(text.contains("\"version\": 1"));
        assert_eq!(from_json(&text).unwrap(), calibration);
    }

    /// A file written before taxels carried their calibrated C0: the same JSON without the
    /// `unloaded_sensor_pf` keys. It loads, with no C0 on any taxel.
    #[test]
    fn a_file_without_the_calibrated_c0_still_loads() {
        let mut spec = Calibration::default().to_spec();
        spec.id = 31;
        for (taxel, taxel_spec) in spec.taxels.iter_mut().enumerate() {
            taxel_spec.parasitic_pf = 0.25 * taxel as f32;
        }
        let calibration = Calibration::new(&spec).unwrap();
        let mut value = serde_json::to_value(CalibrationFile {
            format: FORMAT_NAME.to_owned(),
            version: FORMAT_VERSION,
            calibration: spec,
        })
        .unwrap();
        for taxel in value["calibration"]["taxels"].as_array_mut().unwrap() {
            let removed = taxel.as_object_mut().unwrap().remove("unloaded_sensor_pf");
            assert_eq!(removed, Some(serde_json::Value::Null));
        }
        let old_file = serde_json::to_string_pretty(&value).unwrap();
        assert!(!old_file.contains("unloaded_sensor_pf"));
        let loaded = from_json(&old_file).unwrap();
        assert_eq!(loaded, calibration);
        assert!(loaded
            .taxels()
            .iter()
            .all(|taxel| taxel.unloaded_sensor_pf().is_none()));
    }

    #[test]
    fn a_calibrated_c0_round_trips_and_is_checked() {
        let mut spec = Calibration::default().to_spec();
        for (taxel, taxel_spec) in spec.taxels.iter_mut().enumerate() {
            taxel_spec.unloaded_sensor_pf = Some(4.25 + 0.125 * taxel as f32);
        }
        let calibration = Calibration::new(&spec).unwrap();
        let text = to_json(&calibration).unwrap();
        assert!(text.contains("\"unloaded_sensor_pf\": 4.375"), "{text}");
        assert_eq!(from_json(&text).unwrap(), calibration);
        let out_of_range = text.replace(
            "\"unloaded_sensor_pf\": 4.375",
            "\"unloaded_sensor_pf\": 0.0",
        );
        let error = from_json(&out_of_range).unwrap_err().to_string();
        assert!(
            error.contains("taxel c12") && error.contains("unloaded capacitance"),
            "{error}"
        );
    }

    #[test]
    fn refuses_other_formats_versions_and_invalid_curves() {
        let text = to_json(&Calibration::default()).unwrap();
        let other_format = text.replace("taxel-calibration", "something-else");
        assert!(matches!(
            from_json(&other_format),
            Err(CalibrationFileError::WrongFormat { .. })
        ));
        let other_version = text.replace("\"version\": 1", "\"version\": 2");
        let error = from_json(&other_version).unwrap_err();
        assert!(matches!(
            error,
            CalibrationFileError::UnsupportedVersion { .. }
        ));
        assert!(error.to_string().contains("version 2"));
        let mut file: CalibrationFile = serde_json::from_str(&text).unwrap();
        file.calibration.taxels[1].points[2].relative_change = 0.01;
        let broken = serde_json::to_string(&file).unwrap();
        let error = from_json(&broken).unwrap_err().to_string();
        assert!(error.contains("taxel c12"), "{error}");
        assert!(error.contains("point 2"), "{error}");
    }
}
