//! Scene files: what happens to the simulated pads over time, as data (TOML).
//!
//! One pad (every pad of a device plays it):
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
//!
//! Several pads, in the device's pad order (a device then reads as many pads as the scene has):
//!
//! ```toml
//! name = "gripper"
//! repeat = true
//! [[pad]]
//! name = "left finger"
//! [[pad.keyframe]]
//! time_s = 0.0
//! pressure_kpa = [0.0, 0.0, 0.0, 0.0]
//! temperature_c = 25.0
//! [[pad.fault]]
//! kind = "unplugged"
//! start_s = 3.0
//! end_s = 4.0
//! [[pad]]
//! name = "right finger"
//! # ...
//! ```
//!
//! A pad may say what it is and where its electrodes are (the article's pad when it does not):
//! the simulated board leaves the factory with that role and geometry saved beside the pad's
//! calibration, so PadInfo reports them and the force is computed with them.
//!
//! ```toml
//! [[pad]]
//! name = "palm"
//! role = "palm"           # unspecified, fingertip, finger, palm, gripper-jaw
//! [[pad.taxel]]           # c11, then c12, c21, c22: centre in mm, electrode area in mm²
//! x_mm = -6.5
//! y_mm = 4.5
//! area_mm2 = 96.0
//! # ... three more [[pad.taxel]] tables
//! ```

use std::fmt;

use model_core::{PadGeometry, PadRole, TaxelGeometry};
use sensor_sim::{Device, Fault, Keyframe, ScriptedScene};
use serde::Deserialize;

/// The built-in demo scene: a light press, a sliding press, the whole pad to 50 kPa, warming
/// 25 -> 45 °C while loaded, and a concentrated-load short.
pub const DEFAULT_SCENE_TOML: &str = include_str!("../scenes/default.toml");

/// The built-in scenes by name: the demo pad, a two-finger gripper grasping an object that
/// slips, a glove (five fingertips and the palm) grasping with the whole hand while one
/// fingertip shorts, and three scenes of one pad that go through faults so that a client sees
/// every event and flag a scene can cause: the TMP117 lost and back and temperature jumps
/// (`temperature-fallback`), every converter and taxel fault with the converter's recovery
/// (`converter-faults`), and a tare at power-on that leaves a taxel out (`tare-refused`). Each
/// file's header lists what the device sends and when.
pub const BUILT_IN_SCENES: [(&str, &str); 6] = [
    ("default", DEFAULT_SCENE_TOML),
    ("gripper", include_str!("../scenes/gripper.toml")),
    ("glove", include_str!("../scenes/glove.toml")),
    (
        "temperature-fallback",
        include_str!("../scenes/temperature-fallback.toml"),
    ),
    (
        "converter-faults",
        include_str!("../scenes/converter-faults.toml"),
    ),
    ("tare-refused", include_str!("../scenes/tare-refused.toml")),
];

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
    /// The taxel's converter channel freezes: its conversions complete but its result repeats
    /// one code, which the device flags STUCK and cures by re-initialising the converter.
    Frozen,
    /// The converter does not acknowledge on the bus.
    ConverterNack,
    /// The converter's DONE bits never set.
    DoneStuck,
    /// The converter's result registers read zero.
    ZeroReads,
    /// The pad's own temperature sensor (TMP117) does not acknowledge on the bus: the device
    /// falls back to the MCU's die sensor, and back to the TMP117 when it answers again. The
    /// pads of a scene of several pads have none of their own (they share the TMP117 on the
    /// main bus), so there it changes nothing.
    TemperatureSensorGone,
    /// The pad's board is unplugged: its converter and temperature sensor do not answer, and
    /// come back powered on afresh.
    Unplugged,
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
            FaultKind::Frozen => Fault::FrozenResult { taxel: self.taxel },
            FaultKind::ConverterNack => Fault::Nack(Device::Fdc1004),
            FaultKind::DoneStuck => Fault::DoneStuck,
            FaultKind::ZeroReads => Fault::ZeroReads,
            FaultKind::TemperatureSensorGone => Fault::Nack(Device::Tmp117),
            FaultKind::Unplugged => Fault::Unplugged,
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
    #[serde(default)]
    role: PadRole,
    #[serde(default)]
    taxel: Vec<TaxelGeometry>,
    #[serde(default)]
    keyframe: Vec<Keyframe>,
    #[serde(default)]
    fault: Vec<SceneFault>,
    #[serde(default)]
    pad: Vec<PadDocument>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PadDocument {
    #[serde(default)]
    name: String,
    #[serde(default)]
    role: PadRole,
    #[serde(default)]
    taxel: Vec<TaxelGeometry>,
    keyframe: Vec<Keyframe>,
    #[serde(default)]
    fault: Vec<SceneFault>,
}

