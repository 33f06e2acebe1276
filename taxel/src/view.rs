//! `taxel view`: a live terminal view of the pad. The 2x2 taxels as a heat map with kPa, flags
//! in words, the temperature and its source, the frame rate, dropped frames (sequence gaps and
//! the device's counters); keys t (tare), p (pause), q (quit). It survives unplug and replug by
//! looking for the board again by serial number.
//!
//! [`ViewState`] holds what is shown and [`draw`] renders it; [`render_to_string`] renders one
//! frame into ratatui's `TestBackend`, which is how the view is tested and how `--once` prints a
//! text snapshot.

use std::collections::{HashMap, VecDeque};
use std::io::{self, Read, Write};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use model_core::Tier;
use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::{Alignment, Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Borders, Paragraph, Wrap};
use ratatui::{Frame, Terminal};
use wire::{
    Command, CountersFrame, DeviceFrame, InfoFrame, ReplyPayload, SampleFrame, TaxelSample,
};

use crate::csv_format::{format_time_us, temperature_source_words, wire_flag_names, TAXEL_LABELS};
use crate::device_link::{self, attached_boards, choose_board, DeviceLink, LinkError};
use crate::record::{parse_hex_u16, sequence_gap};

/// Samples `--once` collects (for a frame rate) before it prints, unless its timeout ends first.
const SNAPSHOT_SAMPLES: u64 = 20;

/// Sample timestamps kept for the frame-rate estimate.
const RATE_WINDOW: usize = 128;

/// The long help of the subcommand.
pub const LONG_ABOUT: &str =
    "Live terminal view of the pad: the 2x2 taxels as a heat map with kPa and flags in \
words, the temperature and its source, the frame rate and dropped frames (sequence gaps and the \
device's counters).\n\nKeys: t = tare, p = pause (freeze the display), q = quit.\n\n\
Unplugging is survived: the view waits for the board to come back (found again by its serial \
number) and resumes.\n\n--once prints a single text snapshot after the first sample and exits.";

/// Arguments of `taxel view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// Serial port of the device (default: the only attached board, or --serial).
    #[arg(value_name = "PORT")]
    pub port: Option<String>,
    /// Choose the attached board with this USB serial number.
    #[arg(long, value_name = "SN")]
    pub serial: Option<String>,
    /// USB vendor id of the board, for finding it.
    #[arg(long, value_name = "VID", default_value = "0x1209", value_parser = parse_hex_u16)]
    pub vid: u16,
    /// USB product id of the board, for finding it.
    #[arg(long, value_name = "PID", default_value = "0x0001", value_parser = parse_hex_u16)]
    pub pid: u16,
    /// Print one snapshot of the view as text after the first sample and exit.
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
    /// Pressure shown as the hottest colour, kPa.
    #[arg(long, value_name = "KPA", default_value_t = 50.0)]
    pub full_scale_kpa: f32,
    /// How long --once waits for the first sample, ms.
    #[arg(long, value_name = "MS", default_value_t = 3000)]
    pub timeout_ms: u64,
}

/// Everything the view shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewState {
    /// Which port or board is shown.
    pub source: String,
    /// Whether the device is connected.
    pub connected: bool,
    /// The status line (connection, tare progress, errors).
    pub status: String,
    /// Display frozen (samples are still counted).
    pub paused: bool,
    /// The sample on display.
    pub sample: Option<SampleFrame>,
    /// The device's identity, when known.
    pub info: Option<InfoFrame>,
    /// The device's last counters, when known.
    pub counters: Option<CountersFrame>,
    /// Sample frames received.
    pub samples_received: u64,
    /// Sample sets missing from the sequence numbers.
    pub sequence_gap_samples: u64,
    /// Frames that could not be decoded.
    pub frames_rejected: u64,
    /// Pressure drawn in the hottest colour, kPa.
    pub full_scale_kpa: f32,
    last_sequence: Option<u32>,
    recent_timestamps_us: VecDeque<u64>,
}

impl ViewState {
    /// An empty view of `source`.
    pub fn new(source: impl Into<String>) -> Self {
        Self {
            source: source.into(),
            connected: false,
            status: "connecting".to_owned(),
            paused: false,
            sample: None,
            info: None,
            counters: None,
            samples_received: 0,
            sequence_gap_samples: 0,
            frames_rejected: 0,
            full_scale_kpa: 50.0,
            last_sequence: None,
            recent_timestamps_us: VecDeque::new(),
        }
    }

