//! The device's boot, written once for the firmware and the simulated device: the board's
//! configuration, the calibration to start with from what flash holds, and the assembly of the
//! models, the acquisition loop and the device application around the board's parts and the
//! pads discovery found. The board and the simulator differ only in the parts they pass in (real
//! or simulated I2C, clock, flash).

use core::ops::Deref;

use acquisition::discovery::{PadSlot, PadTemperature, Topology, MAX_PADS};
use acquisition::pad_bus::{MuxedBus, PadBus};
use acquisition::{Acquisition, AcquisitionConfig, Clock, TemperatureSource};
use calibration_store::LoadOutcome;
use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::mutex::Mutex;
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use fdc1004::{Fdc1004, Rate};
use model_core::{Calibration, PadModel};
use model_core::{PadGeometry, PadRole};
use tmp117::Tmp117;
use wire::CalibrationSource;

use crate::retained::{boot_plan, ResetKind, RetainedState};
use crate::{CalibrationPersistence, Device, DeviceConfig, DeviceIdentity};

/// How the board is set up: what the firmware runs, and what the simulated device runs unless a
/// test asks for something else.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardConfig {
    /// CAPDAC of each measurement (CIN1..CIN4), in 3.125 pF steps. A taxel is about 4.5 pF
    /// unloaded and 26 % more at 50 kPa; with the cable shields driven the cable adds little,
    /// so everything stays inside the ±15 pF input without an offset. Calibrations are valid
    /// only for the CAPDAC they were taken with.
    pub capdac: [u8; 4],
    /// The converter's rate at boot (its DONE timeout follows from it): four conversions, one
    /// per taxel, take about 10 ms at 400 S/s, so about 100 sample sets/s.
    pub converter_rate: Rate,
    /// Sample sets averaged by the tare a power-on takes (the pad is taken to be unloaded then).
    pub tare_sets_at_power_on: u16,
    /// The device application's settings.
    pub device: DeviceConfig,
    /// The sensor bus's I2C clock, Hz: fast mode, which the FDC1004, the TMP117 and the
    /// TCA9548A all support.
    pub i2c_frequency_hz: u32,
    /// Where discovery looks for a TCA9548A multiplexer (A2..A0 to ground: 0x70); without one
    /// the bus carries a single pad.
    pub multiplexer: tca9548a::Address,
}

/// The board's configuration.
pub const BOARD: BoardConfig = BoardConfig {
    i2c_frequency_hz: 400_000,
    multiplexer: tca9548a::Address::from_pins(false, false, false),
    capdac: [0; 4],
    converter_rate: Rate::Hz400,
    tare_sets_at_power_on: 16,
    device: DeviceConfig::DEFAULT,
};

impl BoardConfig {
    /// The converter's configuration.
    pub fn converter_config(&self) -> fdc1004::Config {
        fdc1004::Config::new(self.converter_rate, self.capdac)
    }
}

/// What a pad boots with from flash.
#[derive(Debug, Clone, PartialEq)]
pub struct BootPad {
    /// Its calibration.
    pub calibration: Calibration,
    /// Where the calibration came from.
    pub source: CalibrationSource,
    /// Its role and geometry as saved with the calibration; `None`: the configuration's.
    pub layout: Option<(PadRole, PadGeometry)>,
}

/// What a pad boots with and where it came from: the saved record if it is intact and valid,
/// otherwise the built-in calibration and geometry (marked as replacing a corrupt copy when
/// there was one). `None` (no usable flash region) boots on the defaults.
pub fn boot_pad<E>(stored: Option<LoadOutcome<E>>) -> BootPad {
    let defaults = |source| BootPad {
        calibration: Calibration::default(),
        source,
        layout: None,
    };
    match stored {
        Some(LoadOutcome::Stored(record)) => match Calibration::new(&record.calibration) {
            Ok(calibration) => BootPad {
                calibration,
                source: CalibrationSource::Flash,
                layout: Some((record.role, record.geometry)),
            },
            Err(_) => defaults(CalibrationSource::DefaultsAfterCorruptFlash),
        },
        Some(LoadOutcome::Corrupt(_)) => defaults(CalibrationSource::DefaultsAfterCorruptFlash),
        Some(LoadOutcome::Absent) | None => defaults(CalibrationSource::Defaults),
    }
}