/// What a pad is and its geometry, as a scene gives them (none: the built-in geometry).
struct PadLayout {
    role: PadRole,
    taxel: Vec<TaxelGeometry>,
}

impl PadLayout {
    fn geometry(&self, pad: &str) -> Result<PadGeometry, SceneFileError> {
        if self.taxel.is_empty() {
            return Ok(PadGeometry::ARTICLE);
        }
        let taxels: [TaxelGeometry; model_core::TAXEL_COUNT] =
            self.taxel.as_slice().try_into().map_err(|_| {
                SceneFileError::Geometry(format!(
                    "pad {pad:?}: {} [[taxel]] tables; a pad has 4 (c11, c12, c21, c22)",
                    self.taxel.len()
                ))
            })?;
        PadGeometry::new(taxels)
            .map_err(|error| SceneFileError::Geometry(format!("pad {pad:?}: {error}")))
    }
}

/// What happens to one pad.
#[derive(Debug, Clone)]
pub struct PadScene {
    /// Its name (empty when the file gives none).
    pub name: String,
    /// What it is (`role = "palm"`, ...; unspecified when the file gives none).
    pub role: PadRole,
    /// Its taxels' centres and areas (`[[taxel]]` tables; the article's pad when the file gives
    /// none): the simulated board leaves the factory with it saved beside the pad's calibration.
    pub geometry: PadGeometry,
    /// The pressures and temperature over time.
    pub scene: ScriptedScene,
    /// Fault windows.
    pub faults: Vec<SceneFault>,
}

/// A parsed, validated scene.
#[derive(Debug, Clone)]
pub struct SceneFile {
    /// Its name.
    pub name: String,
    /// Whether it starts over after its longest pad's last keyframe.
    pub repeat: bool,
    /// Per pad, in the device's pad order (at least one); a scene of one pad is played by every
    /// pad of a device.
    pub pads: Vec<PadScene>,
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
        /// Index of the fault in the file (in its pad's list for a scene of several pads).
        index: usize,
    },
    /// Both top-level keyframes and `[[pad]]` tables, neither, or more pads than a device reads.
    Pads(String),
    /// No built-in scene has this name.
    UnknownBuiltIn(String),
    /// A pad's `[[taxel]]` tables do not describe four taxels of a valid geometry.
    Geometry(String),
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
            SceneFileError::Pads(message) => write!(formatter, "scene pads: {message}"),
            SceneFileError::Geometry(message) => write!(formatter, "scene geometry: {message}"),
            SceneFileError::UnknownBuiltIn(name) => {
                let names: Vec<&str> = BUILT_IN_SCENES.iter().map(|(name, _)| *name).collect();
                write!(
                    formatter,
                    "no built-in scene `{name}` (built in: {})",
                    names.join(", ")
                )
            }
        }
    }
}

impl std::error::Error for SceneFileError {}

/// The most pads a scene describes: one per multiplexer channel.
pub const MAX_SCENE_PADS: usize = 8;

fn pad_scene(
    name: String,
    layout: PadLayout,
    keyframes: Vec<Keyframe>,
    faults: Vec<SceneFault>,
) -> Result<PadScene, SceneFileError> {
    let geometry = layout.geometry(&name)?;
    let scene = ScriptedScene::new(keyframes).map_err(SceneFileError::Keyframes)?;
    for (index, fault) in faults.iter().enumerate() {
        let valid = fault.start_s.is_finite()
            && fault.end_s.is_finite()
            && 0.0 <= fault.start_s
            && fault.start_s < fault.end_s
            && fault.taxel < model_core::TAXEL_COUNT;
        if !valid {
            return Err(SceneFileError::Fault { index });
        }
    }
    Ok(PadScene {
        name,
        role: layout.role,
        geometry,
        scene,
        faults,
    })
}

impl SceneFile {
    /// A scene of one pad.
    pub fn single_pad(
        name: impl Into<String>,
        repeat: bool,
        scene: ScriptedScene,
        faults: Vec<SceneFault>,
    ) -> Self {
        Self {
            name: name.into(),
            repeat,
            pads: vec![PadScene {
                name: String::new(),
                role: PadRole::Unspecified,
                geometry: PadGeometry::ARTICLE,
                scene,
                faults,
            }],
        }
    }