    /// Takes one frame from the device.
    pub fn apply_frame(&mut self, frame: &DeviceFrame) {
        match frame {
            DeviceFrame::Sample(sample) => self.apply_sample(sample),
            DeviceFrame::Info(info) => self.info = Some(*info),
            DeviceFrame::Counters(counters) => self.counters = Some(*counters),
            DeviceFrame::Reply(reply) => match &reply.result {
                Ok(ReplyPayload::Info(info)) => self.info = Some(*info),
                Ok(ReplyPayload::Counters(counters)) => self.counters = Some(*counters),
                _ => {}
            },
            DeviceFrame::Event(event) => {
                self.status = format!(
                    "device event at {} s: {:?}",
                    format_time_us(event.timestamp_us),
                    event.event
                );
            }
        }
    }

    fn apply_sample(&mut self, sample: &SampleFrame) {
        self.samples_received += 1;
        if let Some(previous) = self.last_sequence {
            self.sequence_gap_samples += sequence_gap(previous, sample.sequence);
        }
        self.last_sequence = Some(sample.sequence);
        if self
            .recent_timestamps_us
            .back()
            .is_some_and(|last| sample.timestamp_us <= *last)
        {
            // The device clock went backwards: it restarted.
            self.recent_timestamps_us.clear();
        }
        self.recent_timestamps_us.push_back(sample.timestamp_us);
        while self.recent_timestamps_us.len() > RATE_WINDOW {
            self.recent_timestamps_us.pop_front();
        }
        if !self.paused {
            self.sample = Some(*sample);
        }
    }

    /// Sample frames per second over the recent window, from the device's timestamps.
    pub fn frame_rate_hz(&self) -> Option<f64> {
        let (first, last) = (
            self.recent_timestamps_us.front()?,
            self.recent_timestamps_us.back()?,
        );
        let span_us = last.checked_sub(*first).filter(|span| *span > 0)?;
        Some((self.recent_timestamps_us.len() - 1) as f64 * 1e6 / span_us as f64)
    }

    /// Device-side drops (queue full), from the last counters.
    pub fn device_dropped(&self) -> u64 {
        self.counters
            .map_or(0, |counters| u64::from(counters.dropped_sample_sets))
    }

    /// All dropped sample sets known: sequence gaps plus the device's own count.
    pub fn dropped_total(&self) -> u64 {
        self.sequence_gap_samples + self.device_dropped()
    }

    /// The device is connected (again) on `source`; sequence tracking restarts.
    pub fn connected_to(&mut self, source: impl Into<String>) {
        self.source = source.into();
        self.connected = true;
        self.status.clear();
        self.last_sequence = None;
        self.recent_timestamps_us.clear();
    }

    /// The device went away.
    pub fn connection_lost(&mut self, why: impl Into<String>) {
        self.connected = false;
        self.status = why.into();
    }
}

/// The flags of a taxel in words, "ok" when none.
pub fn taxel_flag_words(taxel: &TaxelSample) -> String {
    let names = wire_flag_names(taxel.flags);
    if names.is_empty() {
        "ok".to_owned()
    } else {
        names.replace('_', " ").replace('|', ", ")
    }
}

