//! Layout of the golden-vector file, shared by its writer (the build script, on the host) and its
//! reader (the on-target test): fixed-size little-endian records, no allocation, no padding rules.
//!
//! File: [`Header`], then `grid_count` [`GridRecord`]s, then `hard_case_count` [`HardCase`]s,
//! then `hard_calibration_count` [`HardCalibration`]s.
//! References are f64 and per tier in [`model_core::Tier::ALL`] order; a NaN reference means
//! "no pressure" (the reading must come out as a fault).

use model_core::{TaxelReading, Tier};

/// First bytes of the file.
pub const MAGIC: [u8; 4] = *b"TXG2";

/// Number of tiers, in [`Tier::ALL`] order.
pub const TIER_COUNT: usize = Tier::ALL.len();

/// Bytes of a case name (ASCII, NUL-padded).
pub const NAME_BYTES: usize = 32;

/// Bytes of a case description (ASCII, NUL-padded).
pub const DESCRIPTION_BYTES: usize = 96;

/// Bytes of a hard calibration's shape name (ASCII, NUL-padded).
pub const SHAPE_BYTES: usize = 24;

/// Most points of a hard calibration (model-core's `MAX_CURVE_POINTS`).
pub const CALIBRATION_POINTS_MAX: usize = 16;

/// Most probes of a hard calibration.
pub const CALIBRATION_PROBES_MAX: usize = 144;

const READING_BYTES: usize = 16;
const TEMPERATURE_BYTES: usize = 8;
const SETUP_BYTES: usize = 4 + READING_BYTES + TEMPERATURE_BYTES;
const PROBE_BYTES: usize = 4 + 8 + 8 + 8;

/// Encoded size of a [`Header`].
pub const HEADER_BYTES: usize = 4 + 4 + 4 + 4 + SETUP_BYTES + 8 * TIER_COUNT;

/// Encoded size of a [`GridRecord`].
pub const GRID_RECORD_BYTES: usize = 4 + 4 + READING_BYTES + 8 * TIER_COUNT;

/// Encoded size of a [`HardCase`].
pub const HARD_CASE_BYTES: usize = NAME_BYTES
    + DESCRIPTION_BYTES
    + SETUP_BYTES
    + TEMPERATURE_BYTES
    + READING_BYTES
    + TEMPERATURE_BYTES
    + 4
    + 16 * TIER_COUNT;

/// Encoded size of a [`HardCalibration`].
pub const HARD_CALIBRATION_BYTES: usize =
    8 + SHAPE_BYTES + 4 + 8 * CALIBRATION_POINTS_MAX + 4 + PROBE_BYTES * CALIBRATION_PROBES_MAX;

/// How a taxel is calibrated and tared before a reading is converted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setup {
    /// Parasitic capacitance of the calibration, pF.
    pub parasitic_pf: f32,
    /// The single unloaded reading the tare averages.
    pub tare_reading: TaxelReading,
    /// Temperature during the tare, °C.
    pub tare_temperature_c: Option<f32>,
}

/// File header: counts, the grid's setup and the per-tier tolerance on the grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// Grid records that follow.
    pub grid_count: u32,
    /// Hard cases that follow the grid.
    pub hard_case_count: u32,
    /// Hard calibrations that follow the hard cases.
    pub hard_calibration_count: u32,
    /// Setup shared by every grid record.
    pub grid_setup: Setup,
    /// Largest acceptable |on-target - reference| per tier on the grid, kPa.
    pub tolerance_kpa: [f64; TIER_COUNT],
}

/// One point of the pressure x temperature grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridRecord {
    /// Pressure the reading was synthesised at, kPa.
    pub pressure_kpa: f32,
    /// Temperature the reading was synthesised at (and is converted with), °C.
    pub temperature_c: f32,
    /// The converter reading.
    pub reading: TaxelReading,
    /// f64 reference pressure of each tier for this (quantised) reading, kPa.
    pub reference_kpa: [f64; TIER_COUNT],
}

