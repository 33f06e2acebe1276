//! What a simulation starts from: [`SimulationConfig`], the bus [`Topology`] (one pad directly
//! on the bus, or up to eight behind a TCA9548A), and their validation ([`ConfigError`]).

use std::fmt;

use crate::bus::TMP117_ADDRESS;
use crate::fdc1004::Fdc1004Config;
use crate::physics::PadPhysics;
use crate::tca9548a::{ADDRESS_FIRST, ADDRESS_LAST, CHANNEL_COUNT};
use crate::tmp117::Tmp117Config;

/// Seed of the default configuration.
pub const DEFAULT_SEED: u64 = 0x7A_5E_15_11;

/// Most pads one bus carries: one per multiplexer channel.
pub const MAX_PADS: usize = CHANNEL_COUNT;

/// Lowest address a TMP117 can be strapped to (ADD0 to ground).
pub const TMP117_ADDRESS_FIRST: u8 = 0x48;

/// Highest address a TMP117 can be strapped to (ADD0 to SCL).
pub const TMP117_ADDRESS_LAST: u8 = 0x4B;

/// Everything a simulation starts from.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulationConfig {
    /// Seed of the noise generators (every device draws from its own stream, see
    /// [`Topology`]).
    pub seed: u64,
    /// The pad ([`Topology::SinglePad`] only).
    pub physics: PadPhysics,
    /// The FDC1004 model's settings ([`Topology::SinglePad`] only).
    pub fdc1004: Fdc1004Config,
    /// The TMP117 model's settings ([`Topology::SinglePad`] only).
    pub tmp117: Tmp117Config,
    /// I2C clock for the duration of transactions, Hz (default 400 kHz); `None`: transactions
    /// take no simulated time.
    pub bus_frequency_hz: Option<u32>,
    /// What sits on the bus (default: one pad, no multiplexer).
    pub topology: Topology,
}

impl Default for SimulationConfig {
    fn default() -> Self {
        Self {
            seed: DEFAULT_SEED,
            physics: PadPhysics::default(),
            fdc1004: Fdc1004Config::default(),
            tmp117: Tmp117Config::default(),
            bus_frequency_hz: Some(400_000),
            topology: Topology::SinglePad,
        }
    }
}

/// What sits on the simulated bus.
///
/// Pads are numbered 0.. in the order they are configured; pad 0 is the one the single-pad
/// methods of `Simulation` (`set_scene`, `inject`, `physics`, ...) act on. Every device draws
/// its noise from its own stream: pad k's FDC1004 from the seed and k, its TMP117 from another
/// stream of the same, the shared TMP117 from a third; with the same seed and the same calls a
/// run is the same, and pad 0's streams are those of the single-pad setup.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Topology {
    /// One pad directly on the bus: the FDC1004 at 0x50 and the TMP117 at 0x48, configured by
    /// [`SimulationConfig::physics`], [`SimulationConfig::fdc1004`] and
    /// [`SimulationConfig::tmp117`].
    #[default]
    SinglePad,
    /// Up to [`MAX_PADS`] pads behind a TCA9548A; [`SimulationConfig::physics`],
    /// [`SimulationConfig::fdc1004`] and [`SimulationConfig::tmp117`] are not used (each pad
    /// and the shared TMP117 carry their own settings).
    Multiplexed(MultiplexerConfig),
}

/// A TCA9548A on the main bus with pads on its channels.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiplexerConfig {
    /// The multiplexer's 7-bit address, 0x70..=0x77 (A2 A1 A0).
    pub address: u8,
    /// The pads, 1..=[`MAX_PADS`], each on a channel of its own.
    pub pads: Vec<PadConfig>,
    /// A TMP117 on the main bus, upstream of the multiplexer (always on the bus).
    pub shared_tmp117: Option<SharedTmp117Config>,
}

impl MultiplexerConfig {
    /// A multiplexer at `address` with a default pad (no TMP117 of its own) on each of
    /// `channels`, pad k on `channels[k]`, and no shared TMP117.
    pub fn with_pads_on_channels(address: u8, channels: &[u8]) -> Self {
        Self {
            address,
            pads: channels
                .iter()
                .map(|&channel| PadConfig::on_channel(channel))
                .collect(),
            shared_tmp117: None,
        }
    }
}

