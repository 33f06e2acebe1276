//! `taxel view`: a live terminal view of one device or several, on the host library: every
//! device is read by its worker ([`taxel_host::worker`]) over a
//! [`taxel_host::session::DeviceSession`], the one stream loop, and recorded by its recorder
//! ([`taxel_host::recorder`]).
//!
//! One device's view: the 2x2 taxels as a heat map with kPa, a colour scale, each taxel's
//! pressure over the last seconds, flags in words, the temperature and its source, the
//! sample-set rate and where every set went. A device with several pads, or a `--layout`
//! ([`crate::layout`]), gets one tile per pad on the layout's grid (`pads`): name, a small heat
//! map with the centre of pressure, force, contact, faults, and stale or missing pads said as
//! such; the number keys (or `--pad N`) show one pad in the detailed view, `a` all of them again.
//! Several devices share the screen ([`DevicesView`]): a section of tiles and a clock line per
//! device, `d` choosing the device whose pad the number keys show in detail.
//!
//! Keys t (tare: the pad shown in detail, else every pad), p (pause), r (record every device), m (marker), q (quit). Unplugging is
//! survived: a device that went away is looked for again (`live`).
//!
//! [`LiveView`] is the engine without a terminal; [`ViewState`] holds what is shown of one
//! device and [`draw`] renders it in the layout the terminal allows; [`render_to_string`] and
//! [`render_devices_to_string`] render one frame into ratatui's `TestBackend`, which is how the
//! view is tested and how `--once` prints a text snapshot.

mod devices;
mod draw;
mod live;
mod pads;
mod record;
mod state;
mod target;

pub use devices::{draw_view, render_devices_to_string, DeviceView, DevicesView};
pub use draw::{
    draw, heat_colour, taxel_flag_words, CHART_MIN_ROWS, KEYS_LINE, KEYS_LINE_DEVICES,
    KEYS_LINE_ONE_OF_SEVERAL, MIN_HEIGHT, MIN_WIDTH, WIDE_HEIGHT, WIDE_WIDTH,
};
pub use live::LiveView;
pub use pads::{CENTRE_MARKER, KEYS_LINE_EVERY_PAD};
pub use record::recording_file_name;
pub use state::{PadFreshness, RecordingStatus, ViewState, STALE_AFTER};

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context;
use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::Rect;
use ratatui::Terminal;

use crate::layout::Layout;
use taxel_args::{LinkArgs, MultiBoardArgs};