/// Heat-map colour: dark blue at 0, through yellow, to red at full scale.
pub fn heat_colour(pressure_kpa: f32, full_scale_kpa: f32) -> Color {
    let fraction = if full_scale_kpa > 0.0 {
        (pressure_kpa / full_scale_kpa).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let blend = |from: (f32, f32, f32), to: (f32, f32, f32), amount: f32| {
        Color::Rgb(
            (from.0 + (to.0 - from.0) * amount) as u8,
            (from.1 + (to.1 - from.1) * amount) as u8,
            (from.2 + (to.2 - from.2) * amount) as u8,
        )
    };
    let (cold, warm, hot) = (
        (20.0, 40.0, 110.0),
        (230.0, 200.0, 40.0),
        (210.0, 30.0, 30.0),
    );
    if fraction < 0.5 {
        blend(cold, warm, fraction * 2.0)
    } else {
        blend(warm, hot, (fraction - 0.5) * 2.0)
    }
}

fn taxel_widget(
    label: &str,
    taxel: Option<&TaxelSample>,
    full_scale_kpa: f32,
    height: u16,
) -> Paragraph<'static> {
    // Three lines of text, centred inside the two border rows.
    let padding = usize::from(height.saturating_sub(2 + 3) / 2);
    let block = Block::default()
        .borders(Borders::ALL)
        .title(format!(" {label} "));
    let Some(taxel) = taxel else {
        let mut lines = vec![Line::from(""); padding + 1];
        lines.push(Line::from("no data"));
        return Paragraph::new(lines)
            .alignment(Alignment::Center)
            .block(block);
    };
    let (headline, style) = match taxel.pressure_kpa {
        Some(pressure_kpa) => {
            let background = heat_colour(pressure_kpa, full_scale_kpa);
            let foreground =
                if pressure_kpa > 0.25 * full_scale_kpa && pressure_kpa < 0.75 * full_scale_kpa {
                    Color::Black
                } else {
                    Color::White
                };
            (
                format!("{pressure_kpa:.2} kPa"),
                Style::default().bg(background).fg(foreground),
            )
        }
        None => (
            "FAULT".to_owned(),
            Style::default()
                .bg(Color::Rgb(50, 50, 50))
                .fg(Color::LightRed),
        ),
    };
    let mut lines = vec![Line::from(""); padding];
    lines.extend([
        Line::from(Span::styled(
            headline,
            Style::default().add_modifier(Modifier::BOLD),
        )),
        Line::from(format!("{:.4} pF", taxel.capacitance_pf)),
        Line::from(taxel_flag_words(taxel)),
    ]);
    Paragraph::new(lines)
        .alignment(Alignment::Center)
        .wrap(Wrap { trim: true })
        .style(style)
        .block(block)
}

fn temperature_line(state: &ViewState) -> String {
    match &state.sample {
        Some(sample) => match sample.temperature_c {
            Some(temperature_c) => format!(
                "Temperature: {temperature_c:.2} °C ({})",
                temperature_source_words(sample.temperature_source)
            ),
            None => format!(
                "Temperature: none ({})",
                temperature_source_words(sample.temperature_source)
            ),
        },
        None => "Temperature: -".to_owned(),
    }
}

fn rate_line(state: &ViewState) -> String {
    let rate = state
        .frame_rate_hz()
        .map_or_else(|| "-".to_owned(), |rate| format!("{rate:.1}"));
    format!(
        "Frames: {rate}/s, {} received, {} dropped (gaps {}, device {}), {} bad",
        state.samples_received,
        state.dropped_total(),
        state.sequence_gap_samples,
        state.device_dropped(),
        state.frames_rejected
    )
}

fn device_line(state: &ViewState) -> String {
    match &state.info {
        Some(info) => format!(
            "Device: firmware {}.{}.{}, calibration {} ({:?}), tier {}, {}/s",
            info.firmware_version.major,
            info.firmware_version.minor,
            info.firmware_version.patch,
            info.calibration_id,
            info.calibration_source,
            Tier::from_id(info.model_tier).map_or("unknown", Tier::name),
            info.rate_sps
        ),
        None => "Device: -".to_owned(),
    }
}

