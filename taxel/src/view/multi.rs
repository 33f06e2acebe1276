//! `taxel view` with several devices (several PORTs, or repeated `--serial`): one reader thread
//! per device stamps every frame with its arrival on one host clock ([`MonotonicClock`]), each
//! device's clock is mapped onto it with a [`ClockMapper`], and the screen shows one section of
//! pad tiles per device ("dev D pad P") and one line per device: connection, sample sets per
//! second and its clock against the host's (offset, drift and the estimated synchronisation
//! error, or "estimating" until the mapper has one).
//!
//! Staleness is judged per device, on the host clock of each frame's arrival, so that devices
//! with different clocks do not make each other stale. A `--layout` names and places device
//! 0's pads; the other devices get the automatic grid. Keys: t tares every device, p pauses,
//! q quits; recording (r, m) and one pad in detail (0-7, --pad) are for one device only.

use std::collections::HashMap;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use anyhow::Context;
use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::{Constraint, Layout as Split, Rect};
use ratatui::style::{Color, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Borders, Paragraph};
use ratatui::{Frame, Terminal};
use wire::{Command, DeviceFrame, InfoFrame};

use super::connection::{open_connection, BoardTarget};
use super::draw::rate_text;
use super::pads::draw_pad_grid;
use super::state::ViewState;
use super::{area_text, note_reply, Pending, ViewArgs, SNAPSHOT_SAMPLES};
use crate::layout::Layout;
use taxel_host::clock_sync::ClockMapper;
use taxel_host::device_link::LinkError;
use taxel_host::multi_record::{HostClock, MonotonicClock};
use taxel_host::timeline_files::format_sync_error_ms;

/// The line of keys in the view of several devices.
pub const KEYS_LINE_DEVICES: &str =
    "keys: t tare every device  p pause  q quit  (r, m, 0-7: one device only)";

/// How often a reader thread asks its device for its counters.
const COUNTERS_INTERVAL: Duration = Duration::from_secs(1);

/// One device of the view of several: what is shown of it and its clock mapping.
#[derive(Debug, Clone)]
pub struct DeviceView {
    /// Its pads, accounting and connection, as the one-device view holds them.
    pub state: ViewState,
    /// Its clock mapped onto the host clock from the frames' arrivals.
    pub clock: ClockMapper,
}

impl DeviceView {
    /// Device `device` on `source`, its pads named "dev D pad P" (or after `layout`).
    pub fn new(device: usize, source: impl Into<String>, layout: Option<Layout>) -> Self {
        let mut state = ViewState::new(source);
        state.device_label = Some(format!("dev {device}"));
        state.layout = layout;
        Self {
            state,
            clock: ClockMapper::new(),
        }
    }

    /// Takes one frame of the device, arrived at `received_at` (host clock), which is
    /// `arrival_us` on the host clock the device clocks are mapped onto.
    pub fn apply_frame_at(&mut self, frame: &DeviceFrame, received_at: Instant, arrival_us: u64) {
        if let DeviceFrame::Sample(sample) = frame {
            self.clock.observe(sample.timestamp_us, arrival_us);
        }
        self.state.apply_frame_at(frame, received_at);
    }

    /// The device's line: connection, sets/s, its clock against the host's, and its status.
    pub fn sync_words(&self, device: usize) -> String {
        let connection = if self.state.connected {
            "connected"
        } else {
            "disconnected"
        };
        let clock = match self.clock.estimate() {
            Some(estimate) => format!(
                "clock {:+.3} s {:+.1} ppm, sync error {} ms",
                estimate.offset_us as f64 / 1e6,
                estimate.drift_ppm,
                format_sync_error_ms(Some(estimate.uncertainty_us))
            ),
            None => "clock estimating".to_owned(),
        };
        let mut words = format!(
            "dev {device}: {connection} {} sets/s, {clock}",
            rate_text(&self.state)
        );
        if !self.state.status.is_empty() {
            words.push_str(&format!(" | {}", self.state.status));
        }
        words
    }
}

