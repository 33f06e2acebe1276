//! Drawing one device's view: three layouts chosen by the terminal's size, every number with
//! its unit.
//!
//! - side by side (at least [`WIDE_WIDTH`] x [`WIDE_HEIGHT`], and from 80 x 24 whenever the
//!   time series below the heat map would get fewer than [`CHART_MIN_ROWS`] rows): the 2x2
//!   heat map and its colour scale on the left, each taxel's pressure over the last seconds on
//!   the right, as tall as the heat map (16 rows at 80 x 24);
//! - stacked (at least 80 x 24 with room): the heat map, the colour scale, the time series
//!   below it;
//! - compact (at least [`MIN_WIDTH`] x [`MIN_HEIGHT`]): one line per taxel with its pressure,
//!   flags and faults, for small terminals;
//! - smaller than that: a notice saying how much room the view needs.
//!
//! On a device with several pads, or with a layout, these show one pad (`--pad N` or the number
//! keys) and name it in the title; the view of every pad is drawn by [`super::pads`].

use ratatui::layout::{Alignment, Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{
    Axis, Block, Borders, Chart, Dataset, GraphType, LegendPosition, Paragraph, Wrap,
};
use ratatui::Frame;
use wire::TaxelSample;

use super::state::{PadFreshness, ViewState};
use taxel_host::csv_format::{temperature_source_words, wire_flag_names, TAXEL_LABELS};
use taxel_host::device_words::{calibration_source_words, info_words, tier_words};

/// The smallest terminal the view draws in.
pub const MIN_WIDTH: u16 = 40;
/// The smallest terminal the view draws in.
pub const MIN_HEIGHT: u16 = 12;
/// From this size on, the heat map and the time series sit side by side.
pub const WIDE_WIDTH: u16 = 120;
/// From this size on, the heat map and the time series sit side by side.
pub const WIDE_HEIGHT: u16 = 32;
/// The fewest rows the time series gets, its border included (six rows of points, the axis and
/// its labels): below the heat map when that leaves it this many, else beside it.
pub const CHART_MIN_ROWS: u16 = 10;
/// Rows of the heat map when it sits above the time series: five per taxel, its border and
/// three lines (pressure, capacitance, flags).
const STACKED_MAP_ROWS: u16 = 10;

/// The line of keys.
pub const KEYS_LINE: &str = "keys: t tare  p pause  r record  m marker  q quit";

/// The line of keys when one of several pads is shown in detail.
pub const KEYS_LINE_ONE_OF_SEVERAL: &str =
    "keys: t tare  p pause  r record  m marker  q quit  a all pads  0-7 pad";

/// The line of keys in the view of several devices (`d` chooses the device the number keys
/// show a pad of).
pub const KEYS_LINE_DEVICES: &str =
    "keys: t tare  p pause  r record  m marker  q quit  d device  0-7 pad  a all";

/// Colours of the four taxels in the time series.
const TAXEL_COLOURS: [Color; 4] = [Color::Cyan, Color::Yellow, Color::Magenta, Color::Green];

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

/// The style of a pressure cell: its heat colour, or grey with red text for a fault.
pub(super) fn pressure_style(pressure_kpa: Option<f32>, full_scale_kpa: f32) -> Style {
    match pressure_kpa {
        Some(pressure_kpa) => {
            let foreground =
                if pressure_kpa > 0.25 * full_scale_kpa && pressure_kpa < 0.75 * full_scale_kpa {
                    Color::Black
                } else {
                    Color::White
                };
            Style::default()
                .bg(heat_colour(pressure_kpa, full_scale_kpa))
                .fg(foreground)
        }
        None => Style::default()
            .bg(Color::Rgb(50, 50, 50))
            .fg(Color::LightRed),
    }
}

fn pressure_text(pressure_kpa: Option<f32>) -> String {
    match pressure_kpa {
        Some(pressure_kpa) => format!("{pressure_kpa:.2} kPa"),
        None => "FAULT".to_owned(),
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
    let mut lines = vec![Line::from(""); padding];
    lines.extend([
        Line::from(Span::styled(
            pressure_text(taxel.pressure_kpa),
            Style::default().add_modifier(Modifier::BOLD),
        )),
        Line::from(format!("{:.4} pF", taxel.capacitance_pf)),
        Line::from(taxel_flag_words(taxel)),
    ]);
    Paragraph::new(lines)
        .alignment(Alignment::Center)
        .wrap(Wrap { trim: true })
        .style(pressure_style(taxel.pressure_kpa, full_scale_kpa))
        .block(block)
}

fn draw_heat_map(frame: &mut Frame, area: Rect, state: &ViewState) {
    let rows = Layout::vertical([Constraint::Ratio(1, 2), Constraint::Ratio(1, 2)]).split(area);
    for (row_index, row) in rows.iter().enumerate() {
        let cells =
            Layout::horizontal([Constraint::Ratio(1, 2), Constraint::Ratio(1, 2)]).split(*row);
        for (column_index, cell) in cells.iter().enumerate() {
            let taxel = row_index * 2 + column_index;
            let sample = state
                .sample
                .as_ref()
                .and_then(|sample| sample.taxels.get(taxel));
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
}

/// The colour scale: a bar from 0 to full scale with its range in kPa.
fn colour_scale(state: &ViewState, width: u16) -> Line<'static> {
    let full_scale_kpa = state.full_scale_kpa;
    let start = "scale (kPa): 0 ".to_owned();
    let end = format!(" {full_scale_kpa:.0}");
    let bar_width = usize::from(width)
        .saturating_sub(start.len() + end.len())
        .min(40);
    let mut spans = vec![Span::raw(start)];
    for cell in 0..bar_width {
        let pressure_kpa = full_scale_kpa * (cell as f32 + 0.5) / bar_width.max(1) as f32;
        spans.push(Span::styled(
            " ",
            Style::default().bg(heat_colour(pressure_kpa, full_scale_kpa)),
        ));
    }
    spans.push(Span::raw(end));
    Line::from(spans)
}

fn draw_time_series(frame: &mut Frame, area: Rect, state: &ViewState) {
    let series: Vec<Vec<(f64, f64)>> = (0..TAXEL_LABELS.len())
        .map(|taxel| state.history_of(taxel))
        .collect();
    let datasets: Vec<Dataset> = series
        .iter()
        .zip(TAXEL_LABELS)
        .zip(TAXEL_COLOURS)
        .map(|((points, label), colour)| {
            Dataset::default()
                .name(label)
                .marker(Marker::Braille)
                // Points, not lines: a faulted sample is a gap, never a line through it.
                .graph_type(GraphType::Scatter)
                .style(Style::default().fg(colour))
                .data(points)
        })
        .collect();
    let history_s = state.history_s.max(1.0);
    let full_scale_kpa = f64::from(state.full_scale_kpa.max(1.0));
    let chart = Chart::new(datasets)
        .block(
            Block::default()
                .borders(Borders::ALL)
                .title(format!(" pressure (kPa), last {history_s:.0} s ")),
        )
        .x_axis(
            Axis::default()
                .bounds([-history_s, 0.0])
                .labels([format!("-{history_s:.0} s"), "now".to_owned()]),
        )
        .y_axis(Axis::default().bounds([0.0, full_scale_kpa]).labels([
            "0".to_owned(),
            format!("{:.0}", full_scale_kpa / 2.0),
            format!("{full_scale_kpa:.0}"),
        ]))
        // Top left: the newest points are on the right.
        .legend_position(Some(LegendPosition::TopLeft))
        .hidden_legend_constraints((Constraint::Ratio(1, 2), Constraint::Ratio(1, 2)));
    frame.render_widget(chart, area);
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

/// The pad's force, centre of pressure and contact as the device computed them.
fn force_line(state: &ViewState) -> String {
    let Some(sample) = &state.sample else {
        return "Force: -".to_owned();
    };
    let summary = &sample.summary;
    let Some(force_n) = summary.force_n else {
        return "Force: none (no taxel reads)".to_owned();
    };
    let mut line = format!("Force: {force_n:.3} N");
    if let Some([x_mm, y_mm]) = summary.centre_of_pressure_mm {
        line.push_str(&format!(" at ({x_mm:.1}, {y_mm:.1}) mm"));
    }
    line.push_str(if summary.contact {
        ", in contact"
    } else {
        ", no contact"
    });
    if summary.partial {
        line.push_str(" (faulted taxels left out)");
    }
    line
}

/// The force in a few characters, for the compact layout.
fn force_text(state: &ViewState) -> String {
    match state.sample.as_ref().map(|sample| &sample.summary) {
        Some(summary) => match summary.force_n {
            Some(force_n) => format!(
                "{force_n:.2} N{}",
                if summary.contact { " contact" } else { "" }
            ),
            None => "- N".to_owned(),
        },
        None => "- N".to_owned(),
    }
}

pub(super) fn rate_text(state: &ViewState) -> String {
    state
        .sample_set_rate_hz()
        .map_or_else(|| "-".to_owned(), |rate| format!("{rate:.1}"))
}

/// Where every sample set of this connection went.
pub(super) fn accounting_line(state: &ViewState) -> String {
    let accounting = &state.accounting;
    let mut line = format!(
        "{} received, {} lost on link, {} dropped by device, {} bad frames",
        accounting.received(),
        accounting.lost_on_link(),
        accounting.device_dropped(),
        state.frames_rejected
    );
    if accounting.stale_frames() > 0 {
        line.push_str(&format!(", {} stale", accounting.stale_frames()));
    }
    if state.view_dropped_sets > 0 {
        line.push_str(&format!(
            ", {} sets skipped by the view",
            state.view_dropped_sets
        ));
    }
    line
}

/// The device in words: all of it when there is room, the essentials otherwise.
pub(super) fn device_line(state: &ViewState, wide: bool) -> String {
    match &state.info {
        Some(info) if wide => format!("Device: {}", info_words(info)),
        Some(info) => {
            let version = info.firmware_version;
            format!(
                "Device: fw {}.{}.{}, cal. {} ({}), {}, {} conversions/s",
                version.major,
                version.minor,
                version.patch,
                info.calibration_id,
                calibration_source_words(info.calibration_source),
                tier_words(info.model_tier),
                info.rate.sps()
            )
        }
        None => "Device: -".to_owned(),
    }
}

pub(super) fn status_line(state: &ViewState) -> Line<'static> {
    let connection = if state.connected {
        Span::styled("connected", Style::default().fg(Color::Green))
    } else {
        Span::styled("disconnected", Style::default().fg(Color::Red))
    };
    let mut spans = vec![connection];
    if let Some(recording) = &state.recording {
        spans.push(Span::raw(" | "));
        spans.push(Span::styled(
            format!(
                "● REC {} ({} sets, {} markers)",
                recording.file, recording.sets, recording.markers
            ),
            Style::default().fg(Color::Red).add_modifier(Modifier::BOLD),
        ));
    }
    if state.paused {
        spans.push(Span::raw(" | "));
        spans.push(Span::styled(
            "PAUSED",
            Style::default().add_modifier(Modifier::BOLD),
        ));
    }
    if !state.status.is_empty() {
        spans.push(Span::raw(" | "));
        spans.push(Span::raw(state.status.clone()));
    }
    Line::from(spans)
}

fn text_lines(state: &ViewState, wide: bool) -> Vec<Line<'static>> {
    vec![
        Line::from(format!(
            "{}   Samples: {} sets/s",
            temperature_line(state),
            rate_text(state)
        )),
        Line::from(force_line(state)),
        Line::from(accounting_line(state)),
        Line::from(device_line(state, wide)),
        status_line(state),
        Line::from(keys_line(state)),
    ]
}

/// The keys of the detailed view: with several devices, with several pads, or of one pad.
fn keys_line(state: &ViewState) -> &'static str {
    if state.device_label.is_some() {
        KEYS_LINE_DEVICES
    } else if state.several_pads() {
        KEYS_LINE_ONE_OF_SEVERAL
    } else {
        KEYS_LINE
    }
}

/// One line per taxel for small terminals: label, pressure (or FAULT) in its colour, flags.
fn compact_lines(state: &ViewState) -> Vec<Line<'static>> {
    let mut lines: Vec<Line> = TAXEL_LABELS
        .iter()
        .enumerate()
        .map(|(taxel, label)| {
            match state
                .sample
                .as_ref()
                .and_then(|sample| sample.taxels.get(taxel))
            {
                Some(sample) => Line::from(vec![
                    Span::raw(format!("{label} ")),
                    Span::styled(
                        format!("{:>10}", pressure_text(sample.pressure_kpa)),
                        pressure_style(sample.pressure_kpa, state.full_scale_kpa),
                    ),
                    Span::raw(format!(" {}", taxel_flag_words(sample))),
                ]),
                None => Line::from(format!("{label} no data")),
            }
        })
        .collect();
    let temperature = match state
        .sample
        .as_ref()
        .and_then(|sample| sample.temperature_c)
    {
        Some(temperature_c) => format!("{temperature_c:.2} °C"),
        None => "- °C".to_owned(),
    };
    lines.push(Line::from(format!(
        "{temperature}  {}  {} sets/s",
        force_text(state),
        rate_text(state)
    )));
    lines.push(Line::from(format!(
        "{} lost on link, {} dropped by device",
        state.accounting.lost_on_link(),
        state.accounting.device_dropped()
    )));
    lines.push(status_line(state));
    lines.push(Line::from(if state.device_label.is_some() {
        "t tare p pause r rec m mark q quit a all d dev"
    } else if state.several_pads() {
        "t tare p pause r rec m mark q quit a all"
    } else {
        "t tare p pause r rec m mark q quit"
    }));
    lines
}