/// A hard case: one reading with its expected flags and per-tier reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HardCase {
    /// Short identifier.
    pub name: [u8; NAME_BYTES],
    /// What the case exercises.
    pub description: [u8; DESCRIPTION_BYTES],
    /// Calibration and tare.
    pub setup: Setup,
    /// After the tare and before the reading, the pad's temperature is brought here in steps
    /// small enough to be applied as measured (unloaded sample sets), as a real pad warms up.
    pub warm_up_c: Option<f32>,
    /// The reading converted.
    pub reading: TaxelReading,
    /// The temperature given with it, °C.
    pub temperature_c: Option<f32>,
    /// Exact flags expected (`TaxelFlags` bits).
    pub expected_flags: u16,
    /// f64 reference pressure per tier, kPa (NaN: no pressure expected).
    pub reference_kpa: [f64; TIER_COUNT],
    /// Largest acceptable |on-target - reference| per tier, kPa.
    pub tolerance_kpa: [f64; TIER_COUNT],
}

/// One probe of a hard calibration: a dC/C0 and the pressures the reference accepts for it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Probe {
    /// The dC/C0 given to the default tier's inverse.
    pub relative_change: f32,
    /// The f64 reference pressure at exactly this dC/C0, kPa (for the report only).
    pub reference_kpa: f64,
    /// Lowest accepted pressure, kPa: the reference at dC/C0 minus the rounding allowance,
    /// minus the pressure tolerance.
    pub lower_kpa: f64,
    /// Highest accepted pressure, kPa: the reference at dC/C0 plus the rounding allowance,
    /// plus the pressure tolerance.
    pub upper_kpa: f64,
}

/// A valid but ill-conditioned calibration curve with probes of its inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HardCalibration {
    /// Generator seed (`reference_curves::hard_calibration`).
    pub seed: u64,
    /// The generator's name for the curve's difficulty.
    pub shape: [u8; SHAPE_BYTES],
    /// Points in use.
    pub point_count: u32,
    /// (pressure kPa, dC/C0) points; the first `point_count` are the curve.
    pub points: [(f32, f32); CALIBRATION_POINTS_MAX],
    /// Probes in use.
    pub probe_count: u32,
    /// The probes; the first `probe_count` are checked.
    pub probes: [Probe; CALIBRATION_PROBES_MAX],
}

impl HardCalibration {
    /// The curve's points.
    pub fn points(&self) -> &[(f32, f32)] {
        &self.points[..(self.point_count as usize).min(CALIBRATION_POINTS_MAX)]
    }

    /// The probes.
    pub fn probes(&self) -> &[Probe] {
        &self.probes[..(self.probe_count as usize).min(CALIBRATION_PROBES_MAX)]
    }
}

/// Text of a NUL-padded ASCII field.
pub fn field_text(bytes: &[u8]) -> &str {
    let end = bytes
        .iter()
        .position(|byte| *byte == 0)
        .unwrap_or(bytes.len());
    core::str::from_utf8(&bytes[..end]).unwrap_or("?")
}

/// Writes little-endian values into a byte slice. Writes past its end are dropped: the writer
/// (the build script) decodes every record it encodes and compares, which catches a layout slip.
struct Writer<'a> {
    bytes: &'a mut [u8],
    position: usize,
}

impl<'a> Writer<'a> {
    fn new(bytes: &'a mut [u8]) -> Self {
        Self { bytes, position: 0 }
    }

    fn put(&mut self, value: &[u8]) {
        if let Some(slot) = self
            .bytes
            .get_mut(self.position..self.position + value.len())
        {
            slot.copy_from_slice(value);
        }
        self.position += value.len();
    }

    fn u32(&mut self, value: u32) {
        self.put(&value.to_le_bytes());
    }

    fn f32(&mut self, value: f32) {
        self.u32(value.to_bits());
    }

    fn f64(&mut self, value: f64) {
        self.put(&value.to_bits().to_le_bytes());
    }

    fn u64(&mut self, value: u64) {
        self.put(&value.to_le_bytes());
    }

