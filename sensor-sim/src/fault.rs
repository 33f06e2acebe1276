//! Injectable faults, each active over a [`Window`] of simulated time, for a number of events,
//! or until the device is reset.
//!
//! Every fault acts on one kind of event, which is also what a [`Window::Next`] count counts:
//!
//! | fault | event | effect |
//! |---|---|---|
//! | [`Fault::Nack`] | a transaction addressed to the device | its address is not acknowledged |
//! | [`Fault::DoneStuck`] | an FDC1004 conversion | stalls: result kept, DONE not set |
//! | [`Fault::ZeroReads`] | a MEASn_MSB read | the result reads 0 (and its LSB, latched, too) |
//! | [`Fault::Saturated`] | a conversion of the taxel's input | the result is a saturation code |
//! | [`Fault::Shorted`] | a conversion of the taxel's input | the input is a (negative) capacitance |
//! | [`Fault::OpenLead`] | a conversion of the taxel's input | the input is the lead alone |
//! | [`Fault::FrozenResult`] | a conversion of the taxel's input | DONE sets, the result stays |
//! | [`Fault::TemperatureStuck`] | a TEMP_RESULT read | TEMP_RESULT reads a fixed value |
//! | [`Fault::Unplugged`] | a transaction reaching the pad | the pad NACKs, then comes back reset |
//! | [`Fault::MuxChannelStuck`] | a transaction on the bus | the switch ignores the register |
//!
//! A burst of NACKs is `Nack` with `Window::Next(n)`; a device that does not answer at all is
//! `Nack` with `Window::From`. The "MCU-only reset" channel shift is not a windowed fault but a
//! device state: see `Simulation::simulate_mcu_only_reset`.
//!
//! # Which devices a fault acts on
//!
//! Every fault is injected on a target: a pad (`Simulation::inject` is pad 0,
//! `Simulation::inject_on_pad` any pad) or the main bus upstream of the multiplexer
//! (`Simulation::inject_upstream`). A pad's faults act on that pad's FDC1004 and its own
//! TMP117; upstream faults act on the shared TMP117 on the main bus. The multiplexer's faults
//! ([`Fault::MuxChannelStuck`], `Fault::Nack(Device::Tca9548a)`) act on the multiplexer
//! whichever target they are injected on. In the single-pad setup (no multiplexer) the FDC1004
//! and the TMP117 on the bus are pad 0's.
//!
//! # Unplugged pad
//!
//! While [`Fault::Unplugged`] is active, the pad's board has no power: its FDC1004 and TMP117
//! acknowledge nothing, never see a transaction and convert nothing. When the window ends (its
//! end time, its last counted transaction, or the fault's removal), the board is plugged back
//! in at that instant: both devices power on with every register at its reset value and, as
//! after any power-on, do not acknowledge their address until their power-up time has passed.
//! A pad unplugged with [`Window::UntilSoftwareReset`] stays unplugged until the fault is
//! removed or the simulation is power-cycled (a software reset cannot reach it).
//!
//! # Stuck multiplexer channel
//!
//! [`Fault::MuxChannelStuck`] models a broken pass switch: with `closed`, the channel's
//! downstream bus stays connected even when its bit in the control register is 0 (its devices
//! keep answering, and may collide with the selected pad's at the same address); without
//! `closed`, the channel stays disconnected even when its bit is 1 (its devices NACK as if
//! absent). The control register itself is unaffected: it reads back what was written, so a
//! driver's read-back check does not see the fault. A [`Window::Next`] count counts bus
//! transactions, whatever their address.

/// A kind of simulated device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Device {
    /// The FDC1004 at 0x50.
    Fdc1004,
    /// The TMP117 (0x48 on a pad; 0x48..=0x4B when shared on the main bus).
    Tmp117,
    /// The TCA9548A multiplexer (0x70..=0x77), when the topology has one.
    Tca9548a,
}

/// Default capacitance of shorted electrodes, pF: conduction through the dielectric reads as a
/// negative capacitance (the article's LCR meter showed it under concentrated loads).
pub const DEFAULT_SHORTED_PF: f32 = -0.5;

