//! The simulated I2C bus: `embedded_hal_async::i2c::I2c` dispatching by 7-bit address to the
//! devices on the wires: by default the FDC1004 (0x50) and the TMP117 (0x48); with a
//! multiplexer, the multiplexer, the shared TMP117 and the devices behind its connected channels
//! (see `Topology`). An address where no device answers (none there, a device still powering
//! up, an unplugged pad, an injected NACK) fails with `NoAcknowledge(Address)`.
//!
//! A transaction takes bus time when a bus frequency is configured (default 400 kHz): a start
//! or repeated start and 9 bits per byte (address included), plus a stop, so that a register
//! read (`write_read` of 1 + 2 bytes) takes 120 µs. The devices see the transaction at its
//! start; the clock advances by its duration afterwards.

use std::fmt;
use std::sync::{Arc, Mutex};

use embedded_hal_async::i2c::{
    Error, ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation, SevenBitAddress,
};

use crate::simulation::{lock, State};

/// 7-bit address of the FDC1004.
pub const FDC1004_ADDRESS: u8 = 0x50;
/// 7-bit address of the TMP117 (ADD0 to ground).
pub const TMP117_ADDRESS: u8 = 0x48;

/// A failed simulated transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimI2cError {
    kind: ErrorKind,
}

impl SimI2cError {
    /// The address was not acknowledged.
    pub const ADDRESS_NACK: SimI2cError = SimI2cError {
        kind: ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address),
    };
}

impl fmt::Display for SimI2cError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(formatter, "simulated I2C error: {}", self.kind)
    }
}

impl std::error::Error for SimI2cError {}

impl Error for SimI2cError {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

/// A handle to the simulated bus; clones share it (one per driver, as on a shared bus).
#[derive(Clone)]
pub struct SimI2c {
    pub(crate) shared: Arc<Mutex<State>>,
}

impl fmt::Debug for SimI2c {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str("SimI2c")
    }
}

impl ErrorType for SimI2c {
    type Error = SimI2cError;
}

impl I2c<SevenBitAddress> for SimI2c {
    async fn transaction(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let (result, action) = {
            let mut state = lock(&self.shared);
            let result = state.transaction(address, operations);
            (result, state.pacing_action())
        };
        action.run();
        result
    }
}

/// Bits on the wire for a transaction: per operation a (repeated) start, the address byte and
/// the data bytes, 9 bits each byte with its acknowledge; then a stop. A NACKed transaction
/// stops after its address byte.
pub(crate) fn transaction_bits(operations: &[Operation<'_>], acknowledged: bool) -> u64 {
    const START_BITS: u64 = 1;
    const STOP_BITS: u64 = 1;
    const BITS_PER_BYTE: u64 = 9;
    if !acknowledged || operations.is_empty() {
        return START_BITS + BITS_PER_BYTE + STOP_BITS;
    }
    let data_bytes: u64 = operations
        .iter()
        .map(|operation| match operation {
            Operation::Read(buffer) => buffer.len() as u64,
            Operation::Write(bytes) => bytes.len() as u64,
        })
        .sum();
    operations.len() as u64 * (START_BITS + BITS_PER_BYTE) + data_bytes * BITS_PER_BYTE + STOP_BITS
}