/// One pad behind the multiplexer.
#[derive(Debug, Clone, PartialEq)]
pub struct PadConfig {
    /// The multiplexer channel the pad's board hangs on, 0..8.
    pub channel: u8,
    /// The pad.
    pub physics: PadPhysics,
    /// Its FDC1004 (at 0x50 behind the channel).
    pub fdc1004: Fdc1004Config,
    /// Its own TMP117 at 0x48 behind the channel, if the board has one.
    pub tmp117: Option<Tmp117Config>,
}

impl PadConfig {
    /// A default pad on `channel`, without a TMP117 of its own.
    pub fn on_channel(channel: u8) -> Self {
        Self {
            channel,
            physics: PadPhysics::default(),
            fdc1004: Fdc1004Config::default(),
            tmp117: None,
        }
    }
}

/// A TMP117 on the main bus, upstream of the multiplexer. Its temperature is pad 0's scene
/// temperature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SharedTmp117Config {
    /// Its 7-bit address, 0x48..=0x4B (ADD0 strapping).
    pub address: u8,
    /// Its settings.
    pub tmp117: Tmp117Config,
}

impl Default for SharedTmp117Config {
    /// At 0x48 with the default settings.
    fn default() -> Self {
        Self {
            address: TMP117_ADDRESS,
            tmp117: Tmp117Config::default(),
        }
    }
}

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigError {
    /// A taxel's C0 or modulus is not finite and positive, or its Cp not finite and
    /// non-negative.
    Taxel {
        /// Index of the taxel.
        taxel: usize,
    },
    /// The dielectric's densification or the history effects are out of their ranges (see
    /// [`crate::physics`]).
    Pad,
    /// A noise level is negative or not finite.
    Noise,
    /// The bus frequency is zero.
    BusFrequency,
    /// The multiplexer's address is outside 0x70..=0x77.
    MultiplexerAddress {
        /// The refused address.
        address: u8,
    },
    /// A multiplexer has no pad, or more than [`MAX_PADS`].
    PadCount {
        /// The number of pads configured.
        count: usize,
    },
    /// A pad's channel is not 0..8.
    Channel {
        /// Index of the pad.
        pad: usize,
        /// The refused channel.
        channel: u8,
    },
    /// Two pads are on the same channel.
    DuplicateChannel {
        /// The channel.
        channel: u8,
    },
    /// [`ConfigError::Taxel`] on a pad behind the multiplexer.
    PadTaxel {
        /// Index of the pad.
        pad: usize,
        /// Index of the taxel.
        taxel: usize,
    },
    /// [`ConfigError::Pad`] on a pad behind the multiplexer.
    PadDielectric {
        /// Index of the pad.
        pad: usize,
    },
    /// [`ConfigError::Noise`] on a pad behind the multiplexer.
    PadNoise {
        /// Index of the pad.
        pad: usize,
    },
    /// The shared TMP117's address is outside 0x48..=0x4B.
    SharedTmp117Address {
        /// The refused address.
        address: u8,
    },
    /// The shared TMP117 and a pad's own TMP117 have the same address: whenever the pad's
    /// channel is enabled they would be on the same wires.
    Tmp117AddressClash {
        /// The shared address.
        address: u8,
        /// The first pad with a TMP117 at that address.
        pad: usize,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Taxel { taxel } => write!(
                formatter,
                "taxel {taxel}: C0 and the modulus must be finite and positive, Cp finite and non-negative"
            ),
            ConfigError::Pad => formatter.write_str(
                "the dielectric's densification or the pad's history effects are out of range",
            ),
            ConfigError::Noise => formatter.write_str("noise levels must be finite and >= 0"),
            ConfigError::BusFrequency => formatter.write_str("the bus frequency must not be 0"),
            ConfigError::MultiplexerAddress { address } => write!(
                formatter,
                "multiplexer address {address:#04x} is outside 0x70..=0x77"
            ),
            ConfigError::PadCount { count } => write!(
                formatter,
                "{count} pads behind the multiplexer: 1..={MAX_PADS} are possible"
            ),
            ConfigError::Channel { pad, channel } => {
                write!(formatter, "pad {pad}: channel {channel} is not 0..8")
            }
            ConfigError::DuplicateChannel { channel } => {
                write!(formatter, "two pads on multiplexer channel {channel}")
            }
            ConfigError::PadTaxel { pad, taxel } => write!(
                formatter,
                "pad {pad}, taxel {taxel}: C0 and the modulus must be finite and positive, Cp finite and non-negative"
            ),
            ConfigError::PadDielectric { pad } => write!(
                formatter,
                "pad {pad}: the dielectric's densification or the history effects are out of range"
            ),
            ConfigError::PadNoise { pad } => {
                write!(formatter, "pad {pad}: noise levels must be finite and >= 0")
            }
            ConfigError::SharedTmp117Address { address } => write!(
                formatter,
                "shared TMP117 address {address:#04x} is outside 0x48..=0x4B"
            ),
            ConfigError::Tmp117AddressClash { address, pad } => write!(
                formatter,
                "the shared TMP117 and pad {pad}'s TMP117 are both at {address:#04x}"
            ),
        }
    }
}