/// A fault to inject.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// The device does not acknowledge its address.
    Nack(Device),
    /// FDC1004 conversions stall: results stay as they were and DONE never sets (the lock-up
    /// reported on the TI forum, cured only by a software reset).
    DoneStuck,
    /// FDC1004 result registers read 0 (the occasional all-zero read).
    ZeroReads,
    /// The taxel's measurements come out as a saturation code (0x7FFFFF when `high`, else
    /// 0x800000), as users see in repeat mode.
    Saturated {
        /// Taxel 0..4 (= CIN1..CIN4).
        taxel: usize,
        /// Saturated high rather than low.
        high: bool,
    },
    /// The taxel's electrodes conduct: its input is `capacitance_pf` instead of the physics'
    /// value (negative: at CAPDAC 0 a negative code, with a CAPDAC offset possibly saturated low).
    Shorted {
        /// Taxel 0..4 (= CIN1..CIN4).
        taxel: usize,
        /// Capacitance seen by the converter, pF.
        capacitance_pf: f32,
    },
    /// The taxel's lead is open: the converter sees `capacitance_pf`, or when `None` the
    /// taxel's parasitic capacitance alone (the cable up to the break).
    OpenLead {
        /// Taxel 0..4 (= CIN1..CIN4).
        taxel: usize,
        /// Capacitance seen by the converter, pF (`None`: the parasitic capacitance).
        capacitance_pf: Option<f32>,
    },
    /// The taxel's conversions complete and set DONE but leave its result register as it was:
    /// the channel repeats one code (the "locked channel" users report in repeat mode; a
    /// software reset zeroes the results, after which it repeats 0).
    FrozenResult {
        /// Taxel 0..4 (= CIN1..CIN4).
        taxel: usize,
    },
    /// TMP117 TEMP_RESULT reads this register value whatever the temperature (conversions and
    /// Data_Ready go on).
    TemperatureStuck {
        /// The TEMP_RESULT value returned.
        temp_result: u16,
    },
    /// The pad's board is unplugged: its FDC1004 and TMP117 NACK everything, and come back
    /// powered on afresh, registers at reset, when the window ends (see the module
    /// documentation).
    Unplugged,
    /// A multiplexer channel's switch stays closed (`closed`) or open whatever the control
    /// register says (see the module documentation).
    MuxChannelStuck {
        /// Channel 0..8.
        channel: u8,
        /// Stuck connected rather than disconnected.
        closed: bool,
    },
}

impl Fault {
    /// Shorted electrodes on a taxel at [`DEFAULT_SHORTED_PF`].
    pub const fn shorted(taxel: usize) -> Fault {
        Fault::Shorted {
            taxel,
            capacitance_pf: DEFAULT_SHORTED_PF,
        }
    }

    /// An open lead on a taxel: only the parasitic capacitance remains.
    pub const fn open_lead(taxel: usize) -> Fault {
        Fault::OpenLead {
            taxel,
            capacitance_pf: None,
        }
    }

    /// The device the fault belongs to (whose reset ends a [`Window::UntilSoftwareReset`]);
    /// [`Fault::Unplugged`] belongs to the pad's FDC1004, which cannot be reset while
    /// unplugged.
    pub const fn device(&self) -> Device {
        match self {
            Fault::Nack(device) => *device,
            Fault::TemperatureStuck { .. } => Device::Tmp117,
            Fault::MuxChannelStuck { .. } => Device::Tca9548a,
            _ => Device::Fdc1004,
        }
    }

    /// Whether the fault acts on the multiplexer, whatever target it is injected on.
    pub(crate) const fn acts_on_multiplexer(&self) -> bool {
        matches!(
            self,
            Fault::MuxChannelStuck { .. } | Fault::Nack(Device::Tca9548a)
        )
    }
}

/// When a fault is active.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Window {
    /// From `start_us` (inclusive) to `end_us` (exclusive) of simulated time.
    Between {
        /// Start, µs of simulated time.
        start_us: u64,
        /// End, µs of simulated time.
        end_us: u64,
    },
    /// From `start_us` on, until removed.
    From {
        /// Start, µs of simulated time.
        start_us: u64,
    },
    /// The next `n` events the fault acts on (see the module table), then gone.
    Next(u32),
    /// From now until the device is software-reset (FDC1004 RST, TMP117 Soft_Reset) or
    /// power-cycled.
    UntilSoftwareReset,
}

/// Handle of an injected fault, to remove it early.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FaultId(pub(crate) u64);

/// Where an injected fault acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FaultTarget {
    /// The devices of pad `n` (its FDC1004 and its own TMP117).
    Pad(usize),
    /// The devices on the main bus: the multiplexer and the shared TMP117.
    Upstream,
}

#[derive(Debug, Clone)]
struct ScheduledFault {
    id: FaultId,
    target: FaultTarget,
    fault: Fault,
    window: Window,
    remaining: u32,
}

impl ScheduledFault {
    fn active_at(&self, time_us: u64) -> bool {
        match self.window {
            Window::Between { start_us, end_us } => (start_us..end_us).contains(&time_us),
            Window::From { start_us } => time_us >= start_us,
            Window::Next(_) => self.remaining > 0,
            Window::UntilSoftwareReset => true,
        }
    }
}

