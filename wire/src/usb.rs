//! The USB CDC-ACM packet rule the firmware must follow when it writes frames.
//!
//! A full-speed bulk endpoint moves at most 64 bytes per packet, and the host ends a transfer
//! only at a packet shorter than that. A write whose length is an exact multiple of 64 therefore
//! stays in the host's buffer until a later short packet arrives, unless the device follows it
//! with a zero-length packet (ZLP).

/// The bulk max packet size of a full-speed USB CDC-ACM data endpoint.
pub const USB_FULL_SPEED_PACKET_LEN: usize = 64;

/// Whether a write of `len` bytes, sent as 64-byte packets, must be followed by a zero-length
/// packet so that the host delivers it now: true for every non-zero multiple of 64.
pub const fn needs_zero_length_packet(len: usize) -> bool {
    len != 0 && len.is_multiple_of(USB_FULL_SPEED_PACKET_LEN)
}

/// The USB packets of one write, in order: 64-byte packets, the last one shorter, and after an
/// exact multiple of 64 bytes the zero-length packet that ends the transfer.
pub fn usb_packets(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let end_of_transfer: Option<&[u8]> = needs_zero_length_packet(bytes.len()).then_some(&[]);
    bytes
        .chunks(USB_FULL_SPEED_PACKET_LEN)
        .chain(end_of_transfer)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_write_of_a_multiple_of_64_bytes_ends_with_a_zero_length_packet() {
        let lengths = |len: usize| {
            let bytes = [1u8; 200];
            usb_packets(&bytes[..len])
                .map(<[u8]>::len)
                .collect::<heapless::Vec<usize, 8>>()
        };
        assert_eq!(lengths(63), [63]);
        assert_eq!(lengths(64), [64, 0]);
        assert_eq!(lengths(65), [64, 1]);
        assert_eq!(lengths(128), [64, 64, 0]);
        assert!(lengths(0).is_empty());
    }

    #[test]
    fn zero_length_packet_only_after_full_last_packet() {
        assert!(!needs_zero_length_packet(0));
        assert!(!needs_zero_length_packet(1));
        assert!(!needs_zero_length_packet(63));
        assert!(needs_zero_length_packet(64));
        assert!(!needs_zero_length_packet(65));
        assert!(!needs_zero_length_packet(127));
        assert!(needs_zero_length_packet(128));
        assert!(needs_zero_length_packet(192));
    }
}
