//! The record that keeps the baselines and the tier across an MCU-only reset, in RAM that the
//! start-up code leaves alone (cortex-m-rt's `.uninit` section). After a power-on it holds noise,
//! which the record's magic and CRC reject (see `device::RetainedState`).

use core::mem::MaybeUninit;
use core::ptr::{addr_of, addr_of_mut};

use device::{RetainedState, RETAINED_LEN};

// The section is cortex-m-rt's `.uninit` (NOLOAD, not zeroed by the start-up code): placing
// the record there is the whole point of this module.
#[allow(unsafe_code)]
#[link_section = ".uninit.taxel_retained"]
static mut RETAINED: MaybeUninit<[u8; RETAINED_LEN]> = MaybeUninit::uninit();

/// The record left by the firmware before the reset, if it is intact.
#[allow(unsafe_code)]
pub fn read() -> Option<RetainedState> {
    let mut bytes = [0u8; RETAINED_LEN];
    let base = addr_of!(RETAINED).cast::<u8>();
    for (index, byte) in bytes.iter_mut().enumerate() {
        // SAFETY: `base + index` lies inside the static (index < RETAINED_LEN); only the
        // acquisition task touches it, on the one core, and no interrupt handler does. The RAM
        // always holds some byte pattern (after a power-on, noise), so a volatile byte read is
        // defined for the hardware and the record's CRC judges it.
        *byte = unsafe { core::ptr::read_volatile(base.add(index)) };
    }
    RetainedState::decode(&bytes)
}

/// Replaces the record where it differs from `record` (called after every sample set; it
/// changes after a tare or a tier change, or every set while baselines are tracked).
#[allow(unsafe_code)]
pub fn write_if_changed(record: &[u8; RETAINED_LEN]) {
    let base = addr_of_mut!(RETAINED).cast::<u8>();
    for (index, byte) in record.iter().enumerate() {
        // SAFETY: as in `read`: in bounds, one writer, no concurrent reader.
        unsafe {
            let address = base.add(index);
            if core::ptr::read_volatile(address) != *byte {
                core::ptr::write_volatile(address, *byte);
            }
        }
    }
}
