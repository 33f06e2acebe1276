//! The frame check sequence: CRC-16/IBM-SDLC (also catalogued as CRC-16/X-25 and used as the
//! HDLC FCS), computed over version, kind and body and appended little-endian.

use crc::{Algorithm, Crc, CRC_16_IBM_SDLC};

/// The CRC algorithm of every frame: poly 0x1021, init 0xFFFF, refin and refout true,
/// xorout 0xFFFF, check value 0x906E (CRC of the ASCII bytes `123456789`).
pub const CRC_ALGORITHM: &Algorithm<u16> = &CRC_16_IBM_SDLC;

const CRC16: Crc<u16> = Crc::<u16>::new(CRC_ALGORITHM);

/// CRC-16/IBM-SDLC of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_parameters_and_check_value() {
        assert_eq!(CRC_ALGORITHM.width, 16);
        assert_eq!(CRC_ALGORITHM.poly, 0x1021);
        assert_eq!(CRC_ALGORITHM.init, 0xFFFF);
        assert!(CRC_ALGORITHM.refin);
        assert!(CRC_ALGORITHM.refout);
        assert_eq!(CRC_ALGORITHM.xorout, 0xFFFF);
        assert_eq!(CRC_ALGORITHM.check, 0x906E);
        assert_eq!(crc16(b"123456789"), 0x906E);
    }

    #[test]
    fn residue_over_data_and_little_endian_crc_is_constant() {
        let data = [0x01, 0x02, 0x80, 0xFF, 0x00, 0x42];
        let mut with_crc = [0u8; 8];
        with_crc[..6].copy_from_slice(&data);
        with_crc[6..].copy_from_slice(&crc16(&data).to_le_bytes());
        // The catalogue residue 0xF0B8 is before xorout: 0xF0B8 ^ 0xFFFF = 0x0F47.
        assert_eq!(crc16(&with_crc), 0x0F47);
    }
}
