//! Sample frames of several devices put on one host timeline, as `taxel record` with several
//! devices writes them: each device's clock mapped onto the host clock by its own
//! [`ClockMapper`], rows released in host-time order, one row per sample frame.
//!
//! # When a row gets its host time
//!
//! A device's clock estimate improves as its frames arrive, and a row must not be written
//! before the rows that belong before it have arrived from every device. So frames are held
//! for [`TimelineConfig::hold_us`] (4 s by default) of host time after the newest arrival seen
//! from any device, and a frame is written once its mapped host time is older than that: it is
//! mapped with its device's estimate **as of the moment it is written**, which has seen the
//! frames of the hold after it (the mapping interpolates rather than extrapolates, and the
//! estimate has settled: it needs about 1.5 s of frames, see [`crate::clock_sync`]). The
//! recording's end writes what is still held, with the estimates at the end.
//!
//! # The error column
//!
//! Each row carries the estimate's uncertainty at the frame's device time
//! ([`ClockEstimate::uncertainty_at_us`]): an estimated bound on `|host time − true sampling
//! instant|` under the assumptions stated in [`crate::clock_sync`]. Rows are never written out
//! of host-time order: a frame whose mapped time falls before a row already written (it
//! arrived more than the hold late, or the estimate moved back) is written at the last written
//! host time, and the shift is added to its error, which therefore still bounds its distance
//! from the true instant. A frame of a device that has no estimate (too few frames yet, or the
//! fit is not believable) is placed at its arrival time, which is later than the sample by an
//! unknown latency: its error is unknown, `None` (an empty cell), never a number.
//!
//! # Restarts
//!
//! When a device's mapper starts again (the device rebooted, a clock stepped, a long gap), the
//! frames it still holds are placed with the estimate from before the restart; the frames
//! after it wait for the new estimate.
//!
//! Every frame given to [`HostTimeline::push`] comes out exactly once, from
//! [`HostTimeline::release`] or [`HostTimeline::finish`].

use std::collections::VecDeque;

use wire::SampleFrame;

use crate::clock_sync::{ClockEstimate, ClockMapper, ClockMapperConfig, Observation};

/// Settings of a [`HostTimeline`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimelineConfig {
    /// How long, in host µs after the newest arrival, a frame is held before it is written
    /// (see the module documentation). Longer than the mapper's settling (about 1.5 s) and
    /// than any latency a frame may have and still be written in its place.
    pub hold_us: u64,
    /// The settings of every device's clock mapper.
    pub mapper: ClockMapperConfig,
}

impl Default for TimelineConfig {
    fn default() -> Self {
        Self {
            hold_us: 4_000_000,
            mapper: ClockMapperConfig::default(),
        }
    }
}

/// Where a frame goes on the host timeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Placement {
    /// Host time, µs of the host clock.
    pub host_us: u64,
    /// Estimated bound on the distance from the true sampling instant, µs; `None` when the
    /// device had no clock estimate (the host time is then the frame's arrival).
    pub sync_error_us: Option<u64>,
}

/// One row of the timeline: a sample frame of one device at its host time.
#[derive(Debug, Clone, PartialEq)]
pub struct TimelineRow {
    /// The device's index (its place among the devices given).
    pub device: usize,
    /// The frame as received.
    pub sample: SampleFrame,
    /// When it arrived, host µs.
    pub arrival_us: u64,
    /// Its host time, µs; non-decreasing from row to row.
    pub host_us: u64,
    /// Estimated bound on `|host_us − true sampling instant|`, µs; `None` when unknown (no
    /// clock estimate: `host_us` is then the arrival time).
    pub sync_error_us: Option<u64>,
}

/// What the timeline did with one device's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DeviceTimelineCounts {
    /// Rows written.
    pub rows: u64,
    /// Rows written without a clock estimate (at their arrival time, error unknown).
    pub rows_without_estimate: u64,
    /// Rows written later than their mapping to keep host-time order (the shift is in their
    /// error).
    pub rows_shifted: u64,
    /// Frames held, not yet written.
    pub held: u64,
}

/// A frame waiting to be written.
#[derive(Debug, Clone)]
struct Held {
    sample: SampleFrame,
    arrival_us: u64,
    // Set when the mapper restarted after this frame: its place under the old estimate.
    fixed: Option<Placement>,
}

#[derive(Debug, Clone)]
struct DeviceTimeline {
    mapper: ClockMapper,
    held: VecDeque<Held>,
    counts: DeviceTimelineCounts,
}

