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
//! | [`Fault::TemperatureStuck`] | a TEMP_RESULT read | TEMP_RESULT reads a fixed value |
//!
//! A burst of NACKs is `Nack` with `Window::Next(n)`; a device that does not answer at all is
//! `Nack` with `Window::From`. The "MCU-only reset" channel shift is not a windowed fault but a
//! device state: see `Simulation::simulate_mcu_only_reset`.

/// One of the two simulated devices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Device {
    /// The FDC1004 at 0x50.
    Fdc1004,
    /// The TMP117 at 0x48.
    Tmp117,
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
    /// TMP117 TEMP_RESULT reads this register value whatever the temperature (conversions and
    /// Data_Ready go on).
    TemperatureStuck {
        /// The TEMP_RESULT value returned.
        temp_result: u16,
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

    /// The device the fault belongs to (whose reset ends a [`Window::UntilSoftwareReset`]).
    pub const fn device(&self) -> Device {
        match self {
            Fault::Nack(device) => *device,
            Fault::TemperatureStuck { .. } => Device::Tmp117,
            _ => Device::Fdc1004,
        }
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

#[derive(Debug, Clone)]
struct ScheduledFault {
    id: FaultId,
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
    pub(crate) fn inject(&mut self, fault: Fault, window: Window) -> FaultId {
        let id = FaultId(self.next_id);
        self.next_id += 1;
        let remaining = match window {
            Window::Next(count) => count,
            _ => 0,
        };
        self.faults.push(ScheduledFault {
            id,
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

    /// Ends the faults of `device` that last until its reset.
    pub(crate) fn end_until_reset(&mut self, device: Device) {
        self.faults.retain(|scheduled| {
            !(scheduled.window == Window::UntilSoftwareReset && scheduled.fault.device() == device)
        });
    }

    /// The first active fault `select` accepts, for one event at `time_us`; consumes one count
    /// of a [`Window::Next`] fault.
    pub(crate) fn take<T>(
        &mut self,
        time_us: u64,
        select: impl Fn(&Fault) -> Option<T>,
    ) -> Option<T> {
        let (index, value) = self
            .faults
            .iter()
            .enumerate()
            .filter(|(_, scheduled)| scheduled.active_at(time_us))
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