/// Sample sets `--once` waits for from every device (for a rate) before it prints, unless its
/// timeout ends first.
const SNAPSHOT_SETS: u64 = 20;

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Live terminal view of one device or several: the 2x2 taxels as \
a heat map with kPa and flags in words, a colour scale with its kPa range, each taxel's pressure \
over the last seconds (faulted samples are gaps), the temperature and its source, and the rates \
with their units: sample sets per second as received, and the converter's conversions per \
second (four conversions make one set).\n\n\
Sample sets are accounted for the connection, as the device's session counts them: received, \
lost on the link (sequence gaps the device's counters do not explain) and dropped by the device \
(its counters since the connection). Frames waiting in the port from before the connection are \
discarded. A view that falls behind skips its oldest sets rather than show old ones, and says \
how many.\n\n\
Keys: t = tare (keep the pad unloaded; every pad of every device, or only the pad shown in \
detail), p = pause (freeze the display), r = \
start/stop recording every device to a file (taxel-YYYYMMDD-HHMMSS.csv in --record-dir, in the \
schema `taxel record` writes, with each device's state in NAME.csv.dev<n>.device.json; no raw \
byte log, which must be set up before a stream starts: use `taxel record` for one), m = drop a \
marker into the recording, 0-7 = one pad in detail, a = all pads, d = the next device (with \
several), q = quit (a recording in progress is saved). A device that goes away ends the \
recording.\n\n\
Screen layouts: heat map and time series side by side from 120x32, and from 80x24 whenever the \
time series below the heat map would be too low to read; stacked when there is room; one line \
per taxel from 40x12 (flags and faults stay visible); smaller terminals get a notice.\n\n\
Several pads: a device with several pads, or a --layout, shows every pad as a tile: its name, \
a 2x2 heat map of its pressures in kPa (FAULT for a faulted taxel, never a number) with the \
centre of pressure marked ◆, its force in N, the centre of pressure in mm, contact (● CONTACT \
or ○ no contact) and its faults and flags in words. A pad without a frame for 0.5 s (host clock, \
or device clock against the other pads) shows STALE and for how long, never its last values; \
while disconnected every pad is stale. Tiles shrink with the terminal (80x24 holds 8 pads); \
below that, or under 80x24, each pad gets one line. Keys 0-7 (or --pad N) show one pad in the \
detailed view above, a = all pads again.\n\n\
--layout gripper|glove|FILE names the pads and places them on a grid. Built in: gripper (pad 0 \
left finger, pad 1 right finger) and glove (a right hand seen from the palm side: little, ring, \
middle and index fingertips on the top row, pads 4 to 1; the palm, pad 5, below the middle \
finger; the thumb, pad 0, below the index). A layout file is TOML:\n\n  \
name = \"two-finger gripper\"\n  \
[[pad]]\n  \
index = 0            # the device's pad index, 0 to 7\n  \
name = \"left finger\"\n  \
column = 0           # grid cell, 0 to 7 from the left\n  \
row = 0              # grid cell, 0 to 7 from the top\n  \
[[pad]]\n  \
index = 1\n  \
name = \"right finger\"\n  \
column = 1\n  \
row = 0\n\n\
Each index at most once, one pad per cell; errors name the line. Pads the layout names that \
the device does not have show \"not on this device\"; the device's pads it does not name are \
added below it. Without --layout, one pad gets the detailed view and several an automatic grid \
(\"pad 0\" to \"pad N-1\", four to a row).\n\n\
Unplugging is survived: the view waits for the board to come back (found again by its serial \
number) and resumes.\n\n--once prints a single text snapshot and exits.\n\n\
Several devices: several PORTs, or --serial repeated (after the PORTs in device order), are read \
at once, each by its own thread, every set stamped with its arrival on one host clock and each \
device's clock mapped onto it (as `taxel record` does). Each device gets a section of tiles \
named \"dev D pad P\" and a line: connected or not, sample sets per second, and its clock's \
offset from the host's, drift in ppm and the estimated synchronisation error in ms (\"clock \
estimating\" until about 2 s of frames came). Staleness is judged per device on the host clock \
of arrival. --layout applies to device 0's pads (\"dev 0 left finger\"); the other devices get \
the automatic grid. d chooses a device (▶), 0-7 show its pad in the detailed view, a all \
devices again; --pad N shows device 0's pad N. --once prints a snapshot after 20 sets from \
every device (or --snapshot-wait-ms).\n\n\
Examples:\n  taxel view /dev/ttyACM0\n  taxel view --once --width 80 --height 24 /dev/ttyACM0\n  \
taxel view --layout gripper /dev/ttyACM0\n  taxel view --layout my-hand.toml --pad 2\n  \
taxel view /dev/ttyACM0 /dev/ttyACM1\n  taxel view --serial 0A1B2C --serial 3D4E5F";

/// Arguments of `taxel view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// The device, or several (one section of tiles each, see the long help).
    #[command(flatten)]
    pub board: MultiBoardArgs,
    /// Print one snapshot of the view as text and exit.
    #[arg(long)]
    pub once: bool,
    /// Snapshot width in columns (--once).
    #[arg(long, value_name = "COLUMNS", default_value_t = 80)]
    pub width: u16,
    /// Snapshot height in rows (--once).
    #[arg(long, value_name = "ROWS", default_value_t = 24)]
    pub height: u16,
    /// Sample sets averaged by the tare key.
    #[arg(long, value_name = "N", default_value_t = 64)]
    pub tare_sets: u16,
    /// Pressure shown as the hottest colour and the top of the time series, kPa.
    #[arg(long, value_name = "KPA", default_value_t = 50.0, value_parser = parse_full_scale_kpa)]
    pub full_scale_kpa: f32,
    /// Seconds of history in the time series (1 to 3600).
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0, value_parser = parse_history_s)]
    pub history_s: f64,
    /// Directory the record key writes recordings to.
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub record_dir: PathBuf,
    /// How long --once waits for the sample sets of its snapshot, ms.
    #[arg(long, value_name = "MS", default_value_t = 3000)]
    pub snapshot_wait_ms: u64,
    /// How long to wait for the devices.
    #[command(flatten)]
    pub link: LinkArgs,
    /// The pads' names and places: a built-in layout (gripper, glove) or a TOML file.
    #[arg(long, value_name = "NAME|FILE")]
    pub layout: Option<String>,
    /// Show this pad (of the first device) in the detailed view (keys 0-7, d and a switch
    /// while running).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(0..8))]
    pub pad: Option<u8>,
}

impl ViewArgs {
    /// The defaults on these ports (what `taxel view PORT...` gets).
    pub fn for_ports(ports: Vec<String>, once: bool) -> Self {
        Self {
            board: MultiBoardArgs::for_ports(ports),
            once,
            width: 80,
            height: 24,
            tare_sets: 64,
            full_scale_kpa: 50.0,
            history_s: 10.0,
            record_dir: PathBuf::from("."),
            snapshot_wait_ms: 3000,
            link: LinkArgs::default(),
            layout: None,
            pad: None,
        }
    }

    /// The defaults on one port (what `taxel view PORT` gets).
    pub fn for_port(port: String, once: bool) -> Self {
        Self::for_ports(vec![port], once)
    }
}

fn area_text(backend: &TestBackend) -> String {
    let buffer = backend.buffer();
    let area: Rect = buffer.area;
    let mut text = String::new();
    for y in area.top()..area.bottom() {
        let mut line = String::new();
        for x in area.left()..area.right() {
            if let Some(cell) = buffer.cell((x, y)) {
                line.push_str(cell.symbol());
            }
        }
        text.push_str(line.trim_end());
        text.push('\n');
    }
    text
}

