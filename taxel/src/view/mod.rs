//! `taxel view`: a live terminal view of the pad. The 2x2 taxels as a heat map with kPa, a
//! colour scale, each taxel's pressure over the last seconds, flags in words, the temperature
//! and its source, the sample-set rate and where every set went; keys t (tare), p (pause),
//! r (record), m (marker), q (quit). It survives unplug and replug by looking for the board
//! again by serial number.
//!
//! A device with several pads, or a `--layout` ([`crate::layout`]), gets one tile per pad on
//! the layout's grid (`pads`): name, a small heat map with the centre of pressure, force,
//! contact, faults, and stale or missing pads said as such; the number keys (or `--pad N`) show
//! one pad in the detailed view, `a` all of them again.
//!
//! Several devices (several PORTs or `--serial` repeated) are viewed together by `multi`: one
//! reader thread per device, arrivals on one host clock, each device's clock mapped onto it,
//! one section of tiles and one clock line per device ([`DevicesView`]).
//!
//! [`ViewState`] holds what is shown and [`draw`] renders it in the layout the terminal allows;
//! [`render_to_string`] renders one frame into ratatui's `TestBackend`, which is how the view
//! is tested and how `--once` prints a text snapshot.

mod connection;
mod draw;
mod multi;
mod pads;
mod state;

pub use draw::{
    draw, heat_colour, taxel_flag_words, KEYS_LINE, KEYS_LINE_ONE_OF_SEVERAL, MIN_HEIGHT,
    MIN_WIDTH, WIDE_HEIGHT, WIDE_WIDTH,
};
pub use multi::{render_devices_to_string, DeviceView, DevicesView, KEYS_LINE_DEVICES};
pub use pads::{CENTRE_MARKER, KEYS_LINE_EVERY_PAD};
pub use state::{PadFreshness, RecordingStatus, ViewState, STALE_AFTER};

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::Rect;
use ratatui::Terminal;
use wire::{Command, DeviceFrame};

use crate::layout::Layout;
use connection::{connect, BoardTarget, Connection, SerialLink};
use taxel_args::MultiBoardArgs;
use taxel_host::device_link::{DeviceLink, LinkError};
use taxel_host::recording::{read_device_state, BaselineFollower, Recording};

/// Samples `--once` collects (for a rate) before it prints, unless its timeout ends first.
pub(super) const SNAPSHOT_SAMPLES: u64 = 20;