/// The injected faults.
#[derive(Debug, Clone, Default)]
pub(crate) struct FaultBook {
    faults: Vec<ScheduledFault>,
    next_id: u64,
}

impl FaultBook {
    pub(crate) fn inject(&mut self, target: FaultTarget, fault: Fault, window: Window) -> FaultId {
        let target = if fault.acts_on_multiplexer() {
            FaultTarget::Upstream
        } else {
            target
        };
        let id = FaultId(self.next_id);
        self.next_id += 1;
        let remaining = match window {
            Window::Next(count) => count,
            _ => 0,
        };
        self.faults.push(ScheduledFault {
            id,
            target,
            fault,
            window,
            remaining,
        });
        id
    }

    pub(crate) fn remove(&mut self, id: FaultId) -> bool {
        let before = self.faults.len();
        self.faults.retain(|scheduled| scheduled.id != id);
        self.faults.len() != before
    }

    pub(crate) fn clear(&mut self) {
        self.faults.clear();
    }

    /// Ends the faults on `target` of `device` that last until its reset.
    pub(crate) fn end_until_reset(&mut self, target: FaultTarget, device: Device) {
        self.faults.retain(|scheduled| {
            !(scheduled.target == target
                && scheduled.window == Window::UntilSoftwareReset
                && scheduled.fault.device() == device)
        });
    }

    /// Ends every fault on any target that lasts until a reset (the whole board power-cycled).
    pub(crate) fn end_all_until_reset(&mut self) {
        self.faults
            .retain(|scheduled| scheduled.window != Window::UntilSoftwareReset);
    }

    /// Whether any fault `select` accepts is injected, active or not, on any target.
    pub(crate) fn contains(&self, select: impl Fn(&Fault) -> bool) -> bool {
        self.faults.iter().any(|scheduled| select(&scheduled.fault))
    }

    /// Whether a fault on `target` that `select` accepts is active at `time_us` (consumes
    /// nothing).
    pub(crate) fn any_active(
        &self,
        time_us: u64,
        target: FaultTarget,
        select: impl Fn(&Fault) -> bool,
    ) -> bool {
        self.faults.iter().any(|scheduled| {
            scheduled.target == target && scheduled.active_at(time_us) && select(&scheduled.fault)
        })
    }

    /// The earliest start or end of a time window (µs) of a fault on `target` that `select`
    /// accepts, after `after_us`.
    pub(crate) fn next_boundary_us(
        &self,
        after_us: u64,
        target: FaultTarget,
        select: impl Fn(&Fault) -> bool,
    ) -> Option<u64> {
        self.faults
            .iter()
            .filter(|scheduled| scheduled.target == target && select(&scheduled.fault))
            .flat_map(|scheduled| match scheduled.window {
                Window::Between { start_us, end_us } => [Some(start_us), Some(end_us)],
                Window::From { start_us } => [Some(start_us), None],
                Window::Next(_) | Window::UntilSoftwareReset => [None, None],
            })
            .flatten()
            .filter(|&boundary_us| boundary_us > after_us)
            .min()
    }

    /// The first active fault on `target` that `select` accepts, for one event at `time_us`;
    /// consumes one count of a [`Window::Next`] fault.
    pub(crate) fn take<T>(
        &mut self,
        time_us: u64,
        target: FaultTarget,
        select: impl Fn(&Fault) -> Option<T>,
    ) -> Option<T> {
        let (index, value) = self
            .faults
            .iter()
            .enumerate()
            .filter(|(_, scheduled)| scheduled.target == target && scheduled.active_at(time_us))
            .find_map(|(index, scheduled)| select(&scheduled.fault).map(|value| (index, value)))?;
        let scheduled = &mut self.faults[index];
        if let Window::Next(_) = scheduled.window {
            scheduled.remaining -= 1;
            if scheduled.remaining == 0 {
                self.faults.remove(index);
            }
        }
        Some(value)
    }
}

/// The fault book as one device sees it: only the faults on its target.
pub(crate) struct TargetFaults<'a> {
    pub(crate) book: &'a mut FaultBook,
    pub(crate) target: FaultTarget,
}

impl TargetFaults<'_> {
    /// [`FaultBook::take`] on this target.
    pub(crate) fn take<T>(
        &mut self,
        time_us: u64,
        select: impl Fn(&Fault) -> Option<T>,
    ) -> Option<T> {
        self.book.take(time_us, self.target, select)
    }

    /// [`FaultBook::end_until_reset`] on this target.
    pub(crate) fn end_until_reset(&mut self, device: Device) {
        self.book.end_until_reset(self.target, device);
    }
}