/// The pad index a pad's calibration is saved under: its multiplexer channel (a pad keeps its
/// calibration when another pad is unplugged, which shifts the discovery order), 0 for the pad
/// on the bus itself.
pub fn calibration_key(slot: &PadSlot) -> u8 {
    slot.channel.map_or(0, |channel| channel.index())
}

/// The board's parts the device runs on.
pub struct BoardParts<S, D, F, K, P> {
    /// The sensor bus with its multiplexer, shared by every pad's handle (a `&'static` on the
    /// MCU, a reference-counted pointer on the host).
    pub bus: S,
    /// The pads on it, as discovery found them ([`acquisition::discovery::discover`]).
    pub topology: Topology,
    /// A delay (the converters' waits and the loop's pacing).
    pub delay: D,
    /// The fallback temperature source (the MCU's die sensor).
    pub fallback_temperature: F,
    /// The clock of the sample timestamps.
    pub clock: K,
    /// Where a calibration is saved.
    pub persistence: P,
    /// Who the device is.
    pub identity: DeviceIdentity,
}

/// What a boot did, for the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BootReport {
    /// Pads found.
    pub pad_count: u8,
    /// Where the first pad's calibration came from (every pad's is in its PadInfo reply).
    pub calibration_source: CalibrationSource,
    /// Sample sets of the tare taken at start (0: none).
    pub tare_sets_at_start: u16,
    /// Taxels, over every pad, whose baseline was restored from the retained record.
    pub restored_taxels: u8,
    /// Whether an MCU-only reset found an intact retained record.
    pub restored: bool,
}

/// One pad's I2C handle on the shared bus.
pub type PadI2c<S> = PadBus<S>;

/// The acquisition loop the device runs: every pad's converter and TMP117 on a handle of the
/// shared bus.
pub type BoardAcquisition<S, D, F, K> = Acquisition<PadI2c<S>, D, Tmp117<PadI2c<S>>, F, K>;

/// The device application the firmware and the simulated device run.
pub type BootedDevice<S, D, F, K, P> = Device<BoardAcquisition<S, D, F, K>, P>;

