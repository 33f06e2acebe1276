//! The simulated TI TCA9548A 8-channel I2C multiplexer (datasheet SCPS207) at register level.
//!
//! Protocol: one 8-bit control register and no register pointer. A write's data bytes go to
//! the control register; "there is no limit to the number of bytes sent, but the last byte sent
//! is what is in the register" (a write of the address alone changes nothing). A read returns
//! the control register; the datasheet shows a one-byte read only, so the assumption here is
//! that every further byte of a longer read repeats it.
//!
//! Register: bit n = channel n (SCn/SDn) enabled; several channels may be enabled at once,
//! 0 = all off. Power-on (and RESET, see `Simulation::reset_multiplexer`): 0.
//!
//! Behaviour, and the assumptions:
//! - **Switching.** The pass switches follow the control register from the STOP that ends the
//!   write: the register changes as the bytes arrive (a read in the same transaction sees the
//!   new value), the downstream buses connect or disconnect at the STOP. Every transaction on
//!   the simulated bus addresses one device, so the downstream devices see the new selection
//!   from the next transaction on.
//! - **Routing.** A device behind channel n is on the main bus only while switch n is closed;
//!   otherwise it never sees a transaction. The multiplexer itself and the devices upstream of
//!   it are always on the bus. Devices sharing an address on the connected wires all take the
//!   transaction (see the crate's topology documentation for the open-drain model).
//! - **Power-up.** The multiplexer acknowledges its address from power-on (the datasheet gives
//!   no start-up time that a driver would wait for).
//! - **Faults.** [`crate::Fault::MuxChannelStuck`] overrides a switch (the register still reads
//!   back what was written) and `Fault::Nack(Device::Tca9548a)` NACKs its address; see
//!   [`crate::fault`].

/// Number of downstream channels.
pub const CHANNEL_COUNT: usize = 8;

/// Lowest address of a TCA9548A (A2 = A1 = A0 = low).
pub const ADDRESS_FIRST: u8 = 0x70;

/// Highest address of a TCA9548A (A2 = A1 = A0 = high).
pub const ADDRESS_LAST: u8 = 0x77;

/// The multiplexer's state.
#[derive(Debug, Clone, Default)]
pub(crate) struct Tca9548aModel {
    /// The control register.
    control: u8,
    /// The pass switches as the register set them at the last STOP (bit n = channel n).
    switches: u8,
}

impl Tca9548aModel {
    /// Handles the data bytes of one write operation: the last one is kept.
    pub(crate) fn write(&mut self, bytes: &[u8]) {
        if let Some(&last) = bytes.last() {
            self.control = last;
        }
    }

    /// Fills the buffer of one read operation with the control register.
    pub(crate) fn read(&self, buffer: &mut [u8]) {
        buffer.fill(self.control);
    }

    /// The STOP that ends a transaction addressed to the multiplexer: the switches take the
    /// register's selection.
    pub(crate) fn stop(&mut self) {
        self.switches = self.control;
    }

    /// The control register, without a read's side effects (a read has none).
    pub(crate) fn control(&self) -> u8 {
        self.control
    }

    /// The channels whose switch is closed, before faults.
    pub(crate) fn switches(&self) -> u8 {
        self.switches
    }

    /// Power-on or RESET: every channel off.
    pub(crate) fn reset(&mut self) {
        self.control = 0;
        self.switches = 0;
    }
}
