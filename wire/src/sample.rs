//! The sample frame: one sample set of one pad's four taxels, with what a robot consumes from it
//! (force, centre of pressure, contact). One frame per pad per sample set: a damaged frame costs
//! one pad's set, not every pad's, and the device's output queue holds small entries. Its worst
//! case (every value present) encodes to 76 bytes, two USB packets.
//!
//! The body is not a derived postcard struct: status bytes say which optional values follow,
//! and the integers are fixed-width little-endian so that the layout is the same for every value.

use core::fmt;

use serde::de::{Error as _, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::TAXEL_COUNT;

/// Where the temperature of a sample set came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum TemperatureSource {
    /// No temperature is known; the model ran without temperature correction.
    None = 0,
    /// The TMP117 next to the pad (the normal case).
    Tmp117 = 1,
    /// The MCU's internal sensor, a fallback while the TMP117 does not answer.
    McuInternal = 2,
    /// The last valid reading, held while no sensor answers.
    LastKnown = 3,
}

impl TemperatureSource {
    /// The 2-bit code of this source (also its postcard discriminant).
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The source of a 2-bit code; only the two low bits are read, so every byte maps to a source.
    pub const fn from_code(code: u8) -> TemperatureSource {
        match code & 0b11 {
            0 => TemperatureSource::None,
            1 => TemperatureSource::Tmp117,
            2 => TemperatureSource::McuInternal,
            _ => TemperatureSource::LastKnown,
        }
    }
}

/// One taxel of a sample set.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaxelSample {
    /// The pressure in kPa; `None` when the taxel is faulted (never sent as a number then).
    pub pressure_kpa: Option<f32>,
    /// The measured capacitance in pF, parasitic capacitance included.
    pub capacitance_pf: f32,
    /// The raw taxel flag bits, see [`crate::flags`].
    pub flags: u16,
}

/// Which pad of the device a frame is about: 0 to [`PadIndex::MAX`], the order of the pads in
/// the device's pad list (multiplexer channel order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadIndex(u8);

impl PadIndex {
    /// The highest index: eight pads, one per multiplexer channel.
    pub const MAX: u8 = 7;

    /// The index `index`, if it is at most [`PadIndex::MAX`].
    pub const fn new(index: u8) -> Option<Self> {
        if index <= Self::MAX {
            Some(Self(index))
        } else {
            None
        }
    }

    /// The index as a number.
    pub const fn get(self) -> u8 {
        self.0
    }
}

impl Serialize for PadIndex {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_u8(self.0)
    }
}

impl<'de> Deserialize<'de> for PadIndex {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let index = u8::deserialize(deserializer)?;
        PadIndex::new(index).ok_or_else(|| D::Error::custom("pad index above 7"))
    }
}

/// What a robot consumes from one sample set of a pad, computed on the device from the taxels
/// that read (faulted taxels are excluded, and `partial` says so).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadSummary {
    /// Total normal force on the pad's electrodes, N; `None` when no taxel reads.
    pub force_n: Option<f32>,
    /// Centre of pressure in the pad's frame, mm (x, y); `None` when the force is too small
    /// to place it.
    pub centre_of_pressure_mm: Option<[f32; 2]>,
    /// Some taxels were excluded because they are faulted.
    pub partial: bool,
    /// The pad is in contact (hysteresis and debounce applied on the device).
    pub contact: bool,
}

/// One sample set: one pad's four taxels at one instant, with temperature, timing and the pad's
/// force, centre of pressure and contact.
///
/// Its serde implementation is the wire layout and is meant for postcard: absent values are
/// left out of a tuple, which other serde formats would see as a tuple of varying length.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleFrame {
    /// The pad.
    pub pad: PadIndex,
    /// Increments by one per sample set produced (dropped sets leave a gap); wraps at `u32::MAX`.
    /// All pads of one set share the number.
    pub sequence: u32,
    /// The device clock at the end of the conversion, in microseconds since boot.
    pub timestamp_us: u64,
    /// The temperature used for this sample set, in °C.
    pub temperature_c: Option<f32>,
    /// Where `temperature_c` came from.
    pub temperature_source: TemperatureSource,
    /// The taxels C11, C12, C21, C22.
    pub taxels: [TaxelSample; TAXEL_COUNT],
    /// Force, centre of pressure and contact.
    pub summary: PadSummary,
}

