//! Routing a transaction over the simulated bus: which devices are on the wires at the
//! address, which of them answer, and what the open-drain bus makes of several answers.
//!
//! - **On the wires.** The multiplexer and the devices upstream of it (the shared TMP117; in
//!   the single-pad setup the pad's FDC1004 and TMP117) always are; a device behind channel n
//!   only while switch n is closed (the control register as of the last STOP, overridden by
//!   [`Fault::MuxChannelStuck`]).
//! - **Answering.** A device on the wires at the address acknowledges unless its pad is
//!   unplugged, it is still powering up, or an injected [`Fault::Nack`] refuses it. When
//!   nobody acknowledges, the transaction fails with a NACK on the address.
//! - **Several answers.** I2C is open-drain: any device pulling a line low wins. All devices
//!   that acknowledge take every write; on a read each drives its own bytes and the master
//!   sees their bitwise AND. Such a transaction counts in [`Counters::address_conflicts`].
//!   (Arbitration between the slaves is not modelled: each device goes on as if it alone had
//!   sent its bytes.)
//! - **Time.** Bus time is as for a single device (see [`crate::bus`]), whatever answered.

use embedded_hal_async::i2c::Operation;

use crate::bus::{transaction_bits, SimI2cError, FDC1004_ADDRESS, TMP117_ADDRESS};
use crate::config::MAX_PADS;
use crate::fault::{Device, Fault, FaultTarget};
use crate::simulation::{DeviceRef, ModelMut, State};
use crate::tca9548a::CHANNEL_COUNT;

/// Most devices one address can reach: the multiplexer or the shared TMP117, and one device
/// per pad.
const MAX_ON_ADDRESS: usize = 2 + MAX_PADS;

/// The devices on the wires at one address, without allocating per transaction.
#[derive(Debug, Clone, Copy)]
struct DeviceSet {
    devices: [DeviceRef; MAX_ON_ADDRESS],
    len: usize,
}

impl DeviceSet {
    fn new() -> Self {
        Self {
            devices: [DeviceRef::Multiplexer; MAX_ON_ADDRESS],
            len: 0,
        }
    }

    fn push(&mut self, device: DeviceRef) {
        if let Some(slot) = self.devices.get_mut(self.len) {
            *slot = device;
            self.len += 1;
        }
    }

    fn as_slice(&self) -> &[DeviceRef] {
        self.devices.get(..self.len).unwrap_or(&[])
    }
}

/// Why a device on the wires did not acknowledge, most telling first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Silence {
    PoweringUp,
    Injected,
    Unplugged,
}

