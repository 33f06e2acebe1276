//! The store's on-flash format: the layout of its pages and records, and (inside the crate) the
//! pure functions that encode and decode the page header and the record header. Reading and
//! writing them in flash is [`CalibrationStore`](crate::CalibrationStore)'s business.
//!
//! # Layout
//!
//! The region is two erase pages. `W` is the flash word: the larger of the flash's read and
//! write sizes (1 to 32 bytes, dividing 32). Everything starts on a `W` boundary and is padded
//! to the next one with erased bytes (0xFF); integers are little-endian; the CRC is CRC-32/
//! ISO-HDLC ([`RECORD_CRC_ALGORITHM`]).
//!
//! ```text
//! page          page header (16 bytes) | commit word (W bytes) | record | record | ... | erased
//! page header   "TXCS" | format version u8 = 1 | FF FF FF | generation u32 |
//!               CRC-32 of the 12 bytes before it
//! commit word   W bytes of 0x00 once the page is complete (erased until then)
//! record        body length u16 | !body length u16 | save counter u32 | pads u8 | FF FF FF |
//!               CRC-32 of the 12 bytes before it and of the body | body (body length bytes)
//! pads          0 to 7: that pad; 0xFF: every pad
//! ```
//!
//! The body is opaque here ([`encode_body`](crate::encode_body) and
//! [`decode_body`](crate::decode_body) define it); the store reads at most [`MAX_BODY_LEN`]
//! bytes of it, and copies longer ones whole.
//!
//! # Meaning
//!
//! - A page is *complete* when its header has the magic and a matching CRC and its commit word
//!   reads all zeros. The *current* page is the complete page with the highest generation (page
//!   0 of two equal ones); it alone is read. A page of another format version keeps this header
//!   and commit word, so it can be dated: when it is current, nothing in it is read.
//! - Walking a page: from the first record slot, a slot whose 16 header bytes read erased ends
//!   the page; a header whose length does not match its complement (torn, damaged) hides where
//!   the next record starts, so the walk tries again one word further on; any other record ends
//!   where its length says and is *intact* when its CRC matches.
//! - A pad loads, of the intact records of the current page that are its own or for every pad,
//!   the one with the highest save counter. A record for a pad index this firmware does not
//!   hold (8 to 0xFE) is intact but loaded by no pad.
//! - Saves give a record the highest save counter of the current page plus one, and a page they
//!   move to the current page's generation plus one. Nothing is ever written twice between
//!   erases: the commit word is written once, after everything else in its page.

use crc::{Algorithm, Crc, Digest, CRC_32_ISO_HDLC};

use crate::record::MAX_BODY_LEN;

/// Pads a device can hold a calibration for (the TCA9548A's eight channels).
pub const MAX_PADS: u8 = 8;

/// The format version of the pages this firmware writes and reads (the page header's fifth
/// byte).
pub const STORE_FORMAT_VERSION: u8 = 1;

/// The CRC of page headers and records: CRC-32/ISO-HDLC (poly 0x04C11DB7, init and xorout
/// 0xFFFFFFFF, reflected, check value 0xCBF43926), stored little-endian.
pub const RECORD_CRC_ALGORITHM: &Algorithm<u32> = &CRC_32_ISO_HDLC;

/// The page header's length before padding to the flash word.
pub(crate) const PAGE_HEADER_LEN: usize = 16;
/// The record header's length before padding to the flash word.
pub(crate) const RECORD_HEADER_LEN: usize = 16;

/// The longest record this firmware writes, header and body, before padding: 659 bytes.
pub const MAX_RECORD_LEN: usize = RECORD_HEADER_LEN + MAX_BODY_LEN;

/// What flash reads where nothing was written since the last erase.
pub(crate) const ERASED_BYTE: u8 = 0xFF;
/// The commit word's bytes.
pub(crate) const COMMIT_BYTE: u8 = 0x00;

const PAGE_MAGIC: [u8; 4] = *b"TXCS";
const EVERY_PAD_BYTE: u8 = 0xFF;
/// The bytes a header's CRC covers (the CRC is the header's last four).
const CHECKED_HEADER_LEN: usize = 12;

static CRC: Crc<u32> = Crc::<u32>::new(RECORD_CRC_ALGORITHM);

/// Which pads a record's calibration is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordScope {
    /// Every pad without a newer record of its own.
    EveryPad,
    /// One pad, by index (0 to [`MAX_PADS`] - 1).
    Pad(u8),
}

impl RecordScope {
    /// Whether the record's calibration is for `pad`.
    pub fn covers(self, pad: u8) -> bool {
        match self {
            RecordScope::EveryPad => true,
            RecordScope::Pad(own) => own == pad,
        }
    }

    /// The record header's pads byte.
    pub(crate) fn to_byte(self) -> u8 {
        match self {
            RecordScope::EveryPad => EVERY_PAD_BYTE,
            RecordScope::Pad(pad) => pad,
        }
    }

    /// The scope of a pads byte; none for a pad index this firmware does not hold.
    pub(crate) fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            EVERY_PAD_BYTE => Some(RecordScope::EveryPad),
            pad if pad < MAX_PADS => Some(RecordScope::Pad(pad)),
            _ => None,
        }
    }
}

/// A page header whose magic and CRC match.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PageHeader {
    pub(crate) format_version: u8,
    pub(crate) generation: u32,
}

