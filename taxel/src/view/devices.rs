//! What the view shows of its devices, one or several ([`DevicesView`]), and how it is drawn.
//!
//! One device fills the screen with its own view ([`super::draw`]: the detailed view of a pad,
//! or every pad as a tile). Several devices share it: a section of pad tiles per device ("dev D
//! pad P"), then a line per device — connection, sample sets per second, its clock against the
//! host's (offset, drift and the synchronisation error the stamping policy,
//! [`taxel_host::stamping::Stamper`], would give its sets now, or "estimating" until it has an
//! estimate) — the status and the keys. `d` chooses a device (▶ marks it) and the number keys
//! show one of its pads in the detailed view, as with one device; `a` shows every device again.
//!
//! Staleness is judged per device, on the host clock of each set's arrival, so that devices
//! with different clocks do not make each other stale. A `--layout` names and places device
//! 0's pads; the other devices get the automatic grid.

use ratatui::backend::TestBackend;
use ratatui::layout::{Constraint, Layout as Split, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Borders, Paragraph};
use ratatui::{Frame, Terminal};
use taxel_host::session::SessionEvent;
use taxel_host::stamping::Stamper;
use wire::InfoFrame;

use super::area_text;
use super::draw::{draw, rate_text, too_small, KEYS_LINE_DEVICES};
use super::pads::draw_pad_grid;
use super::state::{RecordingStatus, ViewState};
use crate::layout::{Layout, MAX_PADS};

/// One device of the view: what is shown of it and its clock mapped onto the host's.
#[derive(Debug)]
pub struct DeviceView {
    /// Its pads, accounting and connection.
    pub state: ViewState,
    /// Its clock mapped onto the host clock from its sets' arrivals (the one stamping policy;
    /// only its estimate is used: the view draws what arrives).
    pub clock: Stamper<()>,
}

impl DeviceView {
    /// A device on `source`; `label` ("dev 1") is put before its pads' names when the view
    /// shows several devices.
    pub fn new(source: impl Into<String>, label: Option<String>, layout: Option<Layout>) -> Self {
        let mut state = ViewState::new(source);
        state.device_label = label;
        state.layout = layout;
        Self {
            state,
            clock: Stamper::default(),
        }
    }

    /// Takes one event of the device's session that arrived at `arrival_us` on the host clock.
    pub fn apply_event(&mut self, event: &SessionEvent, arrival_us: u64) {
        if let SessionEvent::Set { set, .. } = event {
            for frame in set.pads.iter().flatten() {
                self.clock.observe(frame.timestamp_us, arrival_us);
            }
        }
        self.state.apply_event(event, arrival_us);
    }

    /// The device is connected (again) on `source`: its accounting and its clock mapping start
    /// over (it may have restarted).
    pub fn connected_to(&mut self, source: impl Into<String>, info: InfoFrame) {
        self.state.connected_to(source);
        self.state.info = Some(info);
        self.clock = Stamper::default();
        self.clock.set_clock_us_per_s(info.clock_us_per_s);
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
                "clock {:+.3} s {:+.1} ppm, sync error {:.3} ms",
                estimate.offset_us as f64 / 1e6,
                estimate.drift_ppm,
                estimate.uncertainty_us as f64 / 1e3
            ),
            None => "clock estimating".to_owned(),
        };
        let mut words = format!(
            "dev {device}: {connection} {} sets/s, {clock}",
            rate_text(&self.state)
        );
        if self.state.view_dropped_sets > 0 {
            words.push_str(&format!(
                ", {} sets skipped by the view",
                self.state.view_dropped_sets
            ));
        }
        if !self.state.status.is_empty() {
            words.push_str(&format!(" | {}", self.state.status));
        }
        words
    }
}

/// Everything the view shows: its devices, which one is chosen, the status, pause and the
/// recording.
#[derive(Debug)]
pub struct DevicesView {
    /// The devices, in device order (PORTs, then --serial).
    pub devices: Vec<DeviceView>,
    /// The line about the view as a whole (recording, keys refused), with several devices.
    pub status: String,
    /// Display frozen (sets are still counted and recorded).
    pub paused: bool,
    /// The device the number keys show a pad of (`d` chooses the next one).
    pub selected: usize,
    /// With several devices, the device whose own view fills the screen (`None`: a section of
    /// tiles per device).
    pub detail: Option<usize>,
    /// The recording in progress, if any.
    pub recording: Option<RecordingStatus>,
}

impl DevicesView {
    /// The devices on `sources`; `layout` applies to device 0. With several devices, each
    /// device's pads are named after it ("dev 1 pad 0").
    pub fn new(sources: Vec<String>, layout: Option<Layout>) -> Self {
        let several = sources.len() > 1;
        let mut layout = layout;
        let devices = sources
            .into_iter()
            .enumerate()
            .map(|(device, source)| {
                let label = several.then(|| format!("dev {device}"));
                DeviceView::new(source, label, layout.take())
            })
            .collect();
        Self {
            devices,
            status: String::new(),
            paused: false,
            selected: 0,
            detail: None,
            recording: None,
        }
    }

    /// The host clock moved on to `now_us`: pads that sent nothing since
    /// [`super::STALE_AFTER`] become stale.
    pub fn refresh(&mut self, now_us: u64) {
        for device in &mut self.devices {
            device.state.refresh(now_us);
        }
    }

    /// Whether every device gave at least `sets` sample sets.
    pub fn every_device_has(&self, sets: u64) -> bool {
        self.devices
            .iter()
            .all(|device| device.state.sets_received() >= sets)
    }