impl State {
    /// One transaction at the current time; the clock then advances by its bus time.
    pub(crate) fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), SimI2cError> {
        self.counters.transactions += 1;
        let now_ns = self.now_ns;
        self.sync_plugs(now_ns);
        let connected = self.connected(address, now_ns / 1_000);
        let connected = connected.as_slice();
        self.count_connected(connected);
        let mut responders = DeviceSet::new();
        let mut silence: Option<Silence> = None;
        for &device in connected {
            match self.answer(device, now_ns) {
                Ok(()) => responders.push(device),
                Err(reason) => silence = Some(silence.map_or(reason, |other| other.min(reason))),
            }
        }
        let responders = responders.as_slice();
        let result = if responders.is_empty() {
            let counter = match silence {
                None => &mut self.counters.nacks_unknown_address,
                Some(Silence::PoweringUp) => &mut self.counters.nacks_powering_up,
                Some(Silence::Injected) => &mut self.counters.nacks_injected,
                Some(Silence::Unplugged) => &mut self.counters.nacks_unplugged,
            };
            *counter += 1;
            self.counters.nacks += 1;
            for pad in connected.iter().filter_map(|&device| pad_of(device)) {
                if let Some(counters) = self.counters.pads.get_mut(pad) {
                    counters.nacks += 1;
                }
            }
            Err(SimI2cError::ADDRESS_NACK)
        } else {
            if responders.len() > 1 {
                self.counters.address_conflicts += 1;
            }
            self.run_operations(responders, operations, now_ns);
            Ok(())
        };
        // A pad whose last counted unplugged transaction this was comes back now.
        self.sync_plugs(now_ns);
        if let Some(frequency_hz) = self.bus_frequency_hz {
            let bits = transaction_bits(operations, result.is_ok());
            self.advance_by_ns((bits * 1_000_000_000).div_ceil(frequency_hz as u64));
        }
        result
    }

    /// The channels whose downstream bus is connected for a transaction at `now_us`; consumes
    /// one count of each [`Window::Next`](crate::Window::Next) stuck-channel fault in force.
    fn closed_channels(&mut self, now_us: u64) -> u8 {
        let Some(multiplexer) = &self.multiplexer else {
            return 0;
        };
        let mut closed = multiplexer.model.switches();
        for channel in 0..CHANNEL_COUNT as u8 {
            let stuck = self
                .faults
                .take(now_us, FaultTarget::Upstream, |fault| match fault {
                    Fault::MuxChannelStuck {
                        channel: stuck_channel,
                        closed,
                    } if *stuck_channel == channel => Some(*closed),
                    _ => None,
                });
            match stuck {
                Some(true) => closed |= 1 << channel,
                Some(false) => closed &= !(1 << channel),
                None => {}
            }
        }
        closed
    }

    /// Every device on the wires at `address` (answering or not).
    fn connected(&mut self, address: u8, now_us: u64) -> DeviceSet {
        let closed = self.closed_channels(now_us);
        let mut devices = DeviceSet::new();
        if self
            .multiplexer
            .as_ref()
            .is_some_and(|multiplexer| multiplexer.address == address)
        {
            devices.push(DeviceRef::Multiplexer);
        }
        if self
            .shared_tmp117
            .as_ref()
            .is_some_and(|shared| shared.address == address)
        {
            devices.push(DeviceRef::SharedTmp117);
        }
        for (index, pad) in self.pads.iter().enumerate() {
            let on_wires = pad
                .channel
                .is_none_or(|channel| closed & (1u8 << channel) != 0);
            if !on_wires {
                continue;
            }
            if address == FDC1004_ADDRESS {
                devices.push(DeviceRef::PadFdc1004(index));
            }
            if address == TMP117_ADDRESS && pad.tmp117.is_some() {
                devices.push(DeviceRef::PadTmp117(index));
            }
        }
        devices
    }

    fn count_connected(&mut self, connected: &[DeviceRef]) {
        let (mut fdc1004, mut tmp117, mut multiplexer) = (false, false, false);
        for &device in connected {
            match device {
                DeviceRef::PadFdc1004(_) => fdc1004 = true,
                DeviceRef::PadTmp117(_) | DeviceRef::SharedTmp117 => tmp117 = true,
                DeviceRef::Multiplexer => multiplexer = true,
            }
            if let Some(pad) = pad_of(device).and_then(|pad| self.counters.pads.get_mut(pad)) {
                pad.transactions += 1;
            }
        }
        let counters = &mut self.counters;
        counters.fdc1004_transactions += u64::from(fdc1004);
        counters.tmp117_transactions += u64::from(tmp117);
        counters.multiplexer_transactions += u64::from(multiplexer);
    }

    /// Whether `device` acknowledges a transaction starting at `now_ns`; consumes the fault
    /// counts the transaction uses up.
    fn answer(&mut self, device: DeviceRef, now_ns: u64) -> Result<(), Silence> {
        let now_us = now_ns / 1_000;
        let (target, kind, answers) = match device {
            DeviceRef::PadFdc1004(index) | DeviceRef::PadTmp117(index) => {
                let Some(pad) = self.pad(index) else {
                    return Err(Silence::Unplugged);
                };
                let target = FaultTarget::Pad(index);
                if pad.unplugged {
                    // Counts one event of a `Window::Next` unplug.
                    self.faults.take(now_us, target, |fault| {
                        matches!(fault, Fault::Unplugged).then_some(())
                    });
                    return Err(Silence::Unplugged);
                }
                match device {
                    DeviceRef::PadFdc1004(_) => {
                        (target, Device::Fdc1004, pad.fdc1004.answers(now_ns))
                    }
                    _ => (
                        target,
                        Device::Tmp117,
                        pad.tmp117
                            .as_ref()
                            .is_some_and(|tmp117| tmp117.answers(now_ns)),
                    ),
                }
            }
            DeviceRef::SharedTmp117 => (
                FaultTarget::Upstream,
                Device::Tmp117,
                self.shared_tmp117
                    .as_ref()
                    .is_some_and(|shared| shared.model.answers(now_ns)),
            ),
            DeviceRef::Multiplexer => (FaultTarget::Upstream, Device::Tca9548a, true),
        };
        if !answers {
            return Err(Silence::PoweringUp);
        }
        let injected = self
            .faults
            .take(now_us, target, |fault| {
                (*fault == Fault::Nack(kind)).then_some(())
            })
            .is_some();
        if injected {
            Err(Silence::Injected)
        } else {
            Ok(())
        }
    }

    fn run_operations(
        &mut self,
        responders: &[DeviceRef],
        operations: &mut [Operation<'_>],
        now_ns: u64,
    ) {
        for operation in operations.iter_mut() {
            match operation {
                Operation::Write(bytes) => {
                    for &device in responders {
                        self.device_write(device, bytes, now_ns);
                    }
                }
                Operation::Read(buffer) => match responders {
                    [device] => self.device_read(*device, buffer, now_ns),
                    _ => {
                        // Open drain: a 0 from any device wins.
                        buffer.fill(0xFF);
                        let mut own = vec![0u8; buffer.len()];
                        for &device in responders {
                            self.device_read(device, &mut own, now_ns);
                            for (wire, driven) in buffer.iter_mut().zip(&own) {
                                *wire &= driven;
                            }
                        }
                    }
                },
            }
        }
        if responders.contains(&DeviceRef::Multiplexer) {
            if let Some(multiplexer) = self.multiplexer.as_mut() {
                multiplexer.model.stop();
            }
        }
    }

    fn device_write(&mut self, device: DeviceRef, bytes: &[u8], now_ns: u64) {
        if device == DeviceRef::Multiplexer {
            if let Some(multiplexer) = self.multiplexer.as_mut() {
                multiplexer.model.write(bytes);
            }
            return;
        }
        self.with_model(device, |model, environment| match model {
            ModelMut::Fdc1004(fdc1004) => fdc1004.write(bytes, now_ns, environment),
            ModelMut::Tmp117(tmp117) => tmp117.write(bytes, now_ns, environment),
        });
    }

    fn device_read(&mut self, device: DeviceRef, buffer: &mut [u8], now_ns: u64) {
        if device == DeviceRef::Multiplexer {
            if let Some(multiplexer) = self.multiplexer.as_ref() {
                multiplexer.model.read(buffer);
            }
            return;
        }
        self.with_model(device, |model, environment| match model {
            ModelMut::Fdc1004(fdc1004) => fdc1004.read(buffer, now_ns, environment),
            ModelMut::Tmp117(tmp117) => tmp117.read(buffer, now_ns, environment),
        });
    }
}

/// The pad a device belongs to.
fn pad_of(device: DeviceRef) -> Option<usize> {
    match device {
        DeviceRef::PadFdc1004(index) | DeviceRef::PadTmp117(index) => Some(index),
        DeviceRef::SharedTmp117 | DeviceRef::Multiplexer => None,
    }
}