/// Everything the view of several devices shows.
#[derive(Debug, Clone)]
pub struct DevicesView {
    /// The devices, in device order (PORTs, then --serial).
    pub devices: Vec<DeviceView>,
    /// The line about the view as a whole (keys refused, pause).
    pub status: String,
    /// Display frozen (samples are still counted).
    pub paused: bool,
}

impl DevicesView {
    /// The devices on `sources`; `layout` applies to device 0.
    pub fn new(sources: Vec<String>, layout: Option<Layout>) -> Self {
        let mut layout = layout;
        let devices = sources
            .into_iter()
            .enumerate()
            .map(|(device, source)| DeviceView::new(device, source, layout.take()))
            .collect();
        Self {
            devices,
            status: String::new(),
            paused: false,
        }
    }

    /// The host clock moved on to `now`: pads that sent nothing since
    /// [`super::STALE_AFTER`] become stale.
    pub fn refresh(&mut self, now: Instant) {
        for device in &mut self.devices {
            device.state.refresh(now);
        }
    }

    /// Whether every device gave at least `samples` sample frames.
    pub fn every_device_has(&self, samples: u64) -> bool {
        self.devices
            .iter()
            .all(|device| device.state.accounting.received() >= samples)
    }

    /// Freezes or unfreezes the display of every device.
    fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        for device in &mut self.devices {
            device.state.paused = paused;
        }
    }
}

/// Draws the view of several devices: a section of tiles per device, then a line per device,
/// the status and the keys.
pub(super) fn draw_devices(frame: &mut Frame, view: &DevicesView) {
    let area = frame.area();
    let outer = Block::default()
        .borders(Borders::ALL)
        .title(format!(" taxel view: {} devices ", view.devices.len()));
    let inner = outer.inner(area);
    frame.render_widget(outer, area);
    let mut text: Vec<Line> = view
        .devices
        .iter()
        .enumerate()
        .map(|(device, shown)| {
            let colour = if shown.state.connected {
                Color::Green
            } else {
                Color::Red
            };
            Line::from(Span::styled(
                shown.sync_words(device),
                Style::default().fg(colour),
            ))
        })
        .collect();
    let mut status = view.status.clone();
    if view.paused {
        status = format!("PAUSED {status}");
    }
    if !status.is_empty() {
        text.push(Line::from(status));
    }
    text.push(Line::from(KEYS_LINE_DEVICES));
    let [sections_area, text_area] =
        Split::vertical([Constraint::Min(1), Constraint::Length(text.len() as u16)]).areas(inner);
    let count = view.devices.len().max(1) as u32;
    let sections =
        Split::vertical(vec![Constraint::Ratio(1, count); count as usize]).split(sections_area);
    for ((device, shown), section) in view.devices.iter().enumerate().zip(sections.iter()) {
        draw_device_section(frame, *section, device, &shown.state);
    }
    // Cut, never wrapped: a wrapped line would push the keys out of the box.
    frame.render_widget(Paragraph::new(text), text_area);
}

fn draw_device_section(frame: &mut Frame, area: Rect, device: usize, state: &ViewState) {
    let layout_name = state
        .layout
        .as_ref()
        .map_or_else(String::new, |layout| format!(" | layout {}", layout.name));
    let block = Block::default()
        .borders(Borders::TOP)
        .title(format!(" dev {device}: {}{layout_name} ", state.source));
    let inner = block.inner(area);
    frame.render_widget(block, area);
    draw_pad_grid(frame, inner, state);
}

/// Renders one frame of the view of several devices into a `width` x `height` text (what a
/// terminal would show, without colours).
pub fn render_devices_to_string(view: &DevicesView, width: u16, height: u16) -> String {
    // The test backend cannot fail.
    let Ok(mut terminal) = Terminal::new(TestBackend::new(width, height));
    let Ok(_) = terminal.draw(|frame| draw_devices(frame, view));
    area_text(terminal.backend())
}