    /// Freezes or unfreezes the display of every device.
    pub fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        for device in &mut self.devices {
            device.state.paused = paused;
        }
    }

    /// Shows the recording in progress (`None`: none) with every device.
    pub fn set_recording(&mut self, recording: Option<RecordingStatus>) {
        for device in &mut self.devices {
            device.state.recording.clone_from(&recording);
        }
        self.recording = recording;
    }

    /// The device whose own view fills the screen: the only one, or the one shown in detail.
    pub fn shown_device(&self) -> Option<usize> {
        if self.devices.len() == 1 {
            Some(0)
        } else {
            self.detail.filter(|device| *device < self.devices.len())
        }
    }

    /// The device and pad the detailed view shows, when it shows one pad: what the tare key
    /// tares then (else every pad of every device).
    pub fn pad_in_detail(&self) -> Option<(usize, u8)> {
        let device = self.shown_device()?;
        let pad = self.devices.get(device)?.state.detail_pad?;
        Some((device, pad))
    }

    /// Says `words` where the screen shows them: the status of the device shown alone, else
    /// the view's status line.
    pub fn say(&mut self, words: impl Into<String>) {
        let words = words.into();
        match self.shown_device() {
            Some(device) => {
                if let Some(shown) = self.devices.get_mut(device) {
                    shown.state.status = words;
                }
            }
            None => self.status = words,
        }
    }

    /// Shows pad `pad` of the chosen device in the detailed view; `None`: every pad of every
    /// device again.
    pub fn show_pad(&mut self, pad: Option<u8>) {
        match pad.filter(|pad| *pad < MAX_PADS) {
            Some(pad) => {
                let selected = self.selected.min(self.devices.len().saturating_sub(1));
                if self.devices.len() > 1 {
                    self.detail = Some(selected);
                }
                if let Some(device) = self.devices.get_mut(selected) {
                    device.state.show_pad(Some(pad));
                }
            }
            None => {
                self.detail = None;
                for device in &mut self.devices {
                    device.state.show_pad(None);
                }
            }
        }
    }

    /// Chooses the next device (with several); a device shown in detail gives way to the next
    /// one, showing the same pad.
    pub fn select_next_device(&mut self) {
        let count = self.devices.len();
        if count < 2 {
            self.say("d chooses one of several devices; this view has one");
            return;
        }
        let pad = self
            .detail
            .and_then(|device| self.devices.get(device))
            .and_then(|device| device.state.detail_pad);
        self.selected = (self.selected + 1) % count;
        if self.detail.is_some() {
            self.detail = Some(self.selected);
            if let (Some(pad), Some(device)) = (pad, self.devices.get_mut(self.selected)) {
                device.state.show_pad(Some(pad));
            }
        }
    }
}

/// Draws the view: the device shown alone in its own view, else a section per device.
pub fn draw_view(frame: &mut Frame, view: &DevicesView) {
    match view
        .shown_device()
        .and_then(|device| view.devices.get(device))
    {
        Some(device) => draw(frame, &device.state),
        None => draw_devices(frame, view),
    }
}

/// The view's status line with several devices: the recording, the pause and the status.
fn status_words(view: &DevicesView) -> Option<Line<'static>> {
    let mut spans = Vec::new();
    if let Some(recording) = &view.recording {
        spans.push(Span::styled(
            format!(
                "● REC {} ({} sets, {} markers)",
                recording.file, recording.sets, recording.markers
            ),
            Style::default().fg(Color::Red).add_modifier(Modifier::BOLD),
        ));
    }
    if view.paused {
        spans.push(Span::styled(
            "PAUSED",
            Style::default().add_modifier(Modifier::BOLD),
        ));
    }
    if !view.status.is_empty() {
        spans.push(Span::raw(view.status.clone()));
    }
    if spans.is_empty() {
        return None;
    }
    let mut line = Vec::new();
    for (index, span) in spans.into_iter().enumerate() {
        if index > 0 {
            line.push(Span::raw(" | "));
        }
        line.push(span);
    }
    Some(Line::from(line))
}

/// Draws a section of tiles per device, then a line per device, the status and the keys.
fn draw_devices(frame: &mut Frame, view: &DevicesView) {
    if too_small(frame) {
        return;
    }
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
    text.extend(status_words(view));
    text.push(Line::from(KEYS_LINE_DEVICES));
    let [sections_area, text_area] =
        Split::vertical([Constraint::Min(1), Constraint::Length(text.len() as u16)]).areas(inner);
    let count = view.devices.len().max(1) as u32;
    let sections =
        Split::vertical(vec![Constraint::Ratio(1, count); count as usize]).split(sections_area);
    for ((device, shown), section) in view.devices.iter().enumerate().zip(sections.iter()) {
        let selected = device == view.selected;
        draw_device_section(frame, *section, device, selected, &shown.state);
    }
    // Cut, never wrapped: a wrapped line would push the keys out of the box.
    frame.render_widget(Paragraph::new(text), text_area);
}

fn draw_device_section(
    frame: &mut Frame,
    area: Rect,
    device: usize,
    selected: bool,
    state: &ViewState,
) {
    let layout_name = state
        .layout
        .as_ref()
        .map_or_else(String::new, |layout| format!(" | layout {}", layout.name));
    let marker = if selected { "▶ " } else { "" };
    let block = Block::default().borders(Borders::TOP).title(format!(
        " {marker}dev {device}: {}{layout_name} ",
        state.source
    ));
    let inner = block.inner(area);
    frame.render_widget(block, area);
    draw_pad_grid(frame, inner, state);
}

/// Renders one frame of the view into a `width` x `height` text (what a terminal would show,
/// without colours).
pub fn render_devices_to_string(view: &DevicesView, width: u16, height: u16) -> String {
    // The test backend cannot fail.
    let Ok(mut terminal) = Terminal::new(TestBackend::new(width, height));
    let Ok(_) = terminal.draw(|frame| draw_view(frame, view));
    area_text(terminal.backend())
}
