//! What the pad feels over time: a pressure per taxel and the pad temperature, sampled by the
//! simulated devices at the instant each conversion completes.
//!
//! Any `FnMut(time_us) -> ScenePoint` is a [`Scene`]; [`ScriptedScene`] interpolates linearly
//! between keyframes, and [`Keyframe`] is serde-derived so that scenes can be loaded from files.

use std::fmt;

use serde::{Deserialize, Serialize};

/// The physical state of the pad at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScenePoint {
    /// Normal pressure on taxels C11, C12, C21, C22 (wired to CIN1..CIN4), kPa.
    pub pressure_kpa: [f32; 4],
    /// Pad temperature (dielectric and TMP117 alike), °C.
    pub temperature_c: f32,
}

impl ScenePoint {
    /// The unloaded pad at the reference temperature, 25 °C.
    pub const UNLOADED: ScenePoint = ScenePoint::new([0.0; 4], 25.0);

    /// A point from its pressures and temperature.
    pub const fn new(pressure_kpa: [f32; 4], temperature_c: f32) -> Self {
        Self {
            pressure_kpa,
            temperature_c,
        }
    }
}

impl Default for ScenePoint {
    fn default() -> Self {
        Self::UNLOADED
    }
}

/// A source of scene points over simulated time.
pub trait Scene: Send {
    /// The pad's state at `time_us` microseconds of simulated time. Called with non-decreasing
    /// times while the simulation runs.
    fn sample(&mut self, time_us: u64) -> ScenePoint;
}

impl<F> Scene for F
where
    F: FnMut(u64) -> ScenePoint + Send,
{
    fn sample(&mut self, time_us: u64) -> ScenePoint {
        self(time_us)
    }
}

/// One keyframe of a [`ScriptedScene`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Keyframe {
    /// Simulated time of the keyframe, s.
    pub time_s: f64,
    /// Pressure per taxel at that time, kPa.
    pub pressure_kpa: [f32; 4],
    /// Pad temperature at that time, °C.
    pub temperature_c: f32,
}

impl Keyframe {
    /// A keyframe from its time, pressures and temperature.
    pub const fn new(time_s: f64, pressure_kpa: [f32; 4], temperature_c: f32) -> Self {
        Self {
            time_s,
            pressure_kpa,
            temperature_c,
        }
    }

    fn point(&self) -> ScenePoint {
        ScenePoint::new(self.pressure_kpa, self.temperature_c)
    }
}

/// Why keyframes were refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneError {
    /// There are no keyframes.
    Empty,
    /// A time, pressure or temperature is NaN or infinite.
    NotFinite {
        /// Index of the keyframe.
        index: usize,
    },
    /// A keyframe is earlier than the one before it.
    TimeGoesBackwards {
        /// Index of the keyframe.
        index: usize,
    },
}

impl fmt::Display for SceneError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SceneError::Empty => formatter.write_str("a scene needs at least one keyframe"),
            SceneError::NotFinite { index } => {
                write!(formatter, "keyframe {index} has a value that is not finite")
            }
            SceneError::TimeGoesBackwards { index } => {
                write!(
                    formatter,
                    "keyframe {index} is earlier than the one before it"
                )
            }
        }
    }
}

impl std::error::Error for SceneError {}

/// Keyframes with linear interpolation between them; before the first keyframe the first holds,
/// after the last the last holds. Two keyframes at the same time make a step (the later one
/// holds from that time on).
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptedScene {
    keyframes: Vec<Keyframe>,
}

impl ScriptedScene {
    /// Validates keyframes: at least one, all values finite, times non-decreasing.
    pub fn new(keyframes: Vec<Keyframe>) -> Result<Self, SceneError> {
        if keyframes.is_empty() {
            return Err(SceneError::Empty);
        }
        for (index, keyframe) in keyframes.iter().enumerate() {
            let finite = keyframe.time_s.is_finite()
                && keyframe.temperature_c.is_finite()
                && keyframe.pressure_kpa.iter().all(|value| value.is_finite());
            if !finite {
                return Err(SceneError::NotFinite { index });
            }
            if index > 0 && keyframe.time_s < keyframes[index - 1].time_s {
                return Err(SceneError::TimeGoesBackwards { index });
            }
        }
        Ok(Self { keyframes })
    }

    /// A scene that never changes.
    pub fn constant(point: ScenePoint) -> Self {
        Self {
            keyframes: vec![Keyframe::new(0.0, point.pressure_kpa, point.temperature_c)],
        }
    }

    /// The keyframes, in time order.
    pub fn keyframes(&self) -> &[Keyframe] {
        &self.keyframes
    }

    /// Time of the last keyframe, s.
    pub fn end_s(&self) -> f64 {
        self.keyframes
            .last()
            .map_or(0.0, |keyframe| keyframe.time_s)
    }

    /// The interpolated point at `time_s` seconds.
    pub fn point_at_s(&self, time_s: f64) -> ScenePoint {
        let after = self
            .keyframes
            .partition_point(|keyframe| keyframe.time_s <= time_s);
        let (Some(first), Some(last)) = (self.keyframes.first(), self.keyframes.last()) else {
            return ScenePoint::UNLOADED;
        };
        if after == 0 {
            return first.point();
        }
        if after >= self.keyframes.len() {
            return last.point();
        }
        let (start, end) = (self.keyframes[after - 1], self.keyframes[after]);
        // `start.time_s <= time_s < end.time_s`, so the span is positive.
        let fraction = (time_s - start.time_s) / (end.time_s - start.time_s);
        let blend =
            |from: f32, to: f32| (from as f64 + fraction * (to as f64 - from as f64)) as f32;
        ScenePoint::new(
            core::array::from_fn(|taxel| blend(start.pressure_kpa[taxel], end.pressure_kpa[taxel])),
            blend(start.temperature_c, end.temperature_c),
        )
    }
}

impl Scene for ScriptedScene {
    fn sample(&mut self, time_us: u64) -> ScenePoint {
        self.point_at_s(time_us as f64 * 1e-6)
    }
}