    fn reading(&mut self, reading: TaxelReading) {
        let (kind, code, capdac, capacitance_pf) = match reading {
            TaxelReading::Raw { code, capdac } => (0, code, capdac, 0.0),
            TaxelReading::CapacitancePf(capacitance_pf) => (1, 0, 0, capacitance_pf),
            TaxelReading::Unavailable => (2, 0, 0, 0.0),
        };
        self.u32(kind);
        self.u32(code as u32);
        self.u32(u32::from(capdac));
        self.f32(capacitance_pf);
    }

    fn temperature(&mut self, temperature_c: Option<f32>) {
        self.u32(u32::from(temperature_c.is_some()));
        self.f32(temperature_c.unwrap_or(0.0));
    }

    fn setup(&mut self, setup: &Setup) {
        self.f32(setup.parasitic_pf);
        self.reading(setup.tare_reading);
        self.temperature(setup.tare_temperature_c);
    }

    fn f64s(&mut self, values: &[f64; TIER_COUNT]) {
        for value in values {
            self.f64(*value);
        }
    }
}

/// Reads little-endian values from a byte slice; `None` past its end.
struct Reader<'a> {
    bytes: &'a [u8],
    position: usize,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, position: 0 }
    }

    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let slice = self.bytes.get(self.position..self.position + N)?;
        self.position += N;
        let mut array = [0; N];
        array.copy_from_slice(slice);
        Some(array)
    }

    fn u32(&mut self) -> Option<u32> {
        self.take::<4>().map(u32::from_le_bytes)
    }

    fn f32(&mut self) -> Option<f32> {
        self.u32().map(f32::from_bits)
    }

    fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }

    fn u64(&mut self) -> Option<u64> {
        self.take::<8>().map(u64::from_le_bytes)
    }

    fn reading(&mut self) -> Option<TaxelReading> {
        let kind = self.u32()?;
        let code = self.u32()? as i32;
        let capdac = u8::try_from(self.u32()?).ok()?;
        let capacitance_pf = self.f32()?;
        match kind {
            0 => Some(TaxelReading::Raw { code, capdac }),
            1 => Some(TaxelReading::CapacitancePf(capacitance_pf)),
            2 => Some(TaxelReading::Unavailable),
            _ => None,
        }
    }

    fn temperature(&mut self) -> Option<Option<f32>> {
        let present = self.u32()? != 0;
        let value = self.f32()?;
        Some(present.then_some(value))
    }

    fn setup(&mut self) -> Option<Setup> {
        Some(Setup {
            parasitic_pf: self.f32()?,
            tare_reading: self.reading()?,
            tare_temperature_c: self.temperature()?,
        })
    }

    fn f64s(&mut self) -> Option<[f64; TIER_COUNT]> {
        let mut values = [0.0; TIER_COUNT];
        for value in values.iter_mut() {
            *value = self.f64()?;
        }
        Some(values)
    }
}

impl Header {
    /// Encodes the header.
    pub fn encode(&self) -> [u8; HEADER_BYTES] {
        let mut bytes = [0; HEADER_BYTES];
        let mut writer = Writer::new(&mut bytes);
        writer.put(&MAGIC);
        writer.u32(self.grid_count);
        writer.u32(self.hard_case_count);
        writer.u32(self.hard_calibration_count);
        writer.setup(&self.grid_setup);
        writer.f64s(&self.tolerance_kpa);
        bytes
    }

    /// Decodes the header; `None` for a wrong magic or a short slice.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut reader = Reader::new(bytes);
        if reader.take::<4>()? != MAGIC {
            return None;
        }
        Some(Self {
            grid_count: reader.u32()?,
            hard_case_count: reader.u32()?,
            hard_calibration_count: reader.u32()?,
            grid_setup: reader.setup()?,
            tolerance_kpa: reader.f64s()?,
        })
    }

    /// Byte offset of grid record `index`.
    pub fn grid_offset(&self, index: usize) -> usize {
        HEADER_BYTES + index * GRID_RECORD_BYTES
    }

    /// Byte offset of hard case `index`.
    pub fn hard_case_offset(&self, index: usize) -> usize {
        self.grid_offset(self.grid_count as usize) + index * HARD_CASE_BYTES
    }

    /// Byte offset of hard calibration `index`.
    pub fn hard_calibration_offset(&self, index: usize) -> usize {
        self.hard_case_offset(self.hard_case_count as usize) + index * HARD_CALIBRATION_BYTES
    }

    /// Total size of the file this header describes.
    pub fn file_bytes(&self) -> usize {
        self.hard_calibration_offset(self.hard_calibration_count as usize)
    }
}

