//! [`TimeoutI2c`]: an I2C bus whose every transaction is bounded in time.
//!
//! embassy-stm32's async I2C on the F4 never times out by itself: a slave holding SCL low would
//! hang the acquisition loop forever. The wrapper races each transaction against a delay; a
//! transaction that loses is dropped (cancelled) and reported as [`TimeoutI2cError::Timeout`].
//! A cancelled transfer sends no STOP: while a slave keeps holding the bus, later transactions
//! time out too (the acquisition loop counts them as I2C errors and keeps running) until it lets
//! go.

use core::future::Future;

use embassy_futures::select::{select, Either};
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::{Error, ErrorKind, ErrorType, I2c, Operation};

/// An I2C bus whose transactions fail with [`TimeoutI2cError::Timeout`] after a fixed time.
pub struct TimeoutI2c<B, D> {
    bus: B,
    delay: D,
    timeout_us: u32,
}

impl<B, D> TimeoutI2c<B, D> {
    /// Wraps `bus`; every transaction gets at most `timeout_us`, measured with `delay`.
    pub fn new(bus: B, delay: D, timeout_us: u32) -> Self {
        Self {
            bus,
            delay,
            timeout_us,
        }
    }

    /// The wrapped bus (tests, diagnostics).
    pub fn inner_mut(&mut self) -> &mut B {
        &mut self.bus
    }
}

/// A [`TimeoutI2c`] transaction failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TimeoutI2cError<E> {
    /// The bus reported an error.
    Bus(E),
    /// The transaction did not finish in time.
    Timeout,
}

impl<E: Error> Error for TimeoutI2cError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Bus(bus_error) => bus_error.kind(),
            Self::Timeout => ErrorKind::Other,
        }
    }
}

impl<B: ErrorType, D> ErrorType for TimeoutI2c<B, D> {
    type Error = TimeoutI2cError<B::Error>;
}

impl<B: I2c, D: DelayNs> I2c for TimeoutI2c<B, D> {
    async fn read(&mut self, address: u8, read: &mut [u8]) -> Result<(), Self::Error> {
        bounded(
            self.bus.read(address, read),
            self.delay.delay_us(self.timeout_us),
        )
        .await
    }

    async fn write(&mut self, address: u8, write: &[u8]) -> Result<(), Self::Error> {
        bounded(
            self.bus.write(address, write),
            self.delay.delay_us(self.timeout_us),
        )
        .await
    }

    async fn write_read(
        &mut self,
        address: u8,
        write: &[u8],
        read: &mut [u8],
    ) -> Result<(), Self::Error> {
        bounded(
            self.bus.write_read(address, write, read),
            self.delay.delay_us(self.timeout_us),
        )
        .await
    }

    async fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        bounded(
            self.bus.transaction(address, operations),
            self.delay.delay_us(self.timeout_us),
        )
        .await
    }
}

async fn bounded<E>(
    transfer: impl Future<Output = Result<(), E>>,
    deadline: impl Future<Output = ()>,
) -> Result<(), TimeoutI2cError<E>> {
    match select(transfer, deadline).await {
        Either::First(result) => result.map_err(TimeoutI2cError::Bus),
        Either::Second(()) => Err(TimeoutI2cError::Timeout),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::future::{pending, poll_fn};
    use core::task::Poll;
    use embassy_futures::block_on;

    /// A bus that answers at once, or never (a slave holding SCL low).
    struct Bus {
        hangs: bool,
        nacks: bool,
    }

    impl ErrorType for Bus {
        type Error = ErrorKind;
    }

    impl I2c for Bus {
        async fn transaction(
            &mut self,
            _address: u8,
            operations: &mut [Operation<'_>],
        ) -> Result<(), Self::Error> {
            if self.hangs {
                pending::<()>().await;
            }
            if self.nacks {
                return Err(ErrorKind::NoAcknowledge(
                    embedded_hal_async::i2c::NoAcknowledgeSource::Address,
                ));
            }
            for operation in operations {
                if let Operation::Read(read) = operation {
                    read.fill(0x5A);
                }
            }
            Ok(())
        }
    }

    /// A delay that expires after being polled `polls` times, counting the microseconds asked.
    struct Delay {
        polls: u32,
        asked_us: u32,
    }

    impl DelayNs for Delay {
        async fn delay_ns(&mut self, ns: u32) {
            self.asked_us = ns / 1000;
            let mut remaining = self.polls;
            poll_fn(|context| {
                if remaining == 0 {
                    Poll::Ready(())
                } else {
                    remaining -= 1;
                    context.waker().wake_by_ref();
                    Poll::Pending
                }
            })
            .await;
        }
    }

    fn bus(hangs: bool, nacks: bool) -> TimeoutI2c<Bus, Delay> {
        TimeoutI2c::new(
            Bus { hangs, nacks },
            Delay {
                polls: 3,
                asked_us: 0,
            },
            20_000,
        )
    }

    #[test]
    fn a_transaction_that_finishes_in_time_is_passed_through() {
        let mut healthy = bus(false, false);
        let mut read = [0u8; 2];
        let result = block_on(healthy.write_read(0x50, &[0xFE], &mut read));
        assert_eq!(result, Ok(()));
        assert_eq!(read, [0x5A; 2]);
    }

    #[test]
    fn a_bus_error_keeps_its_kind() {
        let mut nacking = bus(false, true);
        let error = block_on(nacking.write(0x50, &[0x0C, 0, 0]));
        assert!(matches!(error, Err(TimeoutI2cError::Bus(_))));
        assert!(matches!(
            error.map_err(|error| error.kind()),
            Err(ErrorKind::NoAcknowledge(_))
        ));
    }

    #[test]
    fn a_hung_bus_times_out_after_the_configured_time_on_every_operation() {
        let mut hung = bus(true, false);
        let mut read = [0u8; 2];
        assert_eq!(
            block_on(hung.read(0x48, &mut read)),
            Err(TimeoutI2cError::Timeout)
        );
        assert_eq!(
            block_on(hung.write(0x48, &[1])),
            Err(TimeoutI2cError::Timeout)
        );
        assert_eq!(
            block_on(hung.write_read(0x48, &[0], &mut read)),
            Err(TimeoutI2cError::Timeout)
        );
        assert_eq!(
            block_on(hung.transaction(0x48, &mut [Operation::Write(&[0])])),
            Err(TimeoutI2cError::Timeout)
        );
        assert_eq!(hung.delay.asked_us, 20_000);
        assert_eq!(
            TimeoutI2cError::<ErrorKind>::Timeout.kind(),
            ErrorKind::Other
        );
    }
}
