//! Simulated time: [`SimDelay`] (`embedded_hal_async::delay::DelayNs`) advances the
//! simulation's clock instead of sleeping, and [`Pacing`] optionally ties simulated time to
//! wall-clock time for a live demo.
//!
//! Every advance of the clock (a delay, a bus transaction's duration,
//! `Simulation::advance_us`) first completes, in time order, every device event due up to the
//! new time, then paces. Pacing happens after the simulation's lock is released: a
//! [`Pacing::RealTime`] sleep (`std::thread::sleep`, fine under a simple `block_on` executor)
//! or a [`Pacing::Callback`], which may itself call into the simulation. A real-time sleep ends
//! early when the pacing changes (`Simulation::set_pacing`), so that a slow simulation can be
//! stopped at once: setting [`Pacing::Off`] wakes every sleeper.

use std::fmt;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use embedded_hal_async::delay::DelayNs;

use crate::simulation::{lock, State};

/// A function called with the simulated time (ns) after every advance of the clock.
pub type PacingCallback = Arc<dyn Fn(u64) + Send + Sync>;

/// How simulated time relates to wall-clock time.
#[derive(Clone, Default)]
pub enum Pacing {
    /// Simulated time runs as fast as the host computes (the default; what tests use).
    #[default]
    Off,
    /// Sleeps so that simulated time runs `speed` times as fast as wall-clock time (1.0 = real
    /// time), measured from the moment pacing was set. Never sleeps to catch up backwards: if
    /// the host falls behind, simulated time simply runs late.
    RealTime {
        /// Simulated seconds per wall-clock second (finite, > 0).
        speed: f64,
    },
    /// Calls the function with the new simulated time after every advance (for an external
    /// scheduler, a progress display or a test probe).
    Callback(PacingCallback),
}

impl fmt::Debug for Pacing {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pacing::Off => formatter.write_str("Off"),
            Pacing::RealTime { speed } => formatter
                .debug_struct("RealTime")
                .field("speed", speed)
                .finish(),
            Pacing::Callback(_) => formatter.write_str("Callback(..)"),
        }
    }
}

/// A [`Pacing::RealTime`] speed that is not finite and positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvalidPacing {
    /// The refused speed.
    pub speed: f64,
}

impl fmt::Display for InvalidPacing {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            formatter,
            "real-time pacing speed {} is not finite and positive",
            self.speed
        )
    }
}

impl std::error::Error for InvalidPacing {}

/// What a real-time sleep waits on besides its deadline: the number of pacing changes so far.
#[derive(Debug, Default)]
pub(crate) struct PacingChanges {
    count: Mutex<u64>,
    changed: Condvar,
}

impl PacingChanges {
    fn count(&self) -> u64 {
        *self
            .count
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn announce(&self) {
        *self
            .count
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) += 1;
        self.changed.notify_all();
    }

    /// Sleeps until `deadline`, or until the pacing changes after it read `seen`.
    fn sleep_until(&self, deadline: Instant, seen: u64) {
        let mut count = self
            .count
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        while *count == seen {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return;
            }
            count = self
                .changed
                .wait_timeout(count, remaining)
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .0;
        }
    }
}

/// The pacing in force and its anchor.
#[derive(Debug, Clone)]
pub(crate) struct Pacer {
    pacing: Pacing,
    wall_anchor: Instant,
    simulated_anchor_ns: u64,
    changes: Arc<PacingChanges>,
}

impl Pacer {
    pub(crate) fn new() -> Self {
        Self {
            pacing: Pacing::Off,
            wall_anchor: Instant::now(),
            simulated_anchor_ns: 0,
            changes: Arc::default(),
        }
    }

    pub(crate) fn set(&mut self, pacing: Pacing, now_ns: u64) -> Result<(), InvalidPacing> {
        if let Pacing::RealTime { speed } = pacing {
            if !(speed.is_finite() && speed > 0.0) {
                return Err(InvalidPacing { speed });
            }
        }
        self.pacing = pacing;
        self.wall_anchor = Instant::now();
        self.simulated_anchor_ns = now_ns;
        self.changes.announce();
        Ok(())
    }

    /// What to do, once the lock is released, now that the clock reads `now_ns`.
    pub(crate) fn action(&self, now_ns: u64) -> PacingAction {
        match &self.pacing {
            Pacing::Off => PacingAction::Nothing,
            Pacing::RealTime { speed } => {
                let simulated_s = now_ns.saturating_sub(self.simulated_anchor_ns) as f64 * 1e-9;
                Duration::try_from_secs_f64(simulated_s / speed)
                    .ok()
                    .and_then(|wall| self.wall_anchor.checked_add(wall))
                    .map_or(PacingAction::Nothing, |deadline| PacingAction::SleepUntil {
                        deadline,
                        changes: Arc::clone(&self.changes),
                        seen: self.changes.count(),
                    })
            }
            Pacing::Callback(callback) => PacingAction::Call(Arc::clone(callback), now_ns),
        }
    }
}

/// Pacing work to do outside the lock.
pub(crate) enum PacingAction {
    Nothing,
    SleepUntil {
        deadline: Instant,
        changes: Arc<PacingChanges>,
        seen: u64,
    },
    Call(PacingCallback, u64),
}

impl PacingAction {
    pub(crate) fn run(self) {
        match self {
            PacingAction::Nothing => {}
            PacingAction::SleepUntil {
                deadline,
                changes,
                seen,
            } => changes.sleep_until(deadline, seen),
            PacingAction::Call(callback, now_ns) => callback(now_ns),
        }
    }
}

/// `DelayNs` on simulated time: every delay advances the simulation's clock by exactly its
/// duration (then paces). Clones share the clock.
#[derive(Clone)]
pub struct SimDelay {
    pub(crate) shared: Arc<Mutex<State>>,
}

impl fmt::Debug for SimDelay {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str("SimDelay")
    }
}

impl SimDelay {
    fn advance_ns(&self, duration_ns: u64) {
        let action = {
            let mut state = lock(&self.shared);
            state.advance_by_ns(duration_ns);
            state.pacing_action()
        };
        action.run();
    }
}

impl DelayNs for SimDelay {
    async fn delay_ns(&mut self, ns: u32) {
        self.advance_ns(ns as u64);
    }

    async fn delay_us(&mut self, us: u32) {
        self.advance_ns(us as u64 * 1_000);
    }

    async fn delay_ms(&mut self, ms: u32) {
        self.advance_ns(ms as u64 * 1_000_000);
    }
}