/// Status byte bits 0..=3: the pressure of taxel 0..=3 follows.
const STATUS_PRESSURE_PRESENT_MASK: u8 = 0b0000_1111;
/// Status byte bit 4: the temperature follows.
const STATUS_TEMPERATURE_PRESENT: u8 = 1 << 4;
/// Status byte bits 5..=6: the temperature source code.
const STATUS_TEMPERATURE_SOURCE_SHIFT: u32 = 5;
/// Status byte bit 7: reserved, must be zero (protocol versions 1 to 3).
const STATUS_RESERVED: u8 = 1 << 7;

/// Pad byte bits 0..=2: the pad index.
const PAD_INDEX_MASK: u8 = 0b0000_0111;
/// Pad byte bit 3: contact.
const PAD_CONTACT: u8 = 1 << 3;
/// Pad byte bit 4: the force follows.
const PAD_FORCE_PRESENT: u8 = 1 << 4;
/// Pad byte bit 5: the centre of pressure follows.
const PAD_CENTRE_PRESENT: u8 = 1 << 5;
/// Pad byte bit 6: some taxels were excluded from force and centre of pressure.
const PAD_PARTIAL: u8 = 1 << 6;
/// Pad byte bit 7: reserved, must be zero.
const PAD_RESERVED: u8 = 1 << 7;

/// Status, pad byte, sequence, timestamp, temperature, force, centre of pressure, then
/// pressure, capacitance, flags per taxel.
const SAMPLE_ELEMENT_COUNT_MAX: usize = 7 + 3 * TAXEL_COUNT;

impl SampleFrame {
    /// The largest body: status 1 + pad byte 1 + sequence 4 + timestamp 8 + temperature 4
    /// + force 4 + centre of pressure 8 + 4 x (pressure 4 + capacitance 4 + flags 2).
    pub const MAX_BODY_LEN: usize = 1 + 1 + 4 + 8 + 4 + 4 + 8 + TAXEL_COUNT * (4 + 4 + 2);
    /// The largest encoded frame, delimiter included (76 bytes: two USB packets).
    pub const MAX_ENCODED_LEN: usize = crate::frame_encoded_len_bound(Self::MAX_BODY_LEN);

    /// The pad byte that follows the status byte.
    pub fn pad_byte(&self) -> u8 {
        let mut byte = self.pad.get() & PAD_INDEX_MASK;
        if self.summary.contact {
            byte |= PAD_CONTACT;
        }
        if self.summary.force_n.is_some() {
            byte |= PAD_FORCE_PRESENT;
        }
        if self.summary.centre_of_pressure_mm.is_some() {
            byte |= PAD_CENTRE_PRESENT;
        }
        if self.summary.partial {
            byte |= PAD_PARTIAL;
        }
        byte
    }

    /// The status byte that leads the body.
    pub fn status_byte(&self) -> u8 {
        let mut status = self.temperature_source.code() << STATUS_TEMPERATURE_SOURCE_SHIFT;
        if self.temperature_c.is_some() {
            status |= STATUS_TEMPERATURE_PRESENT;
        }
        for (index, taxel) in self.taxels.iter().enumerate() {
            if taxel.pressure_kpa.is_some() {
                status |= 1 << index;
            }
        }
        status
    }
}

