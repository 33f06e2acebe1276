//! Ctrl-C during long work done with the GIL released (a conversion of millions of rows): the
//! work calls [`SignalCheck::tick`] once per row, which every [`INTERVAL`] takes the GIL for a
//! moment and lets Python run its signal handlers; a `KeyboardInterrupt` (or any exception a
//! handler raises) ends the work.

use std::time::{Duration, Instant};

use pyo3::prelude::*;

/// How often the work looks for signals: Ctrl-C is answered within this and one row.
pub const INTERVAL: Duration = Duration::from_millis(20);

/// Rows between two looks at the clock.
const ROWS_PER_LOOK: u32 = 256;

/// Looks for signals now and then (see the module documentation).
#[derive(Debug)]
pub struct SignalCheck {
    last: Instant,
    rows: u32,
}

impl Default for SignalCheck {
    fn default() -> Self {
        Self::new()
    }
}

impl SignalCheck {
    /// A check whose first look is [`INTERVAL`] from now.
    pub fn new() -> Self {
        Self {
            last: Instant::now(),
            rows: 0,
        }
    }

    /// Counts a row; runs Python's signal handlers when [`INTERVAL`] has passed since the last
    /// time, and returns the exception one raised. Call it without holding the GIL.
    pub fn tick(&mut self) -> PyResult<()> {
        self.tick_rows(1)
    }

    /// [`tick`](Self::tick) for `rows` rows done together.
    pub fn tick_rows(&mut self, rows: u32) -> PyResult<()> {
        self.rows = self.rows.saturating_add(rows);
        if self.rows < ROWS_PER_LOOK {
            return Ok(());
        }
        self.rows = 0;
        if self.last.elapsed() < INTERVAL {
            return Ok(());
        }
        self.last = Instant::now();
        Python::with_gil(|py| py.check_signals())
    }
}