    /// Parses a scene from TOML text.
    pub fn parse(text: &str) -> Result<Self, SceneFileError> {
        let document: SceneDocument =
            toml::from_str(text).map_err(|error| SceneFileError::Syntax(error.to_string()))?;
        let top_level = !document.keyframe.is_empty() || !document.fault.is_empty();
        let pads = match (top_level, document.pad.is_empty()) {
            (true, true) => {
                let layout = PadLayout {
                    role: document.role,
                    taxel: document.taxel,
                };
                vec![pad_scene(
                    String::new(),
                    layout,
                    document.keyframe,
                    document.fault,
                )?]
            }
            (false, false) if document.pad.len() <= MAX_SCENE_PADS => document
                .pad
                .into_iter()
                .map(|pad| {
                    let layout = PadLayout {
                        role: pad.role,
                        taxel: pad.taxel,
                    };
                    pad_scene(pad.name, layout, pad.keyframe, pad.fault)
                })
                .collect::<Result<_, _>>()?,
            (false, false) => {
                return Err(SceneFileError::Pads(format!(
                    "{} [[pad]] tables, a device reads at most {MAX_SCENE_PADS}",
                    document.pad.len()
                )))
            }
            (true, false) => {
                return Err(SceneFileError::Pads(
                    "top-level keyframes or faults and [[pad]] tables: use one or the other"
                        .to_owned(),
                ))
            }
            (false, true) => {
                return Err(SceneFileError::Pads(
                    "no keyframe: give [[keyframe]] tables, or [[pad]] tables with theirs"
                        .to_owned(),
                ))
            }
        };
        Ok(Self {
            name: document.name,
            repeat: document.repeat,
            pads,
        })
    }

    /// The built-in demo scene.
    pub fn default_scene() -> Result<Self, SceneFileError> {
        Self::parse(DEFAULT_SCENE_TOML)
    }

    /// A built-in scene by name ([`BUILT_IN_SCENES`]).
    pub fn built_in(name: &str) -> Result<Self, SceneFileError> {
        let (_, text) = BUILT_IN_SCENES
            .iter()
            .find(|(built_in, _)| *built_in == name)
            .ok_or_else(|| SceneFileError::UnknownBuiltIn(name.to_owned()))?;
        Self::parse(text)
    }

    /// What pad `pad` of a device plays: its own scene, or the only one.
    pub fn pad(&self, pad: usize) -> Option<&PadScene> {
        match self.pads.as_slice() {
            [only] => Some(only),
            pads => pads.get(pad),
        }
    }

