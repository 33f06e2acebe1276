//! When a sample set or an event happened on the host clock: the one stamping policy of the
//! recorder (CSV and MCAP), the live view and the bridge.
//!
//! Each device's clock is mapped onto the host's by a [`ClockMapper`] fed with every sample
//! frame's device time and arrival, in µs of real time: a device's Info says how many µs its
//! clock counts per second ([`Stamper::set_clock_us_per_s`]; a simulated device at speed 5
//! counts 5,000,000), so that the mapper, which refuses implausible drifts, sees a clock it can
//! map at any simulated speed; a device not paced to real time at all (0) is never mapped and
//! its items go out at their arrival. An item (a set, an event) is stamped with its device time
//! mapped onto the host clock, never later than its arrival, with the mapping's error bound.
//! The mapper needs about 1.5 s of frames before its first estimate; until then items wait, at
//! most [`MAX_WAIT_US`] each, and one that waited that long without an estimate is stamped
//! with its arrival and no error bound (the files and messages say so). Nothing is dropped, the
//! order of items is kept, and a device's stamps never go back: an item the mapping would place
//! before the previous one (the estimate moved) is stamped with the previous stamp, the shift
//! added to its error bound.

use std::collections::VecDeque;

use crate::clock_sync::{ClockEstimate, ClockMapper};

/// How long an item waits for its device's first clock estimate, µs (the mapper needs about
/// 1.5 s of frames).
pub const MAX_WAIT_US: u64 = 3_000_000;

/// A board's clock rate: a µs per µs of real time.
const REAL_TIME_US_PER_S: u32 = 1_000_000;

/// An item with its stamp.
#[derive(Debug, Clone, PartialEq)]
pub struct Stamped<T> {
    /// The item.
    pub item: T,
    /// When it happened on the host clock, µs (the clock its arrival was read on).
    pub host_us: u64,
    /// When it arrived, µs on the same clock.
    pub arrival_us: u64,
    /// Bound on `host_us`'s distance from the true instant, µs; `None` when the device had no
    /// clock estimate and `host_us` is the arrival.
    pub error_us: Option<u64>,
}

#[derive(Debug)]
struct Held<T> {
    item: T,
    device_us: u64,
    arrival_us: u64,
}

/// One device's clock mapping and the items waiting for it (see the module documentation).
#[derive(Debug)]
pub struct Stamper<T> {
    mapper: ClockMapper,
    waiting: VecDeque<Held<T>>,
    stamped_at_arrival: u64,
    last_host_us: Option<u64>,
    clock_us_per_s: u32,
}

impl<T> Default for Stamper<T> {
    fn default() -> Self {
        Self::new(ClockMapper::new())
    }
}

impl<T> Stamper<T> {
    /// A stamper mapping with `mapper`.
    pub fn new(mapper: ClockMapper) -> Self {
        Self {
            mapper,
            waiting: VecDeque::new(),
            stamped_at_arrival: 0,
            last_host_us: None,
            clock_us_per_s: REAL_TIME_US_PER_S,
        }
    }

    /// Says how many µs the device's clock counts per second of real time (its Info's
    /// `clock_us_per_s`; 1,000,000 unless told). The mapping starts again.
    pub fn set_clock_us_per_s(&mut self, clock_us_per_s: u32) {
        if clock_us_per_s != self.clock_us_per_s {
            self.clock_us_per_s = clock_us_per_s;
            self.mapper.clear();
        }
    }

    /// A device time in µs of real time (`None` for a device not paced to real time).
    fn real_time_us(&self, device_us: u64) -> Option<u64> {
        match self.clock_us_per_s {
            0 => None,
            REAL_TIME_US_PER_S => Some(device_us),
            rate => Some(
                (u128::from(device_us) * u128::from(REAL_TIME_US_PER_S) / u128::from(rate))
                    .try_into()
                    .unwrap_or(u64::MAX),
            ),
        }
    }

    /// Takes a sample frame's device time and arrival into the clock mapping.
    pub fn observe(&mut self, device_us: u64, arrival_us: u64) {
        if let Some(real_time_us) = self.real_time_us(device_us) {
            self.mapper.observe(real_time_us, arrival_us);
        }
    }

