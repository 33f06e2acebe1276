//! Which pads are on the bus, found at boot: with a TCA9548A multiplexer, every channel whose
//! FDC1004 answers with its identification registers is a pad; without one, the bus carries
//! exactly one pad (today's single-pad board), whether or not its converter answers yet, so a
//! converter that is slow or unplugged at power-up is flagged and retried like any other fault
//! instead of leaving the device with no pad. Each pad gets the TMP117 found behind its own
//! channel, else the one on the main bus, else none.
//!
//! A pad that is not there at boot is not looked for again: plugging a pad in needs a reboot.
//! A pad that was found and later fails keeps its slot and is flagged until it answers again.

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use heapless::Vec;
use tca9548a::{Address, Channel, ChannelMask, Tca9548a, CHANNEL_COUNT};

/// Most pads one device reads: one per multiplexer channel.
pub const MAX_PADS: usize = CHANNEL_COUNT;

/// The TMP117's addresses (ADD0 to GND, V+, SDA, SCL).
pub const TMP117_ADDRESSES: [tmp117::Address; 4] = [
    tmp117::Address::Gnd,
    tmp117::Address::Vplus,
    tmp117::Address::Sda,
    tmp117::Address::Scl,
];

/// Where a pad's temperature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PadTemperature {
    /// A TMP117 on the pad, behind its multiplexer channel.
    Own(tmp117::Address),
    /// The TMP117 on the main bus, shared by every pad without its own.
    Shared(tmp117::Address),
    /// No TMP117: the MCU's die sensor, flagged.
    DieOnly,
}

/// One pad found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadSlot {
    /// The multiplexer channel it is on (`None`: on the bus itself).
    pub channel: Option<Channel>,
    /// Its temperature source.
    pub temperature: PadTemperature,
}

/// What the bus carries.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Topology {
    /// The multiplexer, if one answered.
    pub mux: Option<Address>,
    /// The pads, in channel order.
    pub pads: Vec<PadSlot, MAX_PADS>,
}

impl Topology {
    /// The single-pad board: no multiplexer, one pad on the bus, the main-bus TMP117 if any.
    pub fn single_pad(temperature: PadTemperature) -> Self {
        let mut pads = Vec::new();
        // Cannot fail: the vector is empty and holds up to MAX_PADS (> 0).
        let _ = pads.push(PadSlot {
            channel: None,
            temperature,
        });
        Self { mux: None, pads }
    }
}

/// How long the sensors take to answer after power-on, µs: the FDC1004's power-up time
/// ([`fdc1004::POWER_UP_DELAY_US`]), longer than the TMP117's 1.5 ms.
pub const SENSOR_POWER_UP_US: u32 = fdc1004::POWER_UP_DELAY_US;

/// Waits until sensors powered up with the MCU answer ([`SENSOR_POWER_UP_US`]), then looks for a
/// multiplexer at `mux`, then for the pads and temperature sensors. Leaves every multiplexer
/// channel off. Never fails: what does not answer is not there.
pub async fn discover<BUS: I2c, D: DelayNs>(
    bus: &mut BUS,
    delay: &mut D,
    mux: Address,
) -> Topology {
    // Probing earlier would take a TMP117 still in its power-up for an absent one, and the
    // pads would run on the die sensor until the next reboot.
    delay.delay_us(SENSOR_POWER_UP_US).await;
    let mux_present = Tca9548a::new(&mut *bus, mux)
        .select_mask_verified(ChannelMask::NONE)
        .await
        .is_ok();
    let shared = first_tmp117(bus, None).await;
    let shared_temperature = shared.map_or(PadTemperature::DieOnly, PadTemperature::Shared);
    // A converter that answers with every channel off sits upstream of the multiplexer: it
    // would answer on every channel too, so it is the board's only addressable pad.
    if !mux_present || is_fdc1004(bus).await {
        return Topology::single_pad(shared_temperature);
    }
    let mut pads = Vec::new();
    for channel in Channel::ALL {
        if Tca9548a::new(&mut *bus, mux)
            .select_verified(channel)
            .await
            .is_err()
        {
            continue;
        }
        if !is_fdc1004(bus).await {
            continue;
        }
        // An upstream TMP117 answers on every channel: only another address can be the pad's.
        let temperature = match first_tmp117(bus, shared).await {
            Some(own) => PadTemperature::Own(own),
            None => shared_temperature,
        };
        // Cannot fail: at most one pad per channel, CHANNEL_COUNT == MAX_PADS.
        let _ = pads.push(PadSlot {
            channel: Some(channel),
            temperature,
        });
    }
    let _ = Tca9548a::new(&mut *bus, mux).disable_all().await;
    Topology {
        mux: Some(mux),
        pads,
    }
}

/// Whether an FDC1004 answers at its address with both identification registers.
async fn is_fdc1004<BUS: I2c>(bus: &mut BUS) -> bool {
    let manufacturer = read_u16(
        bus,
        fdc1004::DEVICE_ADDRESS,
        fdc1004::register::MANUFACTURER_ID,
    )
    .await;
    let device = read_u16(bus, fdc1004::DEVICE_ADDRESS, fdc1004::register::DEVICE_ID).await;
    manufacturer == Some(fdc1004::MANUFACTURER_ID_VALUE) && device == Some(fdc1004::DEVICE_ID_VALUE)
}

/// The first TMP117 that answers with its device ID, skipping `except`.
async fn first_tmp117<BUS: I2c>(
    bus: &mut BUS,
    except: Option<tmp117::Address>,
) -> Option<tmp117::Address> {
    for address in TMP117_ADDRESSES {
        if Some(address) == except {
            continue;
        }
        let id = read_u16(bus, address.seven_bit(), tmp117::register::DEVICE_ID).await;
        if id.map(|id| id & tmp117::field::DID_MASK) == Some(tmp117::DEVICE_ID_VALUE) {
            return Some(address);
        }
    }
    None
}

async fn read_u16<BUS: I2c>(bus: &mut BUS, address: u8, register: u8) -> Option<u16> {
    let mut bytes = [0u8; 2];
    bus.write_read(address, &[register], &mut bytes)
        .await
        .ok()
        .map(|()| u16::from_be_bytes(bytes))
}
