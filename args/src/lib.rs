//! The argument groups shared by the taxel programs (the `taxel` command line and the bridge),
//! defined once and flattened into each program's parser: which board or boards to talk to.
#![deny(missing_docs)]

use taxel_host::device_link::{
    attached_boards, choose_board, parse_hex_u16, select_port, LinkError, DEFAULT_PID, DEFAULT_VID,
};

/// The USB vendor and product ids boards are found by (the pad's, unless given).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct UsbIdArgs {
    /// USB vendor id of the boards, for finding them (hex).
    #[arg(long, value_name = "VID", default_value = "0x1209", value_parser = parse_hex_u16)]
    pub vid: u16,
    /// USB product id of the boards, for finding them (hex).
    #[arg(long, value_name = "PID", default_value = "0x0001", value_parser = parse_hex_u16)]
    pub pid: u16,
}

impl Default for UsbIdArgs {
    fn default() -> Self {
        Self {
            vid: DEFAULT_VID,
            pid: DEFAULT_PID,
        }
    }
}

/// Which board to talk to: a serial port, or an attached board chosen by its USB serial number
/// (or the only one attached).
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct BoardArgs {
    /// Serial port of the device (default: the only attached board, or --serial).
    #[arg(value_name = "PORT")]
    pub port: Option<String>,
    /// Choose the attached board with this USB serial number.
    #[arg(long, value_name = "SN", conflicts_with = "port")]
    pub serial: Option<String>,
    /// The boards' USB ids.
    #[command(flatten)]
    pub usb: UsbIdArgs,
}

impl BoardArgs {
    /// The board on `port`, found by its default VID:PID.
    pub fn for_port(port: String) -> Self {
        Self {
            port: Some(port),
            serial: None,
            usb: UsbIdArgs::default(),
        }
    }

    /// The port to open (see [`select_port`]).
    pub fn select_port(&self) -> Result<String, LinkError> {
        select_port(
            self.port.as_deref(),
            self.serial.as_deref(),
            self.usb.vid,
            self.usb.pid,
        )
    }
}

/// Which boards `taxel record` and `taxel view` read: any number of ports and of serial
/// numbers (one device is handled as before; several go on one host timeline).
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct MultiBoardArgs {
    /// Serial ports of the devices, one or more (default: the only attached board, or --serial).
    #[arg(value_name = "PORT")]
    pub ports: Vec<String>,
    /// Choose an attached board by its USB serial number; repeat for several boards (devices
    /// after the PORTs, in the order given).
    #[arg(long, value_name = "SN")]
    pub serial: Vec<String>,
    /// The boards' USB ids.
    #[command(flatten)]
    pub usb: UsbIdArgs,
}

impl MultiBoardArgs {
    /// The boards on these ports, found by the default VID:PID.
    pub fn for_ports(ports: Vec<String>) -> Self {
        Self {
            ports,
            serial: Vec::new(),
            usb: UsbIdArgs::default(),
        }
    }

    /// Refuses a PORT or a serial number given twice: each device is `handled` (recorded,
    /// shown) once.
    pub fn refuse_repeats(&self, handled: &str) -> anyhow::Result<()> {
        if let Some(port) = first_repeated(&self.ports) {
            anyhow::bail!("{port} is given twice: each device is {handled} once");
        }
        if let Some(serial) = first_repeated(&self.serial) {
            anyhow::bail!("--serial {serial} is given twice: each device is {handled} once");
        }
        Ok(())
    }

    /// The ports to open, in device order: the PORTs, then the boards with the serial numbers;
    /// with neither, the only attached board. A port named twice, also once as a PORT and once
    /// by its board's serial number, is refused.
    pub fn select_ports(&self) -> anyhow::Result<Vec<String>> {
        self.refuse_repeats("recorded")?;
        let mut ports = self.ports.clone();
        if !self.serial.is_empty() {
            let boards = attached_boards(self.usb.vid, self.usb.pid)?;
            for serial in &self.serial {
                ports.push(
                    choose_board(&boards, Some(serial), self.usb.vid, self.usb.pid)?.port_name,
                );
            }
        }
        if ports.is_empty() {
            ports.push(select_port(None, None, self.usb.vid, self.usb.pid)?);
        }
        if let Some(port) = first_repeated(&ports) {
            anyhow::bail!("{port} is given twice: each device is recorded once");
        }
        Ok(ports)
    }
}

/// The first item that an earlier one equals, if any.
fn first_repeated<T: PartialEq>(items: &[T]) -> Option<&T> {
    items
        .iter()
        .enumerate()
        .find_map(|(index, item)| items[..index].contains(item).then_some(item))
}

/// How long to wait for a device: every request's reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct LinkArgs {
    /// How long to wait for each reply from a device, ms.
    #[arg(long, value_name = "MS", default_value_t = 2000)]
    pub timeout_ms: u64,
}

impl Default for LinkArgs {
    fn default() -> Self {
        Self { timeout_ms: 2000 }
    }
}

impl LinkArgs {
    /// The timeout of every request.
    pub fn timeout(&self) -> std::time::Duration {
        std::time::Duration::from_millis(self.timeout_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_port_given_twice_is_refused() {
        let args = MultiBoardArgs::for_ports(vec!["/dev/a".into(), "/dev/a".into()]);
        assert!(args.select_ports().is_err());
        let error = args.refuse_repeats("shown").unwrap_err();
        assert_eq!(
            error.to_string(),
            "/dev/a is given twice: each device is shown once"
        );
        let mut args = MultiBoardArgs::for_ports(vec!["/dev/a".into()]);
        args.serial = vec!["S1".into(), "S2".into(), "S1".into()];
        let error = args.refuse_repeats("recorded").unwrap_err();
        assert_eq!(
            error.to_string(),
            "--serial S1 is given twice: each device is recorded once"
        );
        let args = MultiBoardArgs::for_ports(vec!["/dev/a".into(), "/dev/b".into()]);
        assert_eq!(args.select_ports().unwrap(), ["/dev/a", "/dev/b"]);
    }

    #[test]
    fn the_default_usb_ids_are_the_pads() {
        use clap::Parser;
        #[derive(Parser)]
        struct Probe {
            #[command(flatten)]
            usb: UsbIdArgs,
        }
        let probe = Probe::try_parse_from(["probe"]).unwrap();
        assert_eq!(probe.usb, UsbIdArgs::default());
    }
}
