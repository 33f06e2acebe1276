//! The panic handler: logs that a panic happened and stops in HardFault, where `probe-rs run`
//! prints the backtrace (function, file and line, from the ELF's debug information) and exits.
//!
//! It deliberately does not read the panic's message or location: as soon as the handler reads
//! either, every panic site of every dependency keeps its message formatting and its source
//! path in flash, about 16 KiB (measured), a sixth of the flash budget. The firmware itself never
//! panics (clippy denies unwrap, expect and panic); this is for bugs and for the run-time checks
//! inside the HAL.

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};

#[panic_handler]
fn panic(_info: &PanicInfo) -> ! {
    static PANICKED: AtomicBool = AtomicBool::new(false);
    cortex_m::interrupt::disable();
    // A panic while logging the first one must not recurse.
    if !PANICKED.swap(true, Ordering::Relaxed) {
        defmt::error!("panicked; the backtrace below shows where");
    }
    // UsageFault is disabled (its reset state), so the undefined instruction escalates to HardFault.
    cortex_m::asm::udf()
}
