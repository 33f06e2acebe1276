//! `taxel list`: the boards attached by USB with the pad's VID:PID, with their serial numbers.

use std::process::ExitCode;

use taxel_host::device_link::{attached_boards, BoardPort};

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "List the boards attached by USB with the pad's VID:PID: port, \
serial number, manufacturer and product. The serial number chooses a board with --serial in \
`record` and `view`, and finds it again after an unplug.\n\n\
Example: taxel list";

/// Arguments of `taxel list`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ListArgs {
    /// The USB ids to look for.
    #[command(flatten)]
    pub usb: taxel_args::UsbIdArgs,
}

/// The listing text: one line per board, or "no board attached".
pub fn listing(boards: &[BoardPort]) -> String {
    if boards.is_empty() {
        return "no board attached\n".to_owned();
    }
    boards
        .iter()
        .map(|board| {
            format!(
                "{}  {:04x}:{:04x}  serial {}  {} {}\n",
                board.port_name,
                board.vid,
                board.pid,
                board.serial_number.as_deref().unwrap_or("(none)"),
                board.manufacturer.as_deref().unwrap_or(""),
                board.product.as_deref().unwrap_or("")
            )
            .replace("  \n", "\n")
        })
        .collect()
}

/// Runs `taxel list`.
pub fn run(args: &ListArgs) -> anyhow::Result<ExitCode> {
    let boards = attached_boards(args.usb.vid, args.usb.pid)?;
    taxel_host::console::out(format_args!("{}", listing(&boards)))?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_listing_says_so() {
        assert_eq!(listing(&[]), "no board attached\n");
        let board = BoardPort {
            port_name: "/dev/ttyACM0".to_owned(),
            vid: 0x1209,
            pid: 0x0001,
            serial_number: Some("0123456789AB".to_owned()),
            manufacturer: Some("taxel".to_owned()),
            product: Some("pad".to_owned()),
        };
        assert_eq!(
            listing(&[board]),
            "/dev/ttyACM0  1209:0001  serial 0123456789AB  taxel pad\n"
        );
    }
}