/// Renders one frame of one device's view into a `width` x `height` text (what a terminal
/// would show, without colours).
pub fn render_to_string(state: &ViewState, width: u16, height: u16) -> String {
    // The test backend cannot fail.
    let Ok(mut terminal) = Terminal::new(TestBackend::new(width, height));
    let Ok(_) = terminal.draw(|frame| draw(frame, state));
    area_text(terminal.backend())
}

/// Runs `taxel view`.
pub fn run(args: &ViewArgs) -> anyhow::Result<ExitCode> {
    // A bad layout is reported before the terminal is taken over.
    let layout = args.layout.as_deref().map(Layout::load).transpose()?;
    if args.once {
        return run_once(args, layout);
    }
    let mut live = LiveView::new(args, layout)?;
    let mut terminal = ratatui::try_init()?;
    let result = live_loop(&mut terminal, &mut live);
    let (_, saved) = live.finish();
    ratatui::restore();
    if let Some(saved) = saved {
        taxel_host::noteln!("{saved}");
    }
    result.map(|()| ExitCode::SUCCESS)
}

/// `--once`: every device opened once, a snapshot after [`SNAPSHOT_SETS`] sets of each (or
/// `--snapshot-wait-ms`). When no device could be opened, that is the error.
fn run_once(args: &ViewArgs, layout: Option<Layout>) -> anyhow::Result<ExitCode> {
    let mut live = LiveView::new(args, layout)?;
    live.tick();
    while live.opening() {
        std::thread::sleep(Duration::from_millis(10));
        live.tick();
    }
    if !live.any_connected() {
        if let Some(error) = live.take_failure() {
            return Err(error);
        }
    }
    let timeout = Duration::from_millis(args.snapshot_wait_ms);
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline
        && live.any_connected()
        && !live.view().every_device_has(SNAPSHOT_SETS)
    {
        std::thread::sleep(Duration::from_millis(10));
        live.tick();
    }
    let (mut view, _) = live.finish();
    for device in &mut view.devices {
        if !device.state.any_sample() && device.state.connected {
            device.state.status = format!("no sample within {} ms", timeout.as_millis());
        }
    }
    let text = render_devices_to_string(&view, args.width, args.height);
    taxel_host::console::out(format_args!("{text}")).context("writing the snapshot")?;
    let every_device_sent = view.devices.iter().all(|device| device.state.any_sample());
    Ok(if every_device_sent {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// The live view in the terminal until q.
fn live_loop<B: ratatui::backend::Backend>(
    terminal: &mut Terminal<B>,
    live: &mut LiveView,
) -> anyhow::Result<()>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    loop {
        live.tick();
        terminal.draw(|frame| draw_view(frame, live.view()))?;
        if !event::poll(Duration::from_millis(30))? {
            continue;
        }
        let Event::Key(key) = event::read()? else {
            continue;
        };
        if key.kind != KeyEventKind::Press {
            continue;
        }
        let key = match key.code {
            KeyCode::Esc => 'q',
            KeyCode::Char('c') if key.modifiers.contains(KeyModifiers::CONTROL) => 'q',
            KeyCode::Char(key) => key,
            _ => continue,
        };
        if !live.press(key) {
            return Ok(());
        }
    }
}

/// `--history-s`: a finite number of seconds from 1 to an hour (the chart's x axis).
fn parse_history_s(text: &str) -> Result<f64, String> {
    let seconds: f64 = text.parse().map_err(|error| format!("{error}"))?;
    if (1.0..=3600.0).contains(&seconds) {
        Ok(seconds)
    } else {
        Err(format!("{text} is not between 1 and 3600 seconds"))
    }
}

/// `--full-scale-kpa`: a finite pressure above 0 (the colour scale and the chart's y axis).
fn parse_full_scale_kpa(text: &str) -> Result<f32, String> {
    let kpa: f32 = text.parse().map_err(|error| format!("{error}"))?;
    if kpa.is_finite() && kpa > 0.0 {
        Ok(kpa)
    } else {
        Err(format!("{text} is not a pressure above 0 kPa"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::style::Color;

    #[test]
    fn history_and_full_scale_must_be_finite_and_positive() {
        assert_eq!(parse_history_s("30"), Ok(30.0));
        for bad in ["inf", "NaN", "0", "-5", "1e9", "ten"] {
            assert!(parse_history_s(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_full_scale_kpa("20"), Ok(20.0));
        for bad in ["inf", "NaN", "0", "-1"] {
            assert!(parse_full_scale_kpa(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn heat_colour_runs_from_cold_to_hot_and_clamps() {
        assert_eq!(heat_colour(0.0, 50.0), Color::Rgb(20, 40, 110));
        assert_eq!(heat_colour(50.0, 50.0), Color::Rgb(210, 30, 30));
        assert_eq!(heat_colour(500.0, 50.0), heat_colour(50.0, 50.0));
        assert_eq!(heat_colour(-5.0, 50.0), heat_colour(0.0, 50.0));
    }
}