/// Draws the whole view.
pub fn draw(frame: &mut Frame, state: &ViewState) {
    let outer = Block::default()
        .borders(Borders::ALL)
        .title(format!(" taxel view: {} ", state.source));
    let inner = outer.inner(frame.area());
    frame.render_widget(outer, frame.area());
    let [map_area, text_area] =
        Layout::vertical([Constraint::Min(6), Constraint::Length(5)]).areas(inner);
    let rows = Layout::vertical([Constraint::Ratio(1, 2), Constraint::Ratio(1, 2)]).split(map_area);
    for (row_index, row) in rows.iter().enumerate() {
        let cells =
            Layout::horizontal([Constraint::Ratio(1, 2), Constraint::Ratio(1, 2)]).split(*row);
        for (column_index, cell) in cells.iter().enumerate() {
            let taxel = row_index * 2 + column_index;
            let sample = state.sample.as_ref().map(|sample| &sample.taxels[taxel]);
            frame.render_widget(
                taxel_widget(
                    TAXEL_LABELS[taxel],
                    sample,
                    state.full_scale_kpa,
                    cell.height,
                ),
                *cell,
            );
        }
    }
    let connection = if state.connected {
        Span::styled("connected", Style::default().fg(Color::Green))
    } else {
        Span::styled("disconnected", Style::default().fg(Color::Red))
    };
    let mut status_spans = vec![connection];
    if state.paused {
        status_spans.push(Span::raw(" | "));
        status_spans.push(Span::styled(
            "PAUSED",
            Style::default().add_modifier(Modifier::BOLD),
        ));
    }
    if !state.status.is_empty() {
        status_spans.push(Span::raw(" | "));
        status_spans.push(Span::raw(state.status.clone()));
    }
    let lines = vec![
        Line::from(temperature_line(state)),
        Line::from(rate_line(state)),
        Line::from(device_line(state)),
        Line::from(status_spans),
        Line::from("keys: t tare   p pause   q quit"),
    ];
    frame.render_widget(Paragraph::new(lines), text_area);
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

/// Renders one frame of the view into a `width` x `height` text (what a terminal would show,
/// without colours).
pub fn render_to_string(state: &ViewState, width: u16, height: u16) -> String {
    let Ok(mut terminal) = Terminal::new(TestBackend::new(width, height));
    let Ok(_) = terminal.draw(|frame| draw(frame, state));
    area_text(terminal.backend())
}

/// How to find the board again after an unplug.
#[derive(Debug, Clone)]
struct BoardTarget {
    path: Option<String>,
    serial_number: Option<String>,
    vid: u16,
    pid: u16,
}

impl BoardTarget {
    fn new(args: &ViewArgs) -> Self {
        let mut target = Self {
            path: args.port.clone(),
            serial_number: args.serial.clone(),
            vid: args.vid,
            pid: args.pid,
        };
        if target.serial_number.is_none() {
            if let Some(path) = &target.path {
                // Knowing the serial number lets a replugged board be found under a new name.
                target.serial_number = attached_boards(args.vid, args.pid)
                    .ok()
                    .and_then(|boards| boards.into_iter().find(|board| &board.port_name == path))
                    .and_then(|board| board.serial_number);
            }
        }
        target
    }

    fn describe(&self) -> String {
        match (&self.serial_number, &self.path) {
            (Some(serial), _) => format!("board {serial}"),
            (None, Some(path)) => path.clone(),
            (None, None) => format!("a board {:04x}:{:04x}", self.vid, self.pid),
        }
    }

    fn find(&mut self) -> Result<String, LinkError> {
        if self.serial_number.is_some() || self.path.is_none() {
            let boards = attached_boards(self.vid, self.pid)?;
            match choose_board(&boards, self.serial_number.as_deref(), self.vid, self.pid) {
                Ok(board) => {
                    if self.serial_number.is_none() {
                        self.serial_number = board.serial_number.clone();
                    }
                    return Ok(board.port_name);
                }
                Err(error) if self.path.is_none() => return Err(error),
                Err(_) => {}
            }
        }
        match &self.path {
            Some(path) if std::path::Path::new(path).exists() => Ok(path.clone()),
            Some(path) => Err(LinkError::PortMissing { path: path.clone() }),
            None => Err(LinkError::NoBoard {
                vid: self.vid,
                pid: self.pid,
            }),
        }
    }
}

type SerialLink = DeviceLink<Box<dyn serialport::SerialPort>>;

/// An open link that has asked for the device's identity and for streaming; the request id of
/// StartStreaming comes back with it.
struct Connection {
    path: String,
    link: SerialLink,
    start_request_id: u16,
}

fn connect(target: &mut BoardTarget, read_timeout: Duration) -> Result<Connection, LinkError> {
    let path = target.find()?;
    // A pseudo-terminal has no DTR line; a real board that misses it shows up as silence.
    let port = device_link::open_serial(&path, read_timeout)?.port;
    let mut link = DeviceLink::new(port);
    link.send(Command::Info)?;
    let start_request_id = link.send(Command::StartStreaming)?;
    Ok(Connection {
        path,
        link,
        start_request_id,
    })
}

/// What the loop sent and is waiting to hear about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pending {
    Tare,
    StartStreaming,
}