impl std::error::Error for ConfigError {}

fn noise_ok(value: f64) -> bool {
    value.is_finite() && value >= 0.0
}

impl SimulationConfig {
    /// Checks every value; the first problem found.
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        match &self.topology {
            Topology::SinglePad => self.validate_single_pad()?,
            Topology::Multiplexed(multiplexer) => multiplexer.validate()?,
        }
        if self.bus_frequency_hz == Some(0) {
            return Err(ConfigError::BusFrequency);
        }
        Ok(())
    }

    fn validate_single_pad(&self) -> Result<(), ConfigError> {
        if let Some(taxel) = self.physics.first_invalid_taxel() {
            return Err(ConfigError::Taxel { taxel });
        }
        if !self.physics.pad_is_valid() {
            return Err(ConfigError::Pad);
        }
        if !noise_ok(self.fdc1004.noise_rms_pf_at_100_sps) || !noise_ok(self.tmp117.noise_rms_c) {
            return Err(ConfigError::Noise);
        }
        Ok(())
    }
}

impl MultiplexerConfig {
    fn validate(&self) -> Result<(), ConfigError> {
        if !(ADDRESS_FIRST..=ADDRESS_LAST).contains(&self.address) {
            return Err(ConfigError::MultiplexerAddress {
                address: self.address,
            });
        }
        let count = self.pads.len();
        if count == 0 || count > MAX_PADS {
            return Err(ConfigError::PadCount { count });
        }
        let mut channels_used = 0u8;
        for (pad, config) in self.pads.iter().enumerate() {
            let channel = config.channel;
            if channel as usize >= CHANNEL_COUNT {
                return Err(ConfigError::Channel { pad, channel });
            }
            if channels_used & (1 << channel) != 0 {
                return Err(ConfigError::DuplicateChannel { channel });
            }
            channels_used |= 1 << channel;
            if let Some(taxel) = config.physics.first_invalid_taxel() {
                return Err(ConfigError::PadTaxel { pad, taxel });
            }
            if !config.physics.pad_is_valid() {
                return Err(ConfigError::PadDielectric { pad });
            }
            let tmp117_noise_ok = config
                .tmp117
                .is_none_or(|tmp117| noise_ok(tmp117.noise_rms_c));
            if !noise_ok(config.fdc1004.noise_rms_pf_at_100_sps) || !tmp117_noise_ok {
                return Err(ConfigError::PadNoise { pad });
            }
        }
        if let Some(shared) = &self.shared_tmp117 {
            let address = shared.address;
            if !(TMP117_ADDRESS_FIRST..=TMP117_ADDRESS_LAST).contains(&address) {
                return Err(ConfigError::SharedTmp117Address { address });
            }
            if !noise_ok(shared.tmp117.noise_rms_c) {
                return Err(ConfigError::Noise);
            }
            // Pads' own TMP117s sit at 0x48 behind their channel.
            if address == TMP117_ADDRESS {
                if let Some(pad) = self.pads.iter().position(|pad| pad.tmp117.is_some()) {
                    return Err(ConfigError::Tmp117AddressClash { address, pad });
                }
            }
        }
        Ok(())
    }
}
