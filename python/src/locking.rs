//! Locks that outlive a panic: a thread that panicked while holding one left plain data, still
//! usable, so a poisoned lock is taken as it is rather than failing every later call.

use std::sync::{Mutex, MutexGuard};

/// Locks a shared value; a panic while it was held left plain data, still usable.
pub fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}
