//! Where processed sample sets go: anything that can take one without waiting.

use crate::ProcessedSample;

/// The consumer refused the set (its queue is full).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SinkFull;

/// A consumer of sample sets that never blocks the loop.
pub trait SampleSink {
    /// Takes the set now, or refuses it.
    fn try_push(&mut self, sample: ProcessedSample) -> Result<(), SinkFull>;
}

impl<const N: usize> SampleSink for heapless::Deque<ProcessedSample, N> {
    fn try_push(&mut self, sample: ProcessedSample) -> Result<(), SinkFull> {
        self.push_back(sample).map_err(|_| SinkFull)
    }
}
