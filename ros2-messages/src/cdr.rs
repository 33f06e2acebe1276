//! CDR serialisation as ROS 2 middlewares put it on the wire: the 4-byte encapsulation header
//! `00 01 00 00` (plain CDR, little-endian), then the fields in declaration order, each
//! primitive aligned to its own size (at most 8) counted from the end of the header.
//!
//! Strings are a `u32` length that counts the terminating NUL, the bytes, and the NUL;
//! sequences are a `u32` element count followed by the elements. [`CdrReader`] reads the same
//! layout back (the requests of the bridge's services).

/// The encapsulation header of little-endian plain CDR (XCDR1), as rmw implementations write it.
pub const ENCAPSULATION_CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Builds one CDR-serialised message.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buffer: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// A message with only its encapsulation header so far.
    pub fn new() -> Self {
        let mut buffer = Vec::with_capacity(128);
        buffer.extend_from_slice(&ENCAPSULATION_CDR_LE);
        Self { buffer }
    }

    /// Pads with zeros until the next field starts at a multiple of `alignment` bytes from the
    /// end of the encapsulation header.
    fn align(&mut self, alignment: usize) {
        let offset = self.buffer.len() - ENCAPSULATION_CDR_LE.len();
        let padding = (alignment - offset % alignment) % alignment;
        self.buffer.extend(std::iter::repeat_n(0, padding));
    }

    /// A `uint8`, `byte` or `char`.
    pub fn write_u8(&mut self, value: u8) {
        self.buffer.push(value);
    }

    /// A `bool`: one byte, 0 or 1.
    pub fn write_bool(&mut self, value: bool) {
        self.buffer.push(u8::from(value));
    }

    /// A `uint16`.
    pub fn write_u16(&mut self, value: u16) {
        self.align(2);
        self.buffer.extend_from_slice(&value.to_le_bytes());
    }

    /// A `uint32`.
    pub fn write_u32(&mut self, value: u32) {
        self.align(4);
        self.buffer.extend_from_slice(&value.to_le_bytes());
    }

    /// An `int32`.
    pub fn write_i32(&mut self, value: i32) {
        self.align(4);
        self.buffer.extend_from_slice(&value.to_le_bytes());
    }

    /// A `float32`.
    pub fn write_f32(&mut self, value: f32) {
        self.align(4);
        self.buffer.extend_from_slice(&value.to_le_bytes());
    }

    /// A `float64`.
    pub fn write_f64(&mut self, value: f64) {
        self.align(8);
        self.buffer.extend_from_slice(&value.to_le_bytes());
    }

    /// A `string`. A string too long for a `u32` length (4 GiB) is cut at that length, which no
    /// message of this crate comes near.
    pub fn write_string(&mut self, value: &str) {
        let bytes = value.as_bytes();
        let length = u32::try_from(bytes.len()).unwrap_or(u32::MAX - 1);
        self.write_u32(length + 1);
        self.buffer.extend_from_slice(&bytes[..length as usize]);
        self.buffer.push(0);
    }

    /// The element count that starts a sequence (`T[]`), saturated at `u32::MAX`.
    pub fn write_sequence_length(&mut self, length: usize) {
        self.write_u32(u32::try_from(length).unwrap_or(u32::MAX));
    }

    /// A `uint8[]`: its length, then the bytes.
    pub fn write_bytes(&mut self, bytes: &[u8]) {
        self.write_sequence_length(bytes.len());
        self.buffer.extend_from_slice(bytes);
    }

    /// The serialised message, header included.
    pub fn finish(self) -> Vec<u8> {
        self.buffer
    }
}

/// Why a CDR message could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The message ends before a field does.
    #[error("the message ends at byte {0}, within a field")]
    Truncated(usize),
    /// The encapsulation header is not little-endian plain CDR (`00 01`).
    #[error("encapsulation {0:02x?} is not little-endian CDR (00 01)")]
    Encapsulation([u8; 2]),
    /// A string without its terminating NUL, or not UTF-8.
    #[error("a string is not NUL-terminated UTF-8")]
    String,
    /// A `bool` other than 0 or 1.
    #[error("a bool is {0}")]
    Bool(u8),
}