/// The title: the source, and on a device with several pads the pad shown and whether it is
/// live.
fn title(state: &ViewState) -> String {
    if !state.several_pads() && state.detail_pad.unwrap_or(0) == 0 {
        return match &state.device_label {
            Some(label) => format!(" taxel view: {label}: {} ", state.source),
            None => format!(" taxel view: {} ", state.source),
        };
    }
    let pad = state.detail_pad.unwrap_or(0);
    let freshness = match state.pad_freshness(pad) {
        PadFreshness::Live => String::new(),
        PadFreshness::NoData => ", no data".to_owned(),
        PadFreshness::NotOnDevice => ", not on this device".to_owned(),
        PadFreshness::Stale { age_s } => format!(", STALE: no frame for {age_s:.1} s"),
    };
    format!(
        " taxel view: {} | pad {pad}: {}{freshness} ",
        state.source,
        state.pad_name(pad)
    )
}

/// Draws a notice instead of the view when the terminal is smaller than [`MIN_WIDTH`] x
/// [`MIN_HEIGHT`]; says whether it did.
pub(super) fn too_small(frame: &mut Frame) -> bool {
    let area = frame.area();
    if area.width >= MIN_WIDTH && area.height >= MIN_HEIGHT {
        return false;
    }
    let notice = format!(
        "terminal too small: the view needs at least {MIN_WIDTH}x{MIN_HEIGHT}, this one is {}x{}",
        area.width, area.height
    );
    frame.render_widget(Paragraph::new(notice).wrap(Wrap { trim: true }), area);
    true
}