    /// Length of one pass, seconds: the longest pad's.
    pub fn period_s(&self) -> f64 {
        self.pads
            .iter()
            .map(|pad| pad.scene.end_s())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pad_gets_its_role_and_geometry_from_the_scene() {
        let glove = SceneFile::built_in("glove").unwrap();
        let palm = glove.pads.last().unwrap();
        assert_eq!(palm.role, PadRole::Palm);
        assert!(palm
            .geometry
            .taxels()
            .iter()
            .all(|taxel| taxel.area_mm2 == 96.0));
        assert_eq!(
            (
                palm.geometry.taxels()[0].x_mm,
                palm.geometry.taxels()[0].y_mm
            ),
            (-6.5, 4.5)
        );
        let thumb = &glove.pads[0];
        assert_eq!(thumb.role, PadRole::Fingertip);
        assert_eq!(thumb.geometry, PadGeometry::ARTICLE);
        let gripper = SceneFile::built_in("gripper").unwrap();
        assert!(gripper
            .pads
            .iter()
            .all(|pad| pad.role == PadRole::GripperJaw));
        assert_eq!(
            SceneFile::default_scene().unwrap().pads[0].role,
            PadRole::Unspecified
        );
    }

    #[test]
    fn a_geometry_that_is_not_one_is_refused_with_the_pad_named() {
        let taxel =
            |x: f32, y: f32| format!("[[taxel]]\nx_mm = {x:?}\ny_mm = {y:?}\narea_mm2 = 9.0\n");
        let keyframe = "[[keyframe]]\ntime_s = 0.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n";
        let three = format!(
            "{}{}{}{keyframe}",
            taxel(-1.0, 1.0),
            taxel(1.0, 1.0),
            taxel(-1.0, -1.0)
        );
        let error = SceneFile::parse(&three).unwrap_err().to_string();
        assert!(error.contains("3 [[taxel]] tables"), "{error}");
        let same = format!(
            "{}{}{}{}{keyframe}",
            taxel(-1.0, 1.0),
            taxel(1.0, 1.0),
            taxel(-1.0, -1.0),
            taxel(1.0, 1.0)
        );
        let error = SceneFile::parse(&same).unwrap_err().to_string();
        assert!(
            error.contains("taxel 3") && error.contains("taxel 1"),
            "{error}"
        );
        let role = format!("role = \"elbow\"\n{keyframe}");
        assert!(SceneFile::parse(&role).is_err());
    }

    #[test]
    fn the_default_scene_parses_and_covers_what_the_demo_promises() {
        let scene = SceneFile::default_scene().unwrap();
        assert!(scene.repeat);
        assert!(scene.period_s() > 60.0);
        let pad = scene.pad(0).unwrap();
        let peak = (0..940)
            .map(|step| pad.scene.point_at_s(step as f64 / 10.0))
            .fold(0.0f32, |peak, point| {
                point.pressure_kpa.iter().copied().fold(peak, f32::max)
            });
        assert_eq!(peak, 50.0);
        assert!(pad
            .faults
            .iter()
            .any(|fault| fault.kind == FaultKind::Shorted));
        assert_eq!(pad.scene.point_at_s(62.0).temperature_c, 45.0);
    }

    #[test]
    fn the_fault_scenes_use_every_fault_kind() {
        let mut kinds = Vec::new();
        for name in ["temperature-fallback", "converter-faults", "tare-refused"] {
            let scene = SceneFile::built_in(name).unwrap();
            assert_eq!(scene.name, name);
            assert_eq!(scene.pads.len(), 1, "{name}: one pad, with its own TMP117");
            // The tare at power-on happens once, so the scene about it does not start over.
            assert_eq!(scene.repeat, name != "tare-refused", "{name}");
            let pad = scene.pad(0).unwrap();
            // Faults end before the pass does, so that the next pass starts clean.
            assert!(pad
                .faults
                .iter()
                .all(|fault| fault.end_s < scene.period_s()));
            kinds.extend(pad.faults.iter().map(|fault| fault.kind));
        }
        for kind in [
            FaultKind::Shorted,
            FaultKind::Open,
            FaultKind::Saturated,
            FaultKind::Frozen,
            FaultKind::ConverterNack,
            FaultKind::DoneStuck,
            FaultKind::ZeroReads,
            FaultKind::TemperatureSensorGone,
            FaultKind::Unplugged,
        ] {
            assert!(kinds.contains(&kind), "{kind:?}");
        }
        let frozen = "[[keyframe]]\ntime_s = 0.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n[[fault]]\nkind = \"frozen\"\ntaxel = 3\nstart_s = 1.0\nend_s = 2.0\n";
        let scene = SceneFile::parse(frozen).unwrap();
        assert_eq!(
            scene.pads[0].faults[0].fault(),
            Fault::FrozenResult { taxel: 3 }
        );
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

    #[test]
    fn scenes_of_several_pads_parse_and_bad_ones_are_refused() {
        for (name, pads) in [("default", 1), ("gripper", 2), ("glove", 6)] {
            let scene = SceneFile::built_in(name).unwrap();
            assert_eq!(scene.pads.len(), pads, "{name}");
            assert!(scene.repeat);
        }
        let glove = SceneFile::built_in("glove").unwrap();
        assert_eq!(glove.pads[5].name, "palm");
        assert_eq!(glove.pads[1].faults[0].kind, FaultKind::Shorted);
        assert!(glove.pad(6).is_none());
        // A scene of one pad is every pad's.
        let demo = SceneFile::default_scene().unwrap();
        assert!(demo.pad(7).is_some());
        assert!(matches!(
            SceneFile::built_in("hand"),
            Err(SceneFileError::UnknownBuiltIn(_))
        ));
        let keyframe = "time_s = 0.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n";
        let both = format!("[[keyframe]]\n{keyframe}[[pad]]\n[[pad.keyframe]]\n{keyframe}");
        assert!(matches!(
            SceneFile::parse(&both),
            Err(SceneFileError::Pads(_))
        ));
        assert!(matches!(
            SceneFile::parse("name = \"nothing\""),
            Err(SceneFileError::Pads(_))
        ));
        let nine = format!("[[pad]]\n[[pad.keyframe]]\n{keyframe}").repeat(9);
        assert!(matches!(
            SceneFile::parse(&nine),
            Err(SceneFileError::Pads(_))
        ));
        let bad_fault = format!(
            "[[pad]]\n[[pad.keyframe]]\n{keyframe}[[pad.fault]]\nkind = \"unplugged\"\nstart_s = 2.0\nend_s = 1.0\n"
        );
        assert!(matches!(
            SceneFile::parse(&bad_fault),
            Err(SceneFileError::Fault { index: 0 })
        ));
    }
}