/// Reads the fields of one CDR-serialised message (little-endian, as [`CdrWriter`] writes).
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    bytes: &'a [u8],
    position: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader of `bytes`, whose encapsulation header must be little-endian plain CDR.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        match bytes {
            [0x00, 0x01, _, _, ..] => Ok(Self { bytes, position: 4 }),
            [first, second, _, _, ..] => Err(CdrError::Encapsulation([*first, *second])),
            _ => Err(CdrError::Truncated(bytes.len())),
        }
    }

    fn take(&mut self, alignment: usize, length: usize) -> Result<&'a [u8], CdrError> {
        let offset = self.position - ENCAPSULATION_CDR_LE.len();
        let start = self.position + (alignment - offset % alignment) % alignment;
        let end = start + length;
        let field = self
            .bytes
            .get(start..end)
            .ok_or(CdrError::Truncated(self.bytes.len()))?;
        self.position = end;
        Ok(field)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        let mut array = [0; N];
        array.copy_from_slice(self.take(N, N)?);
        Ok(array)
    }

    /// A `uint8`, `byte` or `char`.
    pub fn read_u8(&mut self) -> Result<u8, CdrError> {
        Ok(u8::from_le_bytes(self.array()?))
    }

    /// A `bool`.
    pub fn read_bool(&mut self) -> Result<bool, CdrError> {
        match self.read_u8()? {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(CdrError::Bool(other)),
        }
    }

    /// A `uint32`.
    pub fn read_u32(&mut self) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A `float32`.
    pub fn read_f32(&mut self) -> Result<f32, CdrError> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    /// A `string`.
    pub fn read_string(&mut self) -> Result<String, CdrError> {
        let length = usize::try_from(self.read_u32()?).map_err(|_| CdrError::String)?;
        match self.take(1, length)? {
            [text @ .., 0] => std::str::from_utf8(text)
                .map(str::to_owned)
                .map_err(|_| CdrError::String),
            _ => Err(CdrError::String),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_aligned_from_the_end_of_the_header() {
        let mut writer = CdrWriter::new();
        writer.write_u8(7);
        writer.write_f64(1.0);
        writer.write_string("ab");
        writer.write_bool(true);
        writer.write_u32(5);
        let bytes = writer.finish();
        let mut expected = vec![0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0];
        expected.extend_from_slice(&1.0f64.to_le_bytes());
        expected.extend_from_slice(&[3, 0, 0, 0, b'a', b'b', 0, 1]);
        expected.extend_from_slice(&[5, 0, 0, 0]);
        assert_eq!(bytes, expected);
    }

    #[test]
    fn the_reader_reads_what_the_writer_wrote() {
        let mut writer = CdrWriter::new();
        writer.write_u8(7);
        writer.write_f32(1.5);
        writer.write_bool(true);
        writer.write_string("ab");
        writer.write_u32(9);
        let bytes = writer.finish();
        let mut reader = CdrReader::new(&bytes).unwrap();
        assert_eq!(reader.read_u8(), Ok(7));
        assert_eq!(reader.read_f32(), Ok(1.5));
        assert_eq!(reader.read_bool(), Ok(true));
        assert_eq!(reader.read_string().as_deref(), Ok("ab"));
        assert_eq!(reader.read_u32(), Ok(9));
        assert_eq!(reader.read_u8(), Err(CdrError::Truncated(bytes.len())));
        assert_eq!(
            CdrReader::new(&[0, 0, 0, 0]).unwrap_err(),
            CdrError::Encapsulation([0, 0])
        );
        assert_eq!(CdrReader::new(&[0, 1]).unwrap_err(), CdrError::Truncated(2));
    }
}