/// Draws one device's view in the layout the terminal's size allows.
pub fn draw(frame: &mut Frame, state: &ViewState) {
    if too_small(frame) {
        return;
    }
    let area = frame.area();
    if state.shows_every_pad() {
        super::pads::draw_every_pad(frame, area, state);
        return;
    }
    let outer = Block::default().borders(Borders::ALL).title(title(state));
    let inner = outer.inner(area);
    frame.render_widget(outer, area);
    if area.width < 80 || area.height < 24 {
        frame.render_widget(
            Paragraph::new(compact_lines(state)).wrap(Wrap { trim: true }),
            inner,
        );
        return;
    }
    let wide = area.width >= WIDE_WIDTH && area.height >= WIDE_HEIGHT;
    let text = text_lines(state, wide);
    // The wide layout spells the device out in full, which may take a second line.
    let text_rows = text.len() as u16 + u16::from(wide);
    let [main_area, text_area] =
        Layout::vertical([Constraint::Min(9), Constraint::Length(text_rows)]).areas(inner);
    let paragraph = if wide {
        Paragraph::new(text).wrap(Wrap { trim: true })
    } else {
        // Cut, never wrapped: a wrapped line would push the keys out of the box.
        Paragraph::new(text)
    };
    frame.render_widget(paragraph, text_area);
    let stacked = !wide && main_area.height >= STACKED_MAP_ROWS + 1 + CHART_MIN_ROWS;
    if stacked {
        let [map_area, scale_area, series_area] = Layout::vertical([
            Constraint::Length(STACKED_MAP_ROWS),
            Constraint::Length(1),
            Constraint::Min(CHART_MIN_ROWS),
        ])
        .areas(main_area);
        draw_heat_map(frame, map_area, state);
        frame.render_widget(
            Paragraph::new(colour_scale(state, scale_area.width)),
            scale_area,
        );
        draw_time_series(frame, series_area, state);
    } else {
        let [left, right] =
            Layout::horizontal([Constraint::Ratio(1, 2), Constraint::Ratio(1, 2)]).areas(main_area);
        let [map_area, scale_area] =
            Layout::vertical([Constraint::Min(6), Constraint::Length(1)]).areas(left);
        draw_heat_map(frame, map_area, state);
        frame.render_widget(
            Paragraph::new(colour_scale(state, scale_area.width)),
            scale_area,
        );
        draw_time_series(frame, right, state);
    }
}