/// Several devices' frames on one host timeline (see the module documentation).
#[derive(Debug, Clone)]
pub struct HostTimeline {
    config: TimelineConfig,
    devices: Vec<DeviceTimeline>,
    newest_arrival_us: Option<u64>,
    last_written_us: Option<u64>,
}

/// The place of `held` with `estimate`, or at its arrival without one.
fn place(estimate: Option<&ClockEstimate>, held: &Held) -> Placement {
    match estimate {
        Some(estimate) => Placement {
            host_us: estimate.to_host_us(held.sample.timestamp_us),
            sync_error_us: Some(estimate.uncertainty_at_us(held.sample.timestamp_us)),
        },
        None => Placement {
            host_us: held.arrival_us,
            sync_error_us: None,
        },
    }
}

impl HostTimeline {
    /// A timeline of `device_count` devices, nothing received.
    pub fn new(device_count: usize, config: TimelineConfig) -> Self {
        Self {
            config,
            devices: (0..device_count)
                .map(|_| DeviceTimeline {
                    mapper: ClockMapper::with_config(config.mapper),
                    held: VecDeque::new(),
                    counts: DeviceTimelineCounts::default(),
                })
                .collect(),
            newest_arrival_us: None,
            last_written_us: None,
        }
    }

    /// The number of devices.
    pub fn device_count(&self) -> usize {
        self.devices.len()
    }

    /// Takes one sample frame of `device` that arrived at host time `arrival_us` (the frames of
    /// one device in the order received). Returns false, taking nothing, for a device index out
    /// of range.
    pub fn push(&mut self, device: usize, sample: SampleFrame, arrival_us: u64) -> bool {
        let Some(timeline) = self.devices.get_mut(device) else {
            return false;
        };
        let before = timeline.mapper.estimate();
        if let Observation::Restarted(_) = timeline.mapper.observe(sample.timestamp_us, arrival_us)
        {
            for held in timeline.held.iter_mut().filter(|held| held.fixed.is_none()) {
                held.fixed = Some(place(before.as_ref(), held));
            }
        }
        timeline.held.push_back(Held {
            sample,
            arrival_us,
            fixed: None,
        });
        timeline.counts.held += 1;
        self.newest_arrival_us = Some(
            self.newest_arrival_us
                .map_or(arrival_us, |newest| newest.max(arrival_us)),
        );
        true
    }

    /// The rows whose host time is at least [`TimelineConfig::hold_us`] before the newest
    /// arrival, in host-time order.
    pub fn release(&mut self) -> Vec<TimelineRow> {
        let Some(newest_us) = self.newest_arrival_us else {
            return Vec::new();
        };
        let horizon_us = newest_us.saturating_sub(self.config.hold_us);
        std::iter::from_fn(|| self.next_row(Some(horizon_us))).collect()
    }

    /// Every row still held, in host-time order (the recording ended).
    pub fn finish(&mut self) -> Vec<TimelineRow> {
        std::iter::from_fn(|| self.next_row(None)).collect()
    }

    /// The current clock estimate of `device`.
    pub fn estimate(&self, device: usize) -> Option<ClockEstimate> {
        self.devices
            .get(device)
            .and_then(|timeline| timeline.mapper.estimate())
    }

    /// How often `device`'s clock mapper started again (reboots, clock steps, gaps).
    pub fn restarts(&self, device: usize) -> u64 {
        self.devices
            .get(device)
            .map_or(0, |timeline| timeline.mapper.restarts())
    }

    /// What happened to `device`'s frames so far.
    pub fn counts(&self, device: usize) -> DeviceTimelineCounts {
        self.devices
            .get(device)
            .map(|timeline| timeline.counts)
            .unwrap_or_default()
    }