impl Serialize for SampleFrame {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        // postcard writes tuple elements back to back without a count, so optional elements are
        // simply left out; the status byte tells the reader which ones are there.
        let mut tuple = serializer.serialize_tuple(SAMPLE_ELEMENT_COUNT_MAX)?;
        tuple.serialize_element(&self.status_byte())?;
        tuple.serialize_element(&self.pad_byte())?;
        tuple.serialize_element(&self.sequence.to_le_bytes())?;
        tuple.serialize_element(&self.timestamp_us.to_le_bytes())?;
        if let Some(temperature_c) = self.temperature_c {
            tuple.serialize_element(&temperature_c)?;
        }
        if let Some(force_n) = self.summary.force_n {
            tuple.serialize_element(&force_n)?;
        }
        if let Some(centre_mm) = self.summary.centre_of_pressure_mm {
            tuple.serialize_element(&centre_mm)?;
        }
        for taxel in &self.taxels {
            if let Some(pressure_kpa) = taxel.pressure_kpa {
                tuple.serialize_element(&pressure_kpa)?;
            }
            tuple.serialize_element(&taxel.capacitance_pf)?;
            tuple.serialize_element(&taxel.flags.to_le_bytes())?;
        }
        tuple.end()
    }
}

impl<'de> Deserialize<'de> for SampleFrame {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_tuple(SAMPLE_ELEMENT_COUNT_MAX, SampleVisitor)
    }
}

struct SampleVisitor;

/// Reads the tuple elements in order and counts them for the error message.
struct Elements<A> {
    access: A,
    read: usize,
}

impl<'de, A: SeqAccess<'de>> Elements<A> {
    fn next<T: Deserialize<'de>>(&mut self) -> Result<T, A::Error> {
        let index = self.read;
        self.read += 1;
        self.access
            .next_element()?
            .ok_or_else(|| A::Error::invalid_length(index, &"a sample frame body"))
    }
}

impl<'de> Visitor<'de> for SampleVisitor {
    type Value = SampleFrame;

    fn expecting(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str("a sample frame body")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, access: A) -> Result<SampleFrame, A::Error> {
        let mut elements = Elements { access, read: 0 };
        let status: u8 = elements.next()?;
        if status & STATUS_RESERVED != 0 {
            return Err(A::Error::custom("reserved status bit set"));
        }
        let pad_byte: u8 = elements.next()?;
        if pad_byte & PAD_RESERVED != 0 {
            return Err(A::Error::custom("reserved pad bit set"));
        }
        let pad = PadIndex(pad_byte & PAD_INDEX_MASK);
        let sequence = u32::from_le_bytes(elements.next()?);
        let timestamp_us = u64::from_le_bytes(elements.next()?);
        let temperature_c = if status & STATUS_TEMPERATURE_PRESENT != 0 {
            Some(elements.next::<f32>()?)
        } else {
            None
        };
        let force_n = if pad_byte & PAD_FORCE_PRESENT != 0 {
            Some(elements.next::<f32>()?)
        } else {
            None
        };
        let centre_of_pressure_mm = if pad_byte & PAD_CENTRE_PRESENT != 0 {
            Some(elements.next::<[f32; 2]>()?)
        } else {
            None
        };
        let summary = PadSummary {
            force_n,
            centre_of_pressure_mm,
            partial: pad_byte & PAD_PARTIAL != 0,
            contact: pad_byte & PAD_CONTACT != 0,
        };
        let temperature_source =
            TemperatureSource::from_code(status >> STATUS_TEMPERATURE_SOURCE_SHIFT);
        let mut taxels = [TaxelSample {
            pressure_kpa: None,
            capacitance_pf: 0.0,
            flags: 0,
        }; TAXEL_COUNT];
        for (taxel_index, taxel) in taxels.iter_mut().enumerate() {
            let pressure_present = status & STATUS_PRESSURE_PRESENT_MASK & (1 << taxel_index) != 0;
            taxel.pressure_kpa = if pressure_present {
                Some(elements.next::<f32>()?)
            } else {
                None
            };
            taxel.capacitance_pf = elements.next()?;
            taxel.flags = u16::from_le_bytes(elements.next()?);
        }
        Ok(SampleFrame {
            pad,
            sequence,
            timestamp_us,
            temperature_c,
            temperature_source,
            taxels,
            summary,
        })
    }
}
