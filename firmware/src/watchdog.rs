//! The independent watchdog: it resets the MCU when the acquisition loop stops making progress.
//!
//! [`supervise`] feeds it only while the loop's [`heartbeat`] advances; the calibration flash
//! feeds it before every sector erase, because an erase stalls the whole CPU for up to 2 s.
//! Also reports why the MCU last reset.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};
use device::{ResetKind, Supervisor, SupervisorAction};

use defmt::{error, info, warn};
use embassy_stm32::gpio::Output;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::{Duration, Timer};

/// F411 datasheet: a 128 KiB sector erase at x32 parallelism takes 1 s typical, 2 s max, with the
/// CPU stalled. embassy scales the IWDG from a nominal 32 kHz LSI, but the LSI may run at up to
/// 47 kHz, so 4 s nominal is at least 4 s * 32 / 47 = 2.7 s real: more than one erase.
const WATCHDOG_TIMEOUT_US: u32 = 4_000_000;

/// How often the supervisor looks at the heartbeat (and toggles the LED).
const SUPERVISOR_PERIOD: Duration = Duration::from_millis(250);

/// The watchdog is starved after this many supervisor periods without a heartbeat (2 s): far
/// above the longest cycle with every I2C transfer timing out, and above the supervisor wake-ups
/// a calibration save can span (each erase stalls everything, so it counts as one period).
const MAX_STALLED_SUPERVISOR_PERIODS: u32 = 8;

static WATCHDOG: Mutex<
    CriticalSectionRawMutex,
    RefCell<Option<IndependentWatchdog<'static, IWDG>>>,
> = Mutex::new(RefCell::new(None));
static HEARTBEAT: AtomicU32 = AtomicU32::new(0);

/// Logs why the MCU reset, then clears the reset flags.
pub fn report_reset_cause() -> ResetKind {
    let reset_flags = embassy_stm32::pac::RCC.csr().read();
    // A power-on or brown-out clears RAM; every other reset leaves the pad (and the retained
    // record) as they were.
    let kind = if reset_flags.porrstf() || reset_flags.borrstf() {
        ResetKind::PowerOn
    } else {
        ResetKind::McuOnly
    };
    if reset_flags.wdgrstf() {
        warn!("reset by the independent watchdog");
    } else if reset_flags.sftrstf() {
        info!("software reset");
    } else if reset_flags.porrstf() {
        info!("power-on reset");
    } else if reset_flags.padrstf() {
        info!("reset pin");
    }
    embassy_stm32::pac::RCC.csr().modify(|w| w.set_rmvf(true));
    kind
}

/// Starts the watchdog; from now on it must be fed.
pub fn start(iwdg: Peri<'static, IWDG>) {
    // Stop the IWDG while a debugger halts the core; otherwise every breakpoint ends in a reset.
    embassy_stm32::pac::DBGMCU
        .apb1fzr()
        .modify(|w| w.set_iwdg(true));
    let mut watchdog = IndependentWatchdog::new(iwdg, WATCHDOG_TIMEOUT_US);
    watchdog.unleash();
    WATCHDOG.lock(|cell| {
        if let Ok(mut slot) = cell.try_borrow_mut() {
            *slot = Some(watchdog);
        }
    });
    info!(
        "watchdog started, {} ms nominal",
        WATCHDOG_TIMEOUT_US / 1000
    );
}

/// Feeds the watchdog.
pub fn feed() {
    WATCHDOG.lock(|cell| {
        if let Ok(mut slot) = cell.try_borrow_mut() {
            if let Some(watchdog) = slot.as_mut() {
                watchdog.pet();
            }
        }
    });
}

/// Marks one completed pass of the acquisition loop.
pub fn heartbeat() {
    HEARTBEAT.fetch_add(1, Ordering::Relaxed);
}

/// Feeds the watchdog while the heartbeat advances and blinks the LED meanwhile; never returns.
pub async fn supervise(mut led: Output<'static>) -> ! {
    let mut supervisor = Supervisor::new(
        HEARTBEAT.load(Ordering::Relaxed),
        MAX_STALLED_SUPERVISOR_PERIODS,
    );
    loop {
        // Timer, not Ticker: after a CPU stall (flash erase) a Ticker fires the missed periods
        // back to back, which would count as a stall; each wake-up here is one real chance to run.
        Timer::after(SUPERVISOR_PERIOD).await;
        match supervisor.wake(HEARTBEAT.load(Ordering::Relaxed)) {
            SupervisorAction::Feed => {
                feed();
                led.toggle();
            }
            SupervisorAction::GiveUp => {
                error!("acquisition loop stalled; letting the watchdog reset the MCU")
            }
            SupervisorAction::Wait => {}
        }
    }
}