fn handle_frame(state: &mut ViewState, pending: &mut HashMap<u16, Pending>, frame: &DeviceFrame) {
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
    state.apply_frame(frame);
}

fn live_loop<B: ratatui::backend::Backend>(
    terminal: &mut Terminal<B>,
    args: &ViewArgs,
) -> anyhow::Result<()>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    let mut target = BoardTarget::new(args);
    let mut state = ViewState::new(target.describe());
    state.full_scale_kpa = args.full_scale_kpa;
    let mut link: Option<SerialLink> = None;
    let mut pending: HashMap<u16, Pending> = HashMap::new();
    let mut next_attempt = Instant::now();
    let mut last_counters_request = Instant::now();
    loop {
        if link.is_none() && Instant::now() >= next_attempt {
            match connect(&mut target, Duration::from_millis(20)) {
                Ok(connection) => {
                    state.connected_to(format!("{} ({})", connection.path, target.describe()));
                    pending.clear();
                    pending.insert(connection.start_request_id, Pending::StartStreaming);
                    link = Some(connection.link);
                }
                Err(error) => {
                    state.connection_lost(format!(
                        "waiting for {} to be plugged in ({error})",
                        target.describe()
                    ));
                    next_attempt = Instant::now() + Duration::from_millis(500);
                }
            }
        }
        if let Some(active) = link.as_mut() {
            let started = Instant::now();
            let mut lost = None;
            while started.elapsed() < Duration::from_millis(30) {
                match active.next_frame() {
                    Ok(Some(frame)) => handle_frame(&mut state, &mut pending, &frame),
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
                state.connection_lost(format!(
                    "connection lost ({error}); waiting for {}",
                    target.describe()
                ));
                link = None;
                next_attempt = Instant::now() + Duration::from_millis(200);
            }
        }
        terminal.draw(|frame| draw(frame, &state))?;
        let wait = if link.is_some() {
            Duration::ZERO
        } else {
            Duration::from_millis(50)
        };
        if event::poll(wait)? {
            if let Event::Key(key) = event::read()? {
                if key.kind != KeyEventKind::Press {
                    continue;
                }
                match key.code {
                    KeyCode::Char('q') | KeyCode::Esc => return Ok(()),
                    KeyCode::Char('c') if key.modifiers.contains(KeyModifiers::CONTROL) => {
                        return Ok(())
                    }
                    KeyCode::Char('p') => state.paused = !state.paused,
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
                    _ => {}
                }
            }
        }
    }
}

/// Reads from an open link until `samples_wanted` samples arrived (or `timeout`; the first
/// sample is enough then) and returns the view state.
pub fn snapshot_state<P: Read + Write>(
    link: &mut DeviceLink<P>,
    source: &str,
    samples_wanted: u64,
    timeout: Duration,
) -> ViewState {
    let mut state = ViewState::new(source);
    state.connected_to(source);
    let deadline = Instant::now() + timeout;
    while state.samples_received < samples_wanted && Instant::now() < deadline {
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
    if state.sample.is_none() && state.connected {
        state.status = format!("no sample within {} ms", timeout.as_millis());
    }
    state
}

/// Runs `taxel view`.
pub fn run(args: &ViewArgs) -> anyhow::Result<ExitCode> {
    if args.once {
        let mut target = BoardTarget::new(args);
        let Connection { path, mut link, .. } = connect(&mut target, Duration::from_millis(50))?;
        let mut state = snapshot_state(
            &mut link,
            &path,
            SNAPSHOT_SAMPLES,
            Duration::from_millis(args.timeout_ms),
        );
        state.full_scale_kpa = args.full_scale_kpa;
        let _ = link.send(Command::StopStreaming);
        let text = render_to_string(&state, args.width, args.height);
        let mut stdout = io::stdout().lock();
        stdout.write_all(text.as_bytes())?;
        stdout.flush()?;
        return Ok(if state.sample.is_some() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        });
    }
    let mut terminal = ratatui::try_init()?;
    let result = live_loop(&mut terminal, args);
    ratatui::restore();
    result.map(|()| ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