/// What a reader thread tells the view.
enum Report {
    /// Connected (again): the view starts the device's accounting over.
    Connected {
        device: usize,
        source: String,
        info: InfoFrame,
        stale: u64,
        start_request_id: u16,
    },
    /// A frame and its arrival (host clock).
    Frame {
        device: usize,
        frame: DeviceFrame,
        received_at: Instant,
        arrival_us: u64,
    },
    /// A request was sent whose reply the view waits for.
    Sent {
        device: usize,
        request_id: u16,
        pending: Pending,
    },
    /// The link's count of frames that could not be decoded.
    Rejected { device: usize, frames_rejected: u64 },
    /// Not connected, and why.
    Lost { device: usize, message: String },
}

/// What the view asks a reader thread to do.
enum Order {
    /// Tare over this many sample sets.
    Tare(u16),
}

/// What every reader thread shares.
struct ReaderContext<'a> {
    clock: &'a dyn HostClock,
    stop: &'a AtomicBool,
    /// `--once`: one connection attempt, no waiting for a replug.
    once: bool,
}

/// Sleeps `duration` in short steps, returning early when the view stops.
fn pause_unless_stopped(stop: &AtomicBool, duration: Duration) {
    let until = Instant::now() + duration;
    while !stop.load(Ordering::Relaxed) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// One device, connection after connection, until the view stops.
fn read_device(
    device: usize,
    mut target: BoardTarget,
    orders: &Receiver<Order>,
    reports: &Sender<Report>,
    context: &ReaderContext<'_>,
) {
    while !context.stop.load(Ordering::Relaxed) {
        let retry_after = match open_connection(&mut target, Duration::from_millis(20)) {
            Ok(opened) => {
                let mut link = opened.connection.link;
                let connected = Report::Connected {
                    device,
                    source: opened.source,
                    info: opened.info,
                    stale: opened.stale,
                    start_request_id: opened.connection.start_request_id,
                };
                if reports.send(connected).is_err() {
                    return;
                }
                let error = stream(device, &mut link, orders, reports, context);
                let message = match error {
                    Some(error) => format!(
                        "connection lost ({error}); waiting for {}",
                        target.describe()
                    ),
                    None => {
                        // Best effort: the view is ending whether or not the device hears it.
                        let _ = link.send(Command::StopStreaming);
                        return;
                    }
                };
                let _ = reports.send(Report::Lost { device, message });
                Duration::from_millis(200)
            }
            Err(error) => {
                let not_a_port = matches!(
                    error.downcast_ref::<LinkError>(),
                    Some(LinkError::NotSerialPort { .. })
                );
                let message = taxel_host::console::error_message(&error);
                let message = if not_a_port || context.once {
                    message
                } else {
                    format!("waiting for {} ({message})", target.describe())
                };
                let _ = reports.send(Report::Lost { device, message });
                if not_a_port {
                    // Waiting cannot turn a file into a port.
                    return;
                }
                Duration::from_millis(500)
            }
        };
        if context.once {
            return;
        }
        pause_unless_stopped(context.stop, retry_after);
    }
}

/// Passes the device's frames on until the view stops (`None`) or the link fails (its error).
fn stream(
    device: usize,
    link: &mut super::SerialLink,
    orders: &Receiver<Order>,
    reports: &Sender<Report>,
    context: &ReaderContext<'_>,
) -> Option<LinkError> {
    let mut last_counters_request = Instant::now();
    let mut frames_rejected = 0;
    while !context.stop.load(Ordering::Relaxed) {
        match link.next_frame() {
            Ok(Some(frame)) => {
                let report = Report::Frame {
                    device,
                    frame,
                    received_at: Instant::now(),
                    arrival_us: context.clock.now_us(),
                };
                if reports.send(report).is_err() {
                    return None;
                }
            }
            Ok(None) => {}
            Err(error) => return Some(error),
        }
        if link.statistics().frames_rejected != frames_rejected {
            frames_rejected = link.statistics().frames_rejected;
            let _ = reports.send(Report::Rejected {
                device,
                frames_rejected,
            });
        }
        if last_counters_request.elapsed() >= COUNTERS_INTERVAL {
            last_counters_request = Instant::now();
            if let Err(error) = link.send(Command::ReadCounters) {
                return Some(error);
            }
        }
        for order in orders.try_iter() {
            let Order::Tare(sample_sets) = order;
            match link.send(Command::Tare { sample_sets }) {
                Ok(request_id) => {
                    let _ = reports.send(Report::Sent {
                        device,
                        request_id,
                        pending: Pending::Tare,
                    });
                }
                Err(error) => return Some(error),
            }
        }
    }
    None
}

/// Applies one reader thread's report to the view.
fn apply_report(view: &mut DevicesView, pending: &mut [HashMap<u16, Pending>], report: Report) {
    let device = match &report {
        Report::Connected { device, .. }
        | Report::Frame { device, .. }
        | Report::Sent { device, .. }
        | Report::Rejected { device, .. }
        | Report::Lost { device, .. } => *device,
    };
    let (Some(shown), Some(pending)) = (view.devices.get_mut(device), pending.get_mut(device))
    else {
        return;
    };
    match report {
        Report::Connected {
            source,
            info,
            stale,
            start_request_id,
            ..
        } => {
            shown.state.connected_to(source);
            shown.state.info = Some(info);
            shown.state.accounting.stale_discarded(stale);
            // The device may have restarted: its clock is learnt again.
            shown.clock.clear();
            pending.clear();
            pending.insert(start_request_id, Pending::StartStreaming);
        }
        Report::Frame {
            frame,
            received_at,
            arrival_us,
            ..
        } => {
            note_reply(&mut shown.state, pending, &frame);
            shown.apply_frame_at(&frame, received_at, arrival_us);
        }
        Report::Sent {
            request_id,
            pending: what,
            ..
        } => {
            pending.insert(request_id, what);
        }
        Report::Rejected {
            frames_rejected, ..
        } => shown.state.frames_rejected = frames_rejected,
        Report::Lost { message, .. } => shown.state.connection_lost(message),
    }
}

/// The boards `args` name, in device order: the PORTs, then the serial numbers. A port or
/// serial number named twice is refused.
fn targets(args: &ViewArgs) -> anyhow::Result<Vec<BoardTarget>> {
    let board = &args.board;
    board.refuse_repeats("shown")?;
    let by_port = board
        .ports
        .iter()
        .map(|port| BoardTarget::new(Some(port.clone()), None, board.vid, board.pid));
    let by_serial = board
        .serial
        .iter()
        .map(|serial| BoardTarget::new(None, Some(serial.clone()), board.vid, board.pid));
    Ok(by_port.chain(by_serial).collect())
}

/// Runs `taxel view` on several devices (see the module documentation).
pub(super) fn run(args: &ViewArgs, layout: Option<Layout>) -> anyhow::Result<ExitCode> {
    if args.pad.is_some() {
        anyhow::bail!("--pad shows one pad of one device: give one PORT or --serial for it");
    }
    let targets = targets(args)?;
    let mut view = DevicesView::new(targets.iter().map(BoardTarget::describe).collect(), layout);
    for shown in &mut view.devices {
        shown.state.full_scale_kpa = args.full_scale_kpa;
        shown.state.history_s = args.history_s;
    }
    let clock = MonotonicClock::new();
    let stop = AtomicBool::new(false);
    let context = ReaderContext {
        clock: &clock,
        stop: &stop,
        once: args.once,
    };
    let mut pending: Vec<HashMap<u16, Pending>> = vec![HashMap::new(); targets.len()];
    let result = std::thread::scope(|scope| {
        let (report_sender, reports) = mpsc::channel();
        let mut order_senders = Vec::new();
        for (device, target) in targets.into_iter().enumerate() {
            let (order_sender, orders) = mpsc::channel();
            order_senders.push(order_sender);
            let report_sender = report_sender.clone();
            let context = &context;
            scope.spawn(move || read_device(device, target, &orders, &report_sender, context));
        }
        drop(report_sender);
        let result = if args.once {
            collect_snapshot(args, &mut view, &mut pending, &reports);
            Ok(())
        } else {
            live(args, &mut view, &mut pending, &reports, &order_senders)
        };
        stop.store(true, Ordering::Relaxed);
        result
    });
    result?;
    if !args.once {
        return Ok(ExitCode::SUCCESS);
    }
    let text = render_devices_to_string(&view, args.width, args.height);
    taxel_host::console::out(format_args!("{text}")).context("writing the snapshot")?;
    let every_device_sent = view.devices.iter().all(|shown| shown.state.any_sample());
    Ok(if every_device_sent {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// Takes reports until every device gave [`SNAPSHOT_SAMPLES`] samples, every reader ended, or
/// `--timeout-ms` passed.
fn collect_snapshot(
    args: &ViewArgs,
    view: &mut DevicesView,
    pending: &mut [HashMap<u16, Pending>],
    reports: &Receiver<Report>,
) {
    let timeout = Duration::from_millis(args.timeout_ms);
    let deadline = Instant::now() + timeout;
    while !view.every_device_has(SNAPSHOT_SAMPLES) && Instant::now() < deadline {
        match reports.recv_timeout(Duration::from_millis(50)) {
            Ok(report) => apply_report(view, pending, report),
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    view.refresh(Instant::now());
    for shown in &mut view.devices {
        if !shown.state.any_sample() && shown.state.connected {
            shown.state.status = format!("no sample within {} ms", timeout.as_millis());
        }
    }
}

/// The live view of several devices until q.
fn live(
    args: &ViewArgs,
    view: &mut DevicesView,
    pending: &mut [HashMap<u16, Pending>],
    reports: &Receiver<Report>,
    orders: &[Sender<Order>],
) -> anyhow::Result<()> {
    let mut terminal = ratatui::try_init()?;
    let result = live_loop(&mut terminal, args, view, pending, reports, orders);
    ratatui::restore();
    result
}

fn live_loop<B: ratatui::backend::Backend>(
    terminal: &mut Terminal<B>,
    args: &ViewArgs,
    view: &mut DevicesView,
    pending: &mut [HashMap<u16, Pending>],
    reports: &Receiver<Report>,
    orders: &[Sender<Order>],
) -> anyhow::Result<()>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    loop {
        for report in reports.try_iter().take(10_000) {
            apply_report(view, pending, report);
        }
        view.refresh(Instant::now());
        terminal.draw(|frame| draw_devices(frame, view))?;
        if !event::poll(Duration::from_millis(30))? {
            continue;
        }
        let Event::Key(key) = event::read()? else {
            continue;
        };
        if key.kind != KeyEventKind::Press {
            continue;
        }
        match key.code {
            KeyCode::Char('q') | KeyCode::Esc => return Ok(()),
            KeyCode::Char('c') if key.modifiers.contains(KeyModifiers::CONTROL) => return Ok(()),
            KeyCode::Char('p') => view.set_paused(!view.paused),
            KeyCode::Char('t') => {
                for (shown, order) in view.devices.iter_mut().zip(orders) {
                    shown.state.status = if !shown.state.connected {
                        "tare needs a connected device".to_owned()
                    } else if order.send(Order::Tare(args.tare_sets)).is_ok() {
                        format!(
                            "tare running over {} sample sets: keep the pad unloaded",
                            args.tare_sets
                        )
                    } else {
                        "tare not sent: the device's reader ended".to_owned()
                    };
                }
            }
            KeyCode::Char('r' | 'm') => {
                view.status = "recording is for one device in the view: use `taxel record PORT PORT...` for several".to_owned()
            }
            KeyCode::Char('a' | '0'..='7') => {
                view.status = "one pad in detail is for one device in the view".to_owned()
            }
            _ => {}
        }
    }
}