/// The header of a page of this format with `generation`.
pub(crate) fn encode_page_header(generation: u32) -> [u8; PAGE_HEADER_LEN] {
    let mut header = [ERASED_BYTE; PAGE_HEADER_LEN];
    let [m0, m1, m2, m3] = PAGE_MAGIC;
    let [g0, g1, g2, g3] = generation.to_le_bytes();
    let checked = [
        m0,
        m1,
        m2,
        m3,
        STORE_FORMAT_VERSION,
        ERASED_BYTE,
        ERASED_BYTE,
        ERASED_BYTE,
        g0,
        g1,
        g2,
        g3,
    ];
    let [c0, c1, c2, c3] = CRC.checksum(&checked).to_le_bytes();
    for (byte, value) in header
        .iter_mut()
        .zip(checked.into_iter().chain([c0, c1, c2, c3]))
    {
        *byte = value;
    }
    header
}

/// The page header in `bytes`, if its magic and CRC match.
pub(crate) fn decode_page_header(bytes: &[u8; PAGE_HEADER_LEN]) -> Option<PageHeader> {
    let [m0, m1, m2, m3, format_version, r0, r1, r2, g0, g1, g2, g3, c0, c1, c2, c3] = *bytes;
    let checked = [m0, m1, m2, m3, format_version, r0, r1, r2, g0, g1, g2, g3];
    if [m0, m1, m2, m3] != PAGE_MAGIC
        || CRC.checksum(&checked) != u32::from_le_bytes([c0, c1, c2, c3])
    {
        return None;
    }
    Some(PageHeader {
        format_version,
        generation: u32::from_le_bytes([g0, g1, g2, g3]),
    })
}

/// A record header whose length matches its complement (its CRC is not checked yet).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RecordHeader {
    pub(crate) body_len: u16,
    pub(crate) save_counter: u32,
    /// The pads byte; see [`RecordScope::from_byte`].
    pub(crate) pads: u8,
    checked: [u8; CHECKED_HEADER_LEN],
    crc: u32,
}

impl RecordHeader {
    /// A CRC over the header's checked bytes, to feed the body into.
    pub(crate) fn digest(&self) -> Digest<'static, u32> {
        let mut digest = CRC.digest();
        digest.update(&self.checked);
        digest
    }

    /// Whether `digest`, fed the whole body, matches the header's CRC.
    pub(crate) fn matches(&self, digest: Digest<'static, u32>) -> bool {
        digest.finalize() == self.crc
    }
}

/// What a record slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RecordSlot {
    /// Every header byte reads erased: no record here.
    Erased,
    /// The length does not match its complement: torn or damaged.
    Damaged,
    /// A record header.
    Header(RecordHeader),
}

/// The header of a record of `body` with `save_counter` for `scope`.
pub(crate) fn encode_record_header(
    body: &[u8],
    save_counter: u32,
    scope: RecordScope,
) -> Option<[u8; RECORD_HEADER_LEN]> {
    let body_len = u16::try_from(body.len()).ok()?;
    let [l0, l1] = body_len.to_le_bytes();
    let [k0, k1] = (!body_len).to_le_bytes();
    let [s0, s1, s2, s3] = save_counter.to_le_bytes();
    let checked = [
        l0,
        l1,
        k0,
        k1,
        s0,
        s1,
        s2,
        s3,
        scope.to_byte(),
        ERASED_BYTE,
        ERASED_BYTE,
        ERASED_BYTE,
    ];
    let mut digest = CRC.digest();
    digest.update(&checked);
    digest.update(body);
    let [c0, c1, c2, c3] = digest.finalize().to_le_bytes();
    let mut header = [ERASED_BYTE; RECORD_HEADER_LEN];
    for (byte, value) in header
        .iter_mut()
        .zip(checked.into_iter().chain([c0, c1, c2, c3]))
    {
        *byte = value;
    }
    Some(header)
}

/// What the record slot whose header is `bytes` holds.
pub(crate) fn decode_record_header(bytes: &[u8; RECORD_HEADER_LEN]) -> RecordSlot {
    if bytes.iter().all(|&byte| byte == ERASED_BYTE) {
        return RecordSlot::Erased;
    }
    let [l0, l1, k0, k1, s0, s1, s2, s3, pads, r0, r1, r2, c0, c1, c2, c3] = *bytes;
    let body_len = u16::from_le_bytes([l0, l1]);
    if !body_len != u16::from_le_bytes([k0, k1]) {
        return RecordSlot::Damaged;
    }
    RecordSlot::Header(RecordHeader {
        body_len,
        save_counter: u32::from_le_bytes([s0, s1, s2, s3]),
        pads,
        checked: [l0, l1, k0, k1, s0, s1, s2, s3, pads, r0, r1, r2],
        crc: u32::from_le_bytes([c0, c1, c2, c3]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_is_the_catalogued_iso_hdlc() {
        assert_eq!(CRC.checksum(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn headers_round_trip() {
        let header = encode_page_header(0x0102_0304);
        assert_eq!(
            decode_page_header(&header),
            Some(PageHeader {
                format_version: STORE_FORMAT_VERSION,
                generation: 0x0102_0304
            })
        );
        let body = [1, 2, 3];
        let bytes = encode_record_header(&body, 7, RecordScope::Pad(3)).unwrap();
        let RecordSlot::Header(header) = decode_record_header(&bytes) else {
            panic!("{bytes:?}");
        };
        assert_eq!(
            (header.body_len, header.save_counter, header.pads),
            (3, 7, 3)
        );
        let mut digest = header.digest();
        digest.update(&body);
        assert!(header.matches(digest));
        assert_eq!(
            decode_record_header(&[ERASED_BYTE; RECORD_HEADER_LEN]),
            RecordSlot::Erased
        );
    }
}