impl GridRecord {
    /// Encodes the record.
    pub fn encode(&self) -> [u8; GRID_RECORD_BYTES] {
        let mut bytes = [0; GRID_RECORD_BYTES];
        let mut writer = Writer::new(&mut bytes);
        writer.f32(self.pressure_kpa);
        writer.f32(self.temperature_c);
        writer.reading(self.reading);
        writer.f64s(&self.reference_kpa);
        bytes
    }

    /// Decodes a record from the start of `bytes`.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut reader = Reader::new(bytes);
        Some(Self {
            pressure_kpa: reader.f32()?,
            temperature_c: reader.f32()?,
            reading: reader.reading()?,
            reference_kpa: reader.f64s()?,
        })
    }
}

impl HardCase {
    /// Encodes the case.
    pub fn encode(&self) -> [u8; HARD_CASE_BYTES] {
        let mut bytes = [0; HARD_CASE_BYTES];
        let mut writer = Writer::new(&mut bytes);
        writer.put(&self.name);
        writer.put(&self.description);
        writer.setup(&self.setup);
        writer.temperature(self.warm_up_c);
        writer.reading(self.reading);
        writer.temperature(self.temperature_c);
        writer.u32(u32::from(self.expected_flags));
        writer.f64s(&self.reference_kpa);
        writer.f64s(&self.tolerance_kpa);
        bytes
    }

    /// Decodes a case from the start of `bytes`.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut reader = Reader::new(bytes);
        Some(Self {
            name: reader.take()?,
            description: reader.take()?,
            setup: reader.setup()?,
            warm_up_c: reader.temperature()?,
            reading: reader.reading()?,
            temperature_c: reader.temperature()?,
            expected_flags: u16::try_from(reader.u32()?).ok()?,
            reference_kpa: reader.f64s()?,
            tolerance_kpa: reader.f64s()?,
        })
    }
}

impl HardCalibration {
    /// Encodes the calibration.
    pub fn encode(&self) -> [u8; HARD_CALIBRATION_BYTES] {
        let mut bytes = [0; HARD_CALIBRATION_BYTES];
        let mut writer = Writer::new(&mut bytes);
        writer.u64(self.seed);
        writer.put(&self.shape);
        writer.u32(self.point_count);
        for (pressure_kpa, relative_change) in &self.points {
            writer.f32(*pressure_kpa);
            writer.f32(*relative_change);
        }
        writer.u32(self.probe_count);
        for probe in &self.probes {
            writer.f32(probe.relative_change);
            writer.f64(probe.reference_kpa);
            writer.f64(probe.lower_kpa);
            writer.f64(probe.upper_kpa);
        }
        bytes
    }

    /// Decodes a calibration from the start of `bytes`.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let mut reader = Reader::new(bytes);
        let seed = reader.u64()?;
        let shape = reader.take()?;
        let point_count = reader.u32()?;
        let mut points = [(0.0, 0.0); CALIBRATION_POINTS_MAX];
        for point in points.iter_mut() {
            *point = (reader.f32()?, reader.f32()?);
        }
        let probe_count = reader.u32()?;
        let mut probes = [Probe::default(); CALIBRATION_PROBES_MAX];
        for probe in probes.iter_mut() {
            *probe = Probe {
                relative_change: reader.f32()?,
                reference_kpa: reader.f64()?,
                lower_kpa: reader.f64()?,
                upper_kpa: reader.f64()?,
            };
        }
        Some(Self {
            seed,
            shape,
            point_count,
            points,
            probe_count,
            probes,
        })
    }
}