    /// Adds an item that happened at `device_us` on the device clock and arrived at
    /// `arrival_us`.
    pub fn push(&mut self, item: T, device_us: u64, arrival_us: u64) {
        self.waiting.push_back(Held {
            item,
            device_us,
            arrival_us,
        });
    }

    /// The items that can be stamped at host time `now_us`, in order: every one once the
    /// device has a clock estimate; before that, those that waited [`MAX_WAIT_US`]; every one
    /// at once for a device not paced to real time, which will never have an estimate.
    pub fn release(&mut self, now_us: u64) -> Vec<Stamped<T>> {
        let estimate = self.mapper.estimate();
        let may_get_an_estimate = self.clock_us_per_s != 0;
        let mut released = Vec::new();
        while let Some(held) = self.waiting.front() {
            if estimate.is_none()
                && may_get_an_estimate
                && now_us.saturating_sub(held.arrival_us) < MAX_WAIT_US
            {
                break;
            }
            let Some(held) = self.waiting.pop_front() else {
                break;
            };
            released.push(self.stamp(held, estimate.as_ref()));
        }
        released
    }

    /// Every item still waiting, stamped as well as possible now (the end of the stream).
    pub fn finish(&mut self) -> Vec<Stamped<T>> {
        let estimate = self.mapper.estimate();
        let held: Vec<Held<T>> = self.waiting.drain(..).collect();
        held.into_iter()
            .map(|held| self.stamp(held, estimate.as_ref()))
            .collect()
    }

    /// The clock mapping now.
    pub fn estimate(&self) -> Option<ClockEstimate> {
        self.mapper.estimate()
    }

    /// The mapper (its restarts and their reasons).
    pub fn mapper(&self) -> &ClockMapper {
        &self.mapper
    }

    /// Items stamped with their arrival for want of an estimate.
    pub fn stamped_at_arrival(&self) -> u64 {
        self.stamped_at_arrival
    }

