//! Scene files: what happens to the simulated pad over time, as data (TOML).
//!
//! ```toml
//! name = "press"
//! repeat = false
//! [[keyframe]]
//! time_s = 0.0
//! pressure_kpa = [0.0, 0.0, 0.0, 0.0]   # c11, c12, c21, c22
//! temperature_c = 25.0
//! [[fault]]
//! kind = "shorted"                      # see FaultKind
//! taxel = 1
//! start_s = 10.0
//! end_s = 12.0
//! ```

use std::fmt;

use sensor_sim::{Device, Fault, Keyframe, ScriptedScene};
use serde::Deserialize;

/// The built-in demo scene: a light press, a sliding press, the whole pad to 50 kPa, warming
/// 25 -> 45 °C while loaded, and a concentrated-load short.
pub const DEFAULT_SCENE_TOML: &str = include_str!("../scenes/default.toml");

/// A fault a scene can inject.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultKind {
    /// The taxel's electrodes conduct (negative capacitance, as under a concentrated load).
    Shorted,
    /// The taxel's lead is open.
    Open,
    /// The taxel's converter channel saturates high.
    Saturated,
    /// The converter does not acknowledge on the bus.
    ConverterNack,
    /// The converter's DONE bits never set.
    DoneStuck,
    /// The converter's result registers read zero.
    ZeroReads,
    /// The temperature sensor does not acknowledge on the bus.
    TemperatureSensorGone,
}

/// One fault window of a scene.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFault {
    /// What goes wrong.
    pub kind: FaultKind,
    /// Taxel 0..4 for taxel faults.
    #[serde(default)]
    pub taxel: usize,
    /// Start, seconds into the scene.
    pub start_s: f64,
    /// End, seconds into the scene.
    pub end_s: f64,
}

impl SceneFault {
    /// The simulator's fault.
    pub fn fault(&self) -> Fault {
        match self.kind {
            FaultKind::Shorted => Fault::shorted(self.taxel),
            FaultKind::Open => Fault::open_lead(self.taxel),
            FaultKind::Saturated => Fault::Saturated {
                taxel: self.taxel,
                high: true,
            },
            FaultKind::ConverterNack => Fault::Nack(Device::Fdc1004),
            FaultKind::DoneStuck => Fault::DoneStuck,
            FaultKind::ZeroReads => Fault::ZeroReads,
            FaultKind::TemperatureSensorGone => Fault::Nack(Device::Tmp117),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneDocument {
    #[serde(default)]
    name: String,
    #[serde(default)]
    repeat: bool,
    keyframe: Vec<Keyframe>,
    #[serde(default)]
    fault: Vec<SceneFault>,
}

/// A parsed, validated scene.
#[derive(Debug, Clone)]
pub struct SceneFile {
    /// Its name.
    pub name: String,
    /// Whether it starts over after the last keyframe.
    pub repeat: bool,
    /// The pressures and temperature over time.
    pub scene: ScriptedScene,
    /// Fault windows.
    pub faults: Vec<SceneFault>,
}

/// Why a scene file was refused.
#[derive(Debug)]
pub enum SceneFileError {
    /// Not valid TOML for a scene (the message names the line).
    Syntax(String),
    /// Keyframes out of order, not finite, or empty.
    Keyframes(sensor_sim::SceneError),
    /// A fault window is empty, not finite, or names a taxel outside 0..4.
    Fault {
        /// Index of the fault in the file.
        index: usize,
    },
}

impl fmt::Display for SceneFileError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SceneFileError::Syntax(message) => write!(formatter, "scene file: {message}"),
            SceneFileError::Keyframes(error) => write!(formatter, "scene keyframes: {error}"),
            SceneFileError::Fault { index } => write!(
                formatter,
                "scene fault #{index}: needs 0 <= start_s < end_s (finite) and taxel 0..3"
            ),
        }
    }
}

impl std::error::Error for SceneFileError {}

impl SceneFile {
    /// Parses a scene from TOML text.
    pub fn parse(text: &str) -> Result<Self, SceneFileError> {
        let document: SceneDocument =
            toml::from_str(text).map_err(|error| SceneFileError::Syntax(error.to_string()))?;
        let scene = ScriptedScene::new(document.keyframe).map_err(SceneFileError::Keyframes)?;
        for (index, fault) in document.fault.iter().enumerate() {
            let valid = fault.start_s.is_finite()
                && fault.end_s.is_finite()
                && 0.0 <= fault.start_s
                && fault.start_s < fault.end_s
                && fault.taxel < model_core::TAXEL_COUNT;
            if !valid {
                return Err(SceneFileError::Fault { index });
            }
        }
        Ok(Self {
            name: document.name,
            repeat: document.repeat,
            scene,
            faults: document.fault,
        })
    }

    /// The built-in demo scene.
    pub fn default_scene() -> Result<Self, SceneFileError> {
        Self::parse(DEFAULT_SCENE_TOML)
    }

    /// Length of one pass, seconds.
    pub fn period_s(&self) -> f64 {
        self.scene.end_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_scene_parses_and_covers_what_the_demo_promises() {
        let scene = SceneFile::default_scene().unwrap();
        assert!(scene.repeat);
        assert!(scene.period_s() > 60.0);
        let peak = (0..940)
            .map(|step| scene.scene.point_at_s(step as f64 / 10.0))
            .fold(0.0f32, |peak, point| {
                point.pressure_kpa.iter().copied().fold(peak, f32::max)
            });
        assert_eq!(peak, 50.0);
        assert!(scene
            .faults
            .iter()
            .any(|fault| fault.kind == FaultKind::Shorted));
        assert_eq!(scene.scene.point_at_s(62.0).temperature_c, 45.0);
    }

    #[test]
    fn bad_scenes_are_refused_with_a_reason() {
        assert!(matches!(
            SceneFile::parse("keyframe = 3"),
            Err(SceneFileError::Syntax(_))
        ));
        let backwards = "[[keyframe]]\ntime_s = 2.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n[[keyframe]]\ntime_s = 1.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n";
        assert!(matches!(
            SceneFile::parse(backwards),
            Err(SceneFileError::Keyframes(_))
        ));
        let bad_fault = "[[keyframe]]\ntime_s = 0.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n[[fault]]\nkind = \"open\"\ntaxel = 7\nstart_s = 1.0\nend_s = 2.0\n";
        assert!(matches!(
            SceneFile::parse(bad_fault),
            Err(SceneFileError::Fault { index: 0 })
        ));
    }
}