/// How long a request made from the view (device state, baselines) may wait for its reply.
pub(super) const VIEW_REQUEST_TIMEOUT: Duration = Duration::from_millis(1000);

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Live terminal view of the pad: the 2x2 taxels as a heat map \
with kPa and flags in words, a colour scale with its kPa range, each taxel's pressure over the \
last seconds (faulted samples are gaps), the temperature and its source, and the rates with \
their units: sample sets per second as received, and the converter's conversions per second \
(four conversions make one set).\n\n\
Sample sets are accounted for the connection: received, lost on the link (sequence gaps the \
device's counters do not explain) and dropped by the device (its counters since the \
connection). Frames waiting in the port from before the connection are discarded.\n\n\
Keys: t = tare (keep the pad unloaded), p = pause (freeze the display), r = start/stop \
recording to a file (taxel-YYYYMMDD-HHMMSS.csv in --record-dir, with its .device.json, as \
`taxel record` writes), m = drop a marker into the recording, q = quit (a recording in progress \
is finished).\n\n\
Screen layouts: heat map and time series side by side from 120x32, stacked from 80x24, one \
line per taxel from 40x12 (flags and faults stay visible); smaller terminals get a notice.\n\n\
Several pads: a device with several pads, or a --layout, shows every pad as a tile: its name, \
a 2x2 heat map of its pressures in kPa (FAULT for a faulted taxel, never a number) with the \
centre of pressure marked ◆, its force in N, the centre of pressure in mm, contact (● CONTACT \
or ○ no contact) and its faults and flags in words. A pad without a frame for 0.5 s (host clock, \
or device clock against the other pads) shows STALE and for how long, never its last values; \
while disconnected every pad is stale. Tiles shrink with the terminal (80x24 holds 8 pads); \
below that, or under 80x24, each pad gets one line. Keys 0-7 (or --pad N) show one pad in the \
detailed view above, a = all pads again. The record key records every pad, one row per sample \
set (see `taxel record --help`).\n\n\
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
at once, each in its own thread, every frame stamped with its arrival on one host clock and each \
device's clock mapped onto it (as `taxel record` does with several devices). Each device gets a \
section of tiles named \"dev D pad P\" and a line: connected or not, sample sets per second, and \
its clock's offset from the host's, drift in ppm and the estimated synchronisation error in ms \
(\"clock estimating\" until about 2 s of frames came). Staleness is judged per device on the \
host clock of arrival. --layout applies to device 0's pads (\"dev 0 left finger\"); the other \
devices get the automatic grid. Keys: t tares every device, p pauses, q quits; r, m, 0-7 and \
--pad are for one device (they say so). --once prints a snapshot after 20 samples from every \
device (or --timeout-ms).\n\n\
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
    /// How long --once waits for samples, ms.
    #[arg(long, value_name = "MS", default_value_t = 3000)]
    pub timeout_ms: u64,
    /// The pads' names and places: a built-in layout (gripper, glove) or a TOML file.
    #[arg(long, value_name = "NAME|FILE")]
    pub layout: Option<String>,
    /// Show this pad in the detailed view (keys 0-7 and a switch while running).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(0..8))]
    pub pad: Option<u8>,
}

impl ViewArgs {
    /// The view's state before the first frame, as these arguments set it up.
    pub(super) fn initial_state(&self, source: String, layout: Option<Layout>) -> ViewState {
        let mut state = ViewState::new(source);
        state.full_scale_kpa = self.full_scale_kpa;
        state.history_s = self.history_s;
        state.layout = layout;
        state.show_pad(self.pad);
        state
    }

    /// The defaults on one port (what `taxel view PORT` gets).
    pub fn for_port(port: String, once: bool) -> Self {
        Self {
            board: MultiBoardArgs::for_ports(vec![port]),
            once,
            width: 80,
            height: 24,
            tare_sets: 64,
            full_scale_kpa: 50.0,
            history_s: 10.0,
            record_dir: PathBuf::from("."),
            timeout_ms: 3000,
            layout: None,
            pad: None,
        }
    }
}

pub(super) fn area_text(backend: &TestBackend) -> String {
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

/// Renders one frame of the view into a `width` x `height` text (what a terminal would show,
/// without colours).
pub fn render_to_string(state: &ViewState, width: u16, height: u16) -> String {
    // The test backend cannot fail.
    let Ok(mut terminal) = Terminal::new(TestBackend::new(width, height));
    let Ok(_) = terminal.draw(|frame| draw(frame, state));
    area_text(terminal.backend())
}

/// What the loop sent and is waiting to hear about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Pending {
    Tare,
    StartStreaming,
}

fn handle_frame(state: &mut ViewState, pending: &mut HashMap<u16, Pending>, frame: &DeviceFrame) {
    note_reply(state, pending, frame);
    state.apply_frame(frame);
}

/// Says in the status what became of a request the view made (tare, start), if `frame` is
/// its reply.
pub(super) fn note_reply(
    state: &mut ViewState,
    pending: &mut HashMap<u16, Pending>,
    frame: &DeviceFrame,
) {
    if let DeviceFrame::Reply(reply) = frame {
        match (pending.remove(&reply.request_id), &reply.result) {
            (Some(Pending::Tare), Ok(_)) => state.status = "tare done".to_owned(),
            (Some(Pending::Tare), Err(code)) => state.status = format!("tare refused: {code:?}"),
            (Some(Pending::StartStreaming), Err(code)) => {
                state.status = format!("start streaming refused: {code:?}")
            }
            _ => {}
        }
    }
}

/// A recording started from the view.
struct ViewRecording {
    recording: Recording,
    csv_path: PathBuf,
    baselines: BaselineFollower,
}

/// The file name of a recording started now: taxel-YYYYMMDD-HHMMSS.csv (UTC).
pub fn recording_file_name(since_epoch: Duration) -> String {
    let seconds = since_epoch.as_secs();
    let (days, second_of_day) = (seconds / 86_400, seconds % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z.rem_euclid(146_097);
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_index = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * month_index + 2) / 5 + 1;
    let month = if month_index < 10 {
        month_index + 3
    } else {
        month_index - 9
    };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    format!(
        "taxel-{year:04}{month:02}{day:02}-{:02}{:02}{:02}.csv",
        second_of_day / 3600,
        second_of_day / 60 % 60,
        second_of_day % 60
    )
}

fn start_recording<P: Read + Write>(
    directory: &Path,
    link: &mut DeviceLink<P>,
    state: &mut ViewState,
) -> anyhow::Result<ViewRecording> {
    let since_epoch = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    let csv_path = directory.join(recording_file_name(since_epoch));
    if csv_path.exists() {
        anyhow::bail!(
            "{} exists already; try again in a second",
            csv_path.display()
        );
    }
    let pad_count = link
        .pad_count()
        .or(state.info.map(|info| info.pad_count))
        .unwrap_or(1)
        .max(1);
    let (mut recording, _) = Recording::create_with_pads(&csv_path, None, pad_count)?;
    match state.info {
        Some(info) => match read_device_state(link, &info, VIEW_REQUEST_TIMEOUT) {
            Ok(device_state) => recording.set_device_state(device_state),
            Err(error) => {
                state.status = format!(
                    "recording without the device's state ({})",
                    taxel_host::console::error_message(&error)
                )
            }
        },
        None => state.status = "recording without the device's state (no Info yet)".to_owned(),
    }
    state.recording = Some(RecordingStatus {
        file: csv_path.display().to_string(),
        samples: 0,
        markers: 0,
    });
    Ok(ViewRecording {
        recording,
        csv_path,
        baselines: BaselineFollower::default(),
    })
}

fn finish_recording(recording: ViewRecording, state: &mut ViewState) {
    let path = recording.csv_path.display().to_string();
    state.recording = None;
    state.status = match recording.recording.finish(None) {
        Ok(files) => format!(
            "saved {path} ({} samples, {} markers)",
            files.samples, files.markers
        ),
        Err(error) => format!(
            "recording {path} failed: {}",
            taxel_host::console::error_message(&error)
        ),
    };
}

/// Feeds one frame to a recording in progress; an error stops it, keeping what it has.
fn record_frame<P: Read + Write>(
    active: &mut Option<ViewRecording>,
    link: &mut DeviceLink<P>,
    frame: &DeviceFrame,
    state: &mut ViewState,
) {
    let Some(recording) = active.as_mut() else {
        return;
    };
    let result = match frame {
        DeviceFrame::Sample(sample) => {
            recording
                .baselines
                .before_sample(&mut recording.recording, sample);
            recording.recording.write_sample(sample)
        }
        DeviceFrame::Event(event) => {
            if let Err(error) = recording
                .baselines
                .on_event(link, event, VIEW_REQUEST_TIMEOUT)
            {
                state.status = format!(
                    "new baselines not recorded: {}",
                    taxel_host::console::error_message(&error)
                );
            }
            Ok(())
        }
        _ => Ok(()),
    };
    if let (Some(status), Some(recording)) = (state.recording.as_mut(), active.as_ref()) {
        status.samples = recording.recording.samples();
    }
    if let Err(error) = result {
        if let Some(failed) = active.take() {
            let kept = failed.recording.abandon(None);
            state.recording = None;
            state.status = format!(
                "recording stopped: {}; kept {}",
                taxel_host::console::error_message(&error),
                kept.iter()
                    .map(|path| path.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
}

fn live_loop<B: ratatui::backend::Backend>(
    terminal: &mut Terminal<B>,
    args: &ViewArgs,
    layout: Option<Layout>,
) -> anyhow::Result<()>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    let mut target = BoardTarget::single(args);
    let mut state = args.initial_state(target.describe(), layout);
    let mut link: Option<SerialLink> = None;
    let mut pending: HashMap<u16, Pending> = HashMap::new();
    let mut recording: Option<ViewRecording> = None;
    let mut next_attempt = Instant::now();
    let mut retry = true;
    let mut last_counters_request = Instant::now();
    loop {
        if link.is_none() && retry && Instant::now() >= next_attempt {
            match connect(&mut target, Duration::from_millis(20), &mut state) {
                Ok(connection) => {
                    pending.clear();
                    pending.insert(connection.start_request_id, Pending::StartStreaming);
                    link = Some(connection.link);
                }
                Err(error) => {
                    let not_a_port = matches!(
                        error.downcast_ref::<LinkError>(),
                        Some(LinkError::NotSerialPort { .. })
                    );
                    let message = taxel_host::console::error_message(&error);
                    if not_a_port {
                        // Waiting cannot turn a file into a port: say so once and stop trying.
                        retry = false;
                        state.connection_lost(format!("{message}; press q to quit"));
                    } else {
                        state.connection_lost(format!(
                            "waiting for {} ({message})",
                            target.describe()
                        ));
                    }
                    next_attempt = Instant::now() + Duration::from_millis(500);
                }
            }
        }
        if let Some(active) = link.as_mut() {
            let started = Instant::now();
            let mut lost = None;
            while started.elapsed() < Duration::from_millis(30) {
                match active.next_frame() {
                    Ok(Some(frame)) => {
                        handle_frame(&mut state, &mut pending, &frame);
                        record_frame(&mut recording, active, &frame, &mut state);
                    }
                    Ok(None) => break,
                    Err(error) => {
                        lost = Some(error);
                        break;
                    }
                }
            }
            state.frames_rejected = active.statistics().frames_rejected;
            if lost.is_none() && last_counters_request.elapsed() >= Duration::from_secs(1) {
                last_counters_request = Instant::now();
                if let Err(error) = active.send(Command::ReadCounters) {
                    lost = Some(error);
                }
            }
            if let Some(error) = lost {
                if let Some(finished) = recording.take() {
                    finish_recording(finished, &mut state);
                }
                state.connection_lost(format!(
                    "connection lost ({error}); waiting for {}",
                    target.describe()
                ));
                link = None;
                next_attempt = Instant::now() + Duration::from_millis(200);
            }
        }
        state.refresh(Instant::now());
        terminal.draw(|frame| draw(frame, &state))?;
        let wait = if link.is_some() {
            Duration::ZERO
        } else {
            Duration::from_millis(50)
        };
        if !event::poll(wait)? {
            continue;
        }
        let Event::Key(key) = event::read()? else {
            continue;
        };
        if key.kind != KeyEventKind::Press {
            continue;
        }
        match key.code {
            KeyCode::Char('q') | KeyCode::Esc => break,
            KeyCode::Char('c') if key.modifiers.contains(KeyModifiers::CONTROL) => break,
            KeyCode::Char('p') => state.paused = !state.paused,
            KeyCode::Char('a') => state.show_pad(None),
            KeyCode::Char(digit @ '0'..='7') => {
                state.show_pad(digit.to_digit(10).and_then(|pad| u8::try_from(pad).ok()))
            }
            KeyCode::Char('t') => match link.as_mut() {
                Some(active) => match active.send(Command::Tare {
                    sample_sets: args.tare_sets,
                }) {
                    Ok(request_id) => {
                        pending.insert(request_id, Pending::Tare);
                        state.status = format!(
                            "tare running over {} sample sets: keep the pad unloaded",
                            args.tare_sets
                        );
                    }
                    Err(error) => state.status = format!("tare not sent: {error}"),
                },
                None => state.status = "tare needs a connected device".to_owned(),
            },
            KeyCode::Char('r') => match (recording.take(), link.as_mut()) {
                (Some(finished), _) => finish_recording(finished, &mut state),
                (None, Some(active)) => {
                    match start_recording(&args.record_dir, active, &mut state) {
                        Ok(started) => recording = Some(started),
                        Err(error) => {
                            state.status = format!(
                                "cannot record: {}",
                                taxel_host::console::error_message(&error)
                            )
                        }
                    }
                }
                (None, None) => state.status = "recording needs a connected device".to_owned(),
            },
            KeyCode::Char('m') => match (recording.as_mut(), state.recording.as_mut()) {
                (Some(active), Some(status)) => {
                    status.markers += 1;
                    let label = format!("marker {}", status.markers);
                    active.recording.mark(&label);
                    state.status = format!("{label} dropped");
                }
                _ => state.status = "markers go into a recording: press r first".to_owned(),
            },
            _ => {}
        }
    }
    if let Some(finished) = recording.take() {
        finish_recording(finished, &mut state);
    }
    Ok(())
}

/// Reads from an open link until `samples_wanted` samples arrived (or `timeout`; the first
/// sample is enough then) and returns the view state.
pub fn snapshot_state<P: Read + Write>(
    link: &mut DeviceLink<P>,
    state: &mut ViewState,
    samples_wanted: u64,
    timeout: Duration,
) {
    let deadline = Instant::now() + timeout;
    while state.accounting.received() < samples_wanted && Instant::now() < deadline {
        match link.next_frame() {
            Ok(Some(frame)) => state.apply_frame(&frame),
            Ok(None) => {}
            Err(error) => {
                state.connection_lost(format!("connection lost ({error})"));
                break;
            }
        }
    }
    state.frames_rejected = link.statistics().frames_rejected;
    state.refresh(Instant::now());
    if !state.any_sample() && state.connected {
        state.status = format!("no sample within {} ms", timeout.as_millis());
    }
}

/// Runs `taxel view`.
pub fn run(args: &ViewArgs) -> anyhow::Result<ExitCode> {
    // A bad layout is reported before the terminal is taken over.
    let layout = args.layout.as_deref().map(Layout::load).transpose()?;
    if args.board.ports.len() + args.board.serial.len() > 1 {
        return multi::run(args, layout);
    }
    if args.once {
        let mut target = BoardTarget::single(args);
        let mut state = args.initial_state(target.describe(), layout);
        let Connection { mut link, .. } =
            connect(&mut target, Duration::from_millis(50), &mut state)?;
        snapshot_state(
            &mut link,
            &mut state,
            SNAPSHOT_SAMPLES,
            Duration::from_millis(args.timeout_ms),
        );
        let _ = link.send(Command::StopStreaming);
        let text = render_to_string(&state, args.width, args.height);
        taxel_host::console::out(format_args!("{text}")).context("writing the snapshot")?;
        return Ok(if state.any_sample() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        });
    }
    let mut terminal = ratatui::try_init()?;
    let result = live_loop(&mut terminal, args, layout);
    ratatui::restore();
    result.map(|()| ExitCode::SUCCESS)
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
    use wire::ReplyPayload;

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
    fn tare_replies_are_matched_by_request_id() {
        let mut state = ViewState::new("test");
        let mut pending = HashMap::from([(5, Pending::Tare), (6, Pending::Tare)]);
        let reply =
            |request_id, result| DeviceFrame::Reply(wire::ReplyFrame { request_id, result });
        handle_frame(&mut state, &mut pending, &reply(9, Ok(ReplyPayload::Ack)));
        assert_eq!(
            state.status, "connecting",
            "a reply nobody waits for changes nothing"
        );
        handle_frame(&mut state, &mut pending, &reply(5, Ok(ReplyPayload::Ack)));
        assert_eq!(state.status, "tare done");
        handle_frame(
            &mut state,
            &mut pending,
            &reply(6, Err(wire::ErrorCode::Busy)),
        );
        assert_eq!(state.status, "tare refused: Busy");
        assert!(pending.is_empty());
    }

    #[test]
    fn heat_colour_runs_from_cold_to_hot_and_clamps() {
        assert_eq!(heat_colour(0.0, 50.0), Color::Rgb(20, 40, 110));
        assert_eq!(heat_colour(50.0, 50.0), Color::Rgb(210, 30, 30));
        assert_eq!(heat_colour(500.0, 50.0), heat_colour(50.0, 50.0));
        assert_eq!(heat_colour(-5.0, 50.0), heat_colour(0.0, 50.0));
    }

    #[test]
    fn the_record_and_marker_keys_write_a_recording_with_markers() {
        let directory = tempfile::tempdir().unwrap();
        let mut link = DeviceLink::new(std::io::Cursor::new(Vec::new()));
        let mut state = ViewState::new("test");
        let mut active = Some(start_recording(directory.path(), &mut link, &mut state).unwrap());
        let sample = |sequence| {
            DeviceFrame::Sample(wire::SampleFrame {
                pad: wire::PadIndex::default(),
                sequence,
                timestamp_us: u64::from(sequence) * 10_000,
                temperature_c: Some(25.0),
                temperature_source: wire::TemperatureSource::Tmp117,
                taxels: [wire::TaxelSample {
                    pressure_kpa: Some(1.5),
                    capacitance_pf: 4.6,
                    flags: 0,
                }; 4],
                summary: wire::PadSummary::default(),
            })
        };
        record_frame(&mut active, &mut link, &sample(1), &mut state);
        if let Some(recording) = active.as_mut() {
            recording.recording.mark("marker 1");
        }
        record_frame(&mut active, &mut link, &sample(2), &mut state);
        record_frame(&mut active, &mut link, &sample(3), &mut state);
        assert_eq!(
            state.recording.as_ref().map(|status| status.samples),
            Some(3)
        );
        let path = active.as_ref().unwrap().csv_path.clone();
        assert!(
            !path.exists(),
            "the file gets its name when the recording stops"
        );
        finish_recording(active.take().unwrap(), &mut state);
        assert!(state.recording.is_none());
        assert!(state.status.starts_with("saved "), "{}", state.status);
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4);
        assert!(lines[0].ends_with(",marker"));
        assert!(lines[1].ends_with(','));
        assert!(lines[2].ends_with(",marker 1"), "{text}");
        assert!(lines[3].ends_with(','));
    }

    #[test]
    fn recording_names_are_utc_date_and_time() {
        // 2026-11-23 23:11:25 UTC.
        assert_eq!(
            recording_file_name(Duration::from_secs(1_795_475_485)),
            "taxel-20261123-231125.csv"
        );
        assert_eq!(
            recording_file_name(Duration::ZERO),
            "taxel-19700101-000000.csv"
        );
        // A leap day.
        assert_eq!(
            recording_file_name(Duration::from_secs(951_782_400)),
            "taxel-20000229-000000.csv"
        );
    }
}
