//! Whether the acquisition loop is alive: the watchdog's supervisor task wakes periodically and
//! feeds the watchdog only while the loop's heartbeat advances, so a stalled loop gets the MCU
//! reset. The decision is here, testable; the firmware owns the timer, the counter and the LED.

/// What the supervisor does at one wake-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SupervisorAction {
    /// The loop is alive (or not yet stalled for long): feed the watchdog.
    Feed,
    /// The loop has just been found stalled: stop feeding (say so once); the watchdog resets.
    GiveUp,
    /// Still stalled: keep not feeding.
    Wait,
}

/// Tracks the loop's heartbeat across the supervisor's wake-ups.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Supervisor {
    last_heartbeat: u32,
    stalled_periods: u32,
    max_stalled_periods: u32,
}

impl Supervisor {
    /// A supervisor that gives up after `max_stalled_periods` wake-ups without a heartbeat.
    pub const fn new(heartbeat: u32, max_stalled_periods: u32) -> Self {
        Self {
            last_heartbeat: heartbeat,
            stalled_periods: 0,
            max_stalled_periods,
        }
    }

    /// One wake-up with the heartbeat counter's current value.
    pub fn wake(&mut self, heartbeat: u32) -> SupervisorAction {
        if heartbeat != self.last_heartbeat {
            self.last_heartbeat = heartbeat;
            self.stalled_periods = 0;
        } else {
            self.stalled_periods = self.stalled_periods.saturating_add(1);
        }
        if self.stalled_periods < self.max_stalled_periods {
            SupervisorAction::Feed
        } else if self.stalled_periods == self.max_stalled_periods {
            SupervisorAction::GiveUp
        } else {
            SupervisorAction::Wait
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stalled_loop_stops_the_feeding_after_the_limit_and_a_live_one_never_does() {
        let mut supervisor = Supervisor::new(0, 3);
        for heartbeat in 1..100 {
            assert_eq!(supervisor.wake(heartbeat), SupervisorAction::Feed);
        }
        let actions: [SupervisorAction; 5] = core::array::from_fn(|_| supervisor.wake(99));
        assert_eq!(
            actions,
            [
                SupervisorAction::Feed,
                SupervisorAction::Feed,
                SupervisorAction::GiveUp,
                SupervisorAction::Wait,
                SupervisorAction::Wait
            ]
        );
        // The counter wraps: a changed value is a heartbeat.
        let mut wrapping = Supervisor::new(u32::MAX, 2);
        assert_eq!(wrapping.wake(0), SupervisorAction::Feed);
    }
}