    fn stamp(&mut self, held: Held<T>, estimate: Option<&ClockEstimate>) -> Stamped<T> {
        let mapped = estimate.zip(self.real_time_us(held.device_us));
        let (host_us, error_us) = match mapped {
            Some((estimate, real_time_us)) => (
                estimate.to_host_us(real_time_us).min(held.arrival_us),
                Some(estimate.uncertainty_at_us(real_time_us)),
            ),
            None => {
                self.stamped_at_arrival += 1;
                (held.arrival_us, None)
            }
        };
        // Never before the previous stamp: the shift joins the error bound.
        let (host_us, error_us) = match self.last_host_us {
            Some(last_us) if host_us < last_us => (
                last_us,
                error_us.map(|error_us| error_us.saturating_add(last_us - host_us)),
            ),
            _ => (host_us, error_us),
        };
        self.last_host_us = Some(host_us);
        Stamped {
            host_us,
            error_us,
            arrival_us: held.arrival_us,
            item: held.item,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device whose clock runs 100 ppm fast, 1 s ahead, frames arriving 300 µs to 2.3 ms
    /// after they were taken.
    fn arrival_of(device_us: u64, index: u64) -> (u64, u64) {
        let true_host_us = (device_us as f64 / 1.0001) as u64 + 1_000_000;
        (true_host_us, true_host_us + 300 + (index * 7919) % 2_000)
    }

    #[test]
    fn items_wait_for_the_estimate_then_go_out_in_order_never_after_arrival() {
        let mut stamper = Stamper::default();
        let mut released = Vec::new();
        for index in 0..400u64 {
            let device_us = 10_000 * index;
            let (true_host_us, arrival_us) = arrival_of(device_us, index);
            stamper.observe(device_us, arrival_us);
            stamper.push((index, true_host_us), device_us, arrival_us);
            released.extend(stamper.release(arrival_us));
        }
        released.extend(stamper.finish());
        assert_eq!(released.len(), 400, "nothing dropped");
        assert!(released
            .windows(2)
            .all(|pair| pair[0].item.0 + 1 == pair[1].item.0));
        assert_eq!(
            stamper.stamped_at_arrival(),
            0,
            "the estimate came within the wait"
        );
        for stamped in &released {
            assert!(stamped.host_us <= stamped.arrival_us);
            let error_us = stamped.error_us.expect("an error bound");
            let true_host_us = stamped.item.1;
            assert!(
                stamped.host_us.abs_diff(true_host_us) <= error_us,
                "{} vs {true_host_us} ± {error_us}",
                stamped.host_us
            );
        }
    }

    #[test]
    fn a_device_s_stamps_never_go_back_and_the_shift_joins_the_error() {
        let mut stamper = Stamper::default();
        // A clock estimate from exact frames, then an item whose device time maps before the
        // previous item's stamp (its device time is earlier: a reordered event).
        for index in 0..400u64 {
            let device_us = 10_000 * index;
            stamper.observe(device_us, device_us + 1_000_300);
        }
        stamper.push("later", 3_990_000, 5_000_000);
        stamper.push("earlier", 3_000_000, 5_000_001);
        let released = stamper.release(5_000_001);
        assert_eq!(released.len(), 2);
        assert!(released[1].host_us >= released[0].host_us);
        let shift = released[0].host_us - (3_000_000 + 1_000_000);
        assert!(released[1].error_us.unwrap() >= shift);
    }

    /// A device whose clock counts 20 times real time (a simulator at speed 20).
    fn stamped_at_speed_20(clock_us_per_s: u32) -> Vec<Stamped<u64>> {
        let mut stamper = Stamper::default();
        stamper.set_clock_us_per_s(clock_us_per_s);
        let mut released = Vec::new();
        // 5 s of host time at 100 sets/s: the mapper's first estimate needs 2 s.
        for index in 0..500u64 {
            let host_us = 10_000 * index;
            let device_us = host_us * 20;
            let arrival_us = host_us + 300 + (index * 7919) % 1_500;
            stamper.observe(device_us, arrival_us);
            stamper.push(host_us, device_us, arrival_us);
            released.extend(stamper.release(arrival_us));
        }
        released.extend(stamper.finish());
        released
    }

    #[test]
    fn a_clock_that_counts_faster_than_real_time_is_mapped_when_its_rate_is_known() {
        let known = stamped_at_speed_20(20_000_000);
        assert_eq!(known.len(), 500);
        assert!(known.iter().all(|stamped| stamped.error_us.is_some()));
        for stamped in &known {
            let error_us = stamped.error_us.unwrap_or(0);
            assert!(
                stamped.host_us.abs_diff(stamped.item) <= error_us,
                "{stamped:?}"
            );
        }
        // Taken as a real-time clock, its rate is an implausible drift: never mapped.
        let unknown = stamped_at_speed_20(1_000_000);
        assert!(unknown.iter().all(|stamped| stamped.error_us.is_none()));
        // Not paced at all: never mapped either.
        assert!(stamped_at_speed_20(0)
            .iter()
            .all(|stamped| stamped.error_us.is_none()));
    }

    #[test]
    fn a_device_not_paced_to_real_time_has_its_items_go_out_at_their_arrival_at_once() {
        let mut stamper = Stamper::default();
        stamper.set_clock_us_per_s(0);
        stamper.observe(5, 1_000);
        stamper.push("set", 5, 1_000);
        let released = stamper.release(1_000);
        assert_eq!(
            released.len(),
            1,
            "no wait for an estimate that cannot come"
        );
        assert_eq!((released[0].host_us, released[0].error_us), (1_000, None));
    }

    #[test]
    fn without_an_estimate_an_item_goes_out_at_its_arrival_after_the_wait() {
        let mut stamper = Stamper::default();
        stamper.push("event", 5, 1_000);
        assert!(stamper.release(1_000 + MAX_WAIT_US - 1).is_empty());
        let released = stamper.release(1_000 + MAX_WAIT_US);
        assert_eq!(
            released,
            [Stamped {
                item: "event",
                host_us: 1_000,
                arrival_us: 1_000,
                error_us: None
            }]
        );
        assert_eq!(stamper.stamped_at_arrival(), 1);
    }
}