    /// The earliest held frame over every device, if its host time is not after `horizon_us`.
    fn next_row(&mut self, horizon_us: Option<u64>) -> Option<TimelineRow> {
        let mut earliest: Option<(usize, Placement)> = None;
        for (device, timeline) in self.devices.iter().enumerate() {
            let Some(head) = timeline.held.front() else {
                continue;
            };
            let placement = head
                .fixed
                .unwrap_or_else(|| place(timeline.mapper.estimate().as_ref(), head));
            // A strict comparison: equal times go to the lower device index.
            if earliest.is_none_or(|(_, best)| placement.host_us < best.host_us) {
                earliest = Some((device, placement));
            }
        }
        let (device, placement) = earliest?;
        if horizon_us.is_some_and(|horizon_us| placement.host_us > horizon_us) {
            return None;
        }
        let timeline = self.devices.get_mut(device)?;
        let held = timeline.held.pop_front()?;
        let host_us = placement
            .host_us
            .max(self.last_written_us.unwrap_or(placement.host_us));
        let shift_us = host_us - placement.host_us;
        let counts = &mut timeline.counts;
        counts.rows += 1;
        counts.held = counts.held.saturating_sub(1);
        if placement.sync_error_us.is_none() {
            counts.rows_without_estimate += 1;
        }
        if shift_us > 0 {
            counts.rows_shifted += 1;
        }
        self.last_written_us = Some(host_us);
        Some(TimelineRow {
            device,
            sample: held.sample,
            arrival_us: held.arrival_us,
            host_us,
            sync_error_us: placement
                .sync_error_us
                .map(|error_us| error_us.saturating_add(shift_us)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(sequence: u32, timestamp_us: u64) -> SampleFrame {
        SampleFrame {
            pad: wire::PadIndex::default(),
            sequence,
            timestamp_us,
            temperature_c: None,
            temperature_source: wire::TemperatureSource::None,
            taxels: [wire::TaxelSample {
                pressure_kpa: None,
                capacitance_pf: 4.5,
                flags: 0,
            }; 4],
            summary: wire::PadSummary::default(),
        }
    }

    #[test]
    fn frames_wait_for_the_hold_and_come_out_once_in_host_order() {
        let mut timeline = HostTimeline::new(2, TimelineConfig::default());
        // Device 0's clock is 5 s ahead of the host, device 1's 2 s; latencies 1 and 4 ms.
        for step in 0..1_000_u64 {
            let true_us = step * 10_000;
            let sequence = u32::try_from(step).unwrap();
            timeline.push(0, frame(sequence, true_us + 5_000_000), true_us + 1_000);
            timeline.push(1, frame(sequence, true_us + 2_000_000), true_us + 4_000);
        }
        assert!(!timeline.push(2, frame(0, 0), 0));
        let mut rows = timeline.release();
        // Everything mapped before 10 s − 4 s of hold is out.
        let released = rows.len();
        assert!((1_150..=1_210).contains(&released), "{released}");
        rows.extend(timeline.finish());
        assert_eq!(rows.len(), 2_000);
        assert!(rows
            .windows(2)
            .all(|pair| pair[0].host_us <= pair[1].host_us));
        for device in 0..2 {
            let sequences: Vec<u32> = rows
                .iter()
                .filter(|row| row.device == device)
                .map(|row| row.sample.sequence)
                .collect();
            assert_eq!(sequences, (0..1_000).collect::<Vec<u32>>());
            assert_eq!(timeline.counts(device).rows, 1_000);
            assert_eq!(timeline.counts(device).held, 0);
        }
        // An exact clock with a constant latency maps to arrival less the latency bound.
        let row = rows.iter().find(|row| row.device == 1).unwrap();
        assert_eq!(row.host_us, row.arrival_us - 500);
        // 501 µs, grown by 1 ppm of wander over the distance from the newest frame.
        assert!((501..=520).contains(&row.sync_error_us.unwrap()), "{row:?}");
    }

    #[test]
    fn without_an_estimate_a_frame_sits_at_its_arrival_with_no_error() {
        let mut timeline = HostTimeline::new(1, TimelineConfig::default());
        timeline.push(0, frame(1, 77), 1_000);
        let rows = timeline.finish();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].host_us, 1_000);
        assert_eq!(rows[0].sync_error_us, None);
        assert_eq!(timeline.counts(0).rows_without_estimate, 1);
    }

    #[test]
    fn a_frame_later_than_the_hold_keeps_the_order_and_says_so_in_its_error() {
        let config = TimelineConfig {
            hold_us: 1_000_000,
            ..TimelineConfig::default()
        };
        let mut timeline = HostTimeline::new(2, config);
        for step in 0..500_u64 {
            let true_us = step * 10_000;
            timeline.push(0, frame(step as u32, true_us), true_us + 1_000);
        }
        let written = timeline.release();
        let last_us = written.last().unwrap().host_us;
        // Device 1's only frame was sampled at 1 s and arrives now, 4 s late.
        timeline.push(1, frame(0, 1_000_000), 5_000_000);
        let rows = timeline.finish();
        let late = rows.iter().find(|row| row.device == 1).unwrap();
        assert!(late.host_us >= last_us);
        assert_eq!(late.sync_error_us, None, "no estimate from one frame");
        assert!(rows
            .windows(2)
            .all(|pair| pair[0].host_us <= pair[1].host_us));
    }
}
