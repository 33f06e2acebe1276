//! A publisher's sequence numbers in rmw_zenoh's form: 64 bits, the first message numbered 1
//! (`PublisherData`'s `sequence_number_` starts at 1 and counts in an `int64_t`). A pad's topics
//! are numbered from the device's 32-bit sample-set sequence, which starts wherever the device
//! is (0 after a boot) and wraps after 2^32 sets (about 500 days at 100 sets per second): it is
//! extended to 64 bits on the host, per publisher, so that a lost set is still a gap of its
//! size and a wrap is none.

/// A device's 32-bit sequence numbers as one publisher's 64-bit numbering from 1.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SequenceExtender {
    /// The device's last sequence number and the number published for it.
    last: Option<(u32, u64)>,
}

/// A step of the device's sequence at or above this is taken for a step back (a device that
/// restarted its count), not for 2^31 lost sets.
const BACKWARDS_FROM: u32 = 1 << 31;

impl SequenceExtender {
    /// The number to publish for the device's `device_sequence`: 1 for the first; then the
    /// previous number plus the device's step forward, modulo 2^32 (so a wrap gives no gap and
    /// a lost set one of its size). A step of 0 (the same set again) or backwards (the device
    /// restarted its count) counts as 1, so the numbers always increase.
    pub fn next(&mut self, device_sequence: u32) -> u64 {
        let published = match self.last {
            None => 1,
            Some((last_device, last_published)) => {
                let step = device_sequence.wrapping_sub(last_device);
                let step = if step == 0 || step >= BACKWARDS_FROM {
                    1
                } else {
                    u64::from(step)
                };
                last_published.saturating_add(step)
            }
        };
        self.last = Some((device_sequence, published));
        published
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn published(device: &[u32]) -> Vec<u64> {
        let mut extender = SequenceExtender::default();
        device
            .iter()
            .map(|&sequence| extender.next(sequence))
            .collect()
    }

    #[test]
    fn the_first_message_is_1_wherever_the_device_starts() {
        assert_eq!(published(&[0, 1, 2]), [1, 2, 3]);
        assert_eq!(published(&[7_000, 7_001]), [1, 2]);
    }

    #[test]
    fn a_wrap_across_2_to_the_32_gives_no_gap() {
        let device = [u32::MAX - 2, u32::MAX - 1, u32::MAX, 0, 1, 2];
        assert_eq!(published(&device), [1, 2, 3, 4, 5, 6]);
        // Over many wraps the numbers keep counting past 2^32.
        let mut extender = SequenceExtender::default();
        let mut last = 0;
        for step in 0..5_u64 {
            let device_sequence = (step * (1 << 30)) as u32;
            last = extender.next(device_sequence);
        }
        assert_eq!(last, 1 + 4 * (1 << 30));
        assert!(last > u64::from(u32::MAX));
    }

    #[test]
    fn a_lost_set_is_a_gap_of_its_size_even_across_the_wrap() {
        assert_eq!(published(&[10, 11, 14]), [1, 2, 5]);
        assert_eq!(published(&[u32::MAX - 1, 1]), [1, 4]);
    }

    #[test]
    fn a_repeat_or_a_restart_still_increases() {
        assert_eq!(published(&[5, 5, 6]), [1, 2, 3]);
        assert_eq!(published(&[1_000, 1_001, 0, 1]), [1, 2, 3, 4]);
    }
}