/// Boots: one model per pad found, each on the calibration flash holds for it (its own, the one
/// saved for every pad, or the default), read pad by pad from `parts.persistence`; after an
/// MCU-only reset every pad gets back the baselines and tier of the pad that was on its channel,
/// after a power-on every pad is tared at start; then the acquisition loop reading the pads in
/// discovery order, and the device application.
// Not inlined into the caller's async body, so that the models exist once in the task's state,
// not twice.
#[inline(never)]
pub fn boot<S, M, BUS, D, F, K, P>(
    mut parts: BoardParts<S, D, F, K, P>,
    config: &BoardConfig,
    reset: ResetKind,
    retained: Option<RetainedState>,
) -> (BootedDevice<S, D, F, K, P>, BootReport)
where
    S: Deref<Target = Mutex<M, MuxedBus<BUS>>> + Clone,
    M: RawMutex,
    BUS: I2c,
    D: DelayNs + Clone,
    F: TemperatureSource,
    K: Clock,
    P: CalibrationPersistence,
{
    let plan = boot_plan(reset, retained, config.tare_sets_at_power_on);
    let mut acquisition = Acquisition::without_pads(
        parts.fallback_temperature,
        parts.clock,
        AcquisitionConfig {
            tare_sets_at_start: plan.tare_sets_at_start,
            ..AcquisitionConfig::default()
        },
        parts.delay.clone(),
        config.converter_rate,
    );
    let mut restored_taxels = 0;
    let mut calibration_sources = heapless::Vec::<CalibrationSource, MAX_PADS>::new();
    let mut layouts = heapless::Vec::<Option<(PadRole, PadGeometry)>, MAX_PADS>::new();
    for slot in &parts.topology.pads {
        // One pad's calibration at a time: eight specs at once would not fit the MCU's RAM.
        let pad = boot_pad(parts.persistence.load(calibration_key(slot)));
        // Cannot fail: discovery finds at most MAX_PADS pads.
        let _ = calibration_sources.push(pad.source);
        let _ = layouts.push(pad.layout);
        let mut model = PadModel::new(pad.calibration);
        let restored = plan.apply_to(slot.channel.map(|channel| channel.index()), &mut model);
        restored_taxels += restored.count_ones() as u8;
        let converter = Fdc1004::new(
            PadBus::new(parts.bus.clone(), slot.channel),
            parts.delay.clone(),
            config.converter_config(),
        );
        let temperature = match slot.temperature {
            PadTemperature::Own(address) => Some(Tmp117::new(
                PadBus::new(parts.bus.clone(), slot.channel),
                address,
            )),
            // Upstream of the multiplexer: it answers whichever channel is selected.
            PadTemperature::Shared(address) => {
                Some(Tmp117::new(PadBus::new(parts.bus.clone(), None), address))
            }
            PadTemperature::DieOnly => None,
        };
        // Cannot fail: discovery finds at most as many pads as the loop holds.
        let _ = acquisition.add_pad(converter, temperature, model);
    }
    let pad_count = u8::try_from(acquisition.pad_count()).unwrap_or(u8::MAX);
    let mut device = Device::new(
        acquisition,
        parts.persistence,
        parts.identity,
        &calibration_sources,
        &parts.topology.pads,
        config.device,
    );
    for (pad, layout) in layouts.iter().enumerate() {
        if let Some((role, geometry)) = layout {
            device.set_pad_geometry(pad, *role, *geometry);
        }
    }
    let report = BootReport {
        pad_count,
        calibration_source: calibration_sources
            .first()
            .copied()
            .unwrap_or(CalibrationSource::Defaults),
        tare_sets_at_start: plan.tare_sets_at_start,
        restored_taxels,
        restored: plan.restore.is_some(),
    };
    (device, report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use calibration_store::{CorruptReason, PadRecord};

    #[test]
    fn flash_contents_choose_the_calibration_and_geometry() {
        let pad = boot_pad::<()>(None);
        assert_eq!(
            (pad.calibration.id(), pad.source, pad.layout),
            (0, CalibrationSource::Defaults, None)
        );
        let pad = boot_pad(Some(LoadOutcome::<()>::Absent));
        assert_eq!(pad.source, CalibrationSource::Defaults);
        let pad = boot_pad(Some(LoadOutcome::<()>::Corrupt(
            CorruptReason::NoIntactRecord,
        )));
        assert_eq!(pad.source, CalibrationSource::DefaultsAfterCorruptFlash);
        let mut spec = Calibration::default().to_spec();
        spec.id = 42;
        let palm = PadGeometry::new(
            [(-6.0, 6.0), (6.0, 6.0), (-6.0, -6.0), (6.0, -6.0)]
                .map(|(x, y)| model_core::TaxelGeometry::new(x, y, 100.0)),
        )
        .unwrap();
        let record = PadRecord {
            calibration: spec,
            role: PadRole::Palm,
            geometry: palm,
        };
        let pad = boot_pad(Some(LoadOutcome::<()>::Stored(record.clone())));
        assert_eq!(
            (pad.calibration.id(), pad.source, pad.layout),
            (42, CalibrationSource::Flash, Some((PadRole::Palm, palm)))
        );
        let mut broken = record;
        broken.calibration.taxels[0].points.truncate(1);
        let pad = boot_pad(Some(LoadOutcome::<()>::Stored(broken)));
        assert_eq!(
            (pad.calibration.id(), pad.source, pad.layout),
            (0, CalibrationSource::DefaultsAfterCorruptFlash, None)
        );
    }
}
