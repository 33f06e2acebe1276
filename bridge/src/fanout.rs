//! One stream of frames and health to several publishers: the Zenoh side (ROS 2 or plain form)
//! and, with `--foxglove`, the Foxglove WebSocket server ([`crate::foxglove`]). Each gets every
//! [`Outgoing`] in order; a publisher's error does not keep the others from theirs.

use crate::health::DeviceHealth;
use crate::publisher::{FramePublisher, Outgoing};

/// Publishes through every one of its publishers, in the order given.
pub struct FanOut<'a> {
    publishers: Vec<&'a mut dyn FramePublisher>,
}

impl<'a> FanOut<'a> {
    /// Publishes through `publishers`, first to last.
    pub fn new(publishers: Vec<&'a mut dyn FramePublisher>) -> Self {
        Self { publishers }
    }

    /// Calls `step` on every publisher, all of them even when one fails; the first error.
    fn each(
        &mut self,
        mut step: impl FnMut(&mut dyn FramePublisher) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let mut first_error = None;
        for publisher in &mut self.publishers {
            if let Err(error) = step(&mut **publisher) {
                first_error.get_or_insert(error);
            }
        }
        first_error.map_or(Ok(()), Err)
    }
}

impl FramePublisher for FanOut<'_> {
    fn publish(&mut self, outgoing: &Outgoing) -> anyhow::Result<()> {
        self.each(|publisher| publisher.publish(outgoing))
    }

    fn publish_health(&mut self, healths: &[DeviceHealth], stamp_ns: u64) -> anyhow::Result<()> {
        self.each(|publisher| publisher.publish_health(healths, stamp_ns))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts what it was given; fails every call when `fails`.
    #[derive(Default)]
    struct Counting {
        frames: usize,
        healths: usize,
        fails: bool,
    }

    impl FramePublisher for Counting {
        fn publish(&mut self, _outgoing: &Outgoing) -> anyhow::Result<()> {
            self.frames += 1;
            anyhow::ensure!(!self.fails, "refused");
            Ok(())
        }

        fn publish_health(&mut self, _: &[DeviceHealth], _: u64) -> anyhow::Result<()> {
            self.healths += 1;
            anyhow::ensure!(!self.fails, "refused");
            Ok(())
        }
    }

    #[test]
    fn every_publisher_gets_everything_even_after_one_fails() {
        let mut failing = Counting {
            fails: true,
            ..Counting::default()
        };
        let mut working = Counting::default();
        let contact = Outgoing::Contact {
            device: 0,
            pad: 1,
            started: true,
            stamp_ns: 5,
            arrival_ns: 6,
        };
        {
            let mut fan_out = FanOut::new(vec![&mut failing, &mut working]);
            assert!(fan_out.publish(&contact).is_err());
            assert!(fan_out.publish(&contact).is_err());
            assert!(fan_out.publish_health(&[], 7).is_err());
        }
        assert_eq!((failing.frames, failing.healths), (2, 1));
        assert_eq!((working.frames, working.healths), (2, 1));
    }
}
