//! The view of every pad: one tile per pad, placed on the layout's grid (or the automatic grid
//! in pad order), each with the pad's name, a 2x2 heat map of its pressures in kPa with the
//! centre of pressure marked ([`CENTRE_MARKER`]), its force in N, the centre of pressure in mm,
//! contact on or off, and its faults and flags in words.
//!
//! A faulted taxel shows `FAULT`, never a pressure; a stale pad (see
//! [`super::state::STALE_AFTER`]) shows `STALE` and how long it has been silent, never its last
//! values; a pad the layout names that the device does not have says so. Tiles shrink to what
//! the terminal allows (fewer map lines, then no centre-of-pressure and temperature lines); when
//! they would be too small, or the terminal is under 80x24, every pad gets one line instead.

use model_core::PadGeometry;
use ratatui::layout::{Constraint, Layout as Split, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Borders, Paragraph};
use ratatui::Frame;
use wire::SampleFrame;

use super::draw::{
    accounting_line, device_line, pressure_style, rate_text, status_line, taxel_flag_words,
    KEYS_LINE_DEVICES,
};
use super::state::{PadFreshness, ViewState};
use crate::layout::{Arrangement, PadTile};
use taxel_host::csv_format::{temperature_source_words, TAXEL_LABELS};

/// The line of keys in the view of every pad.
pub const KEYS_LINE_EVERY_PAD: &str =
    "keys: t tare  p pause  r record  m marker  q quit  0-7 one pad";

/// The keys in the one-line-per-pad view.
const COMPACT_KEYS_LINE: &str = "t tare p pause r rec m mark q quit 0-7";

/// The keys in the one-line-per-pad view of one of several devices.
const COMPACT_KEYS_LINE_DEVICES: &str = "t tare p pause r rec m mark q quit 0-7 d dev";

/// Where the centre of pressure is in a tile's heat map.
pub const CENTRE_MARKER: char = '◆';

/// A tile narrower than this inside its border gives way to one line per pad: room for two map
/// cells with a value each ("12.5", "FLT") and the force.
const MIN_TILE_INNER_WIDTH: u16 = 11;

/// A tile lower than this inside its border gives way to one line per pad: two map lines and
/// the force.
const MIN_TILE_INNER_HEIGHT: u16 = 3;

/// The longest pad name the one-line-per-pad view pads to.
const COMPACT_NAME_WIDTH: usize = 14;

/// Draws every pad in `area` (at least [`super::MIN_WIDTH`] x [`super::MIN_HEIGHT`]).
pub(super) fn draw_every_pad(frame: &mut Frame, area: Rect, state: &ViewState) {
    let arrangement = state.arrangement();
    let device = state
        .device_label
        .as_ref()
        .map_or_else(String::new, |label| format!("{label}: "));
    let outer = Block::default().borders(Borders::ALL).title(format!(
        " taxel view: {device}{} | layout {} ",
        state.source, arrangement.name
    ));
    let inner = outer.inner(area);
    frame.render_widget(outer, area);
    if area.width >= 80 && area.height >= 24 {
        let text = summary_lines(state, &arrangement);
        let [grid_area, text_area] =
            Split::vertical([Constraint::Min(1), Constraint::Length(text.len() as u16)])
                .areas(inner);
        if tiles_fit(grid_area, &arrangement) {
            draw_tiles(frame, grid_area, state, &arrangement);
            // Cut, never wrapped: a wrapped line would push the keys out of the box.
            frame.render_widget(Paragraph::new(text), text_area);
            return;
        }
    }
    frame.render_widget(
        Paragraph::new(compact_lines(state, &arrangement, inner.height)),
        inner,
    );
}

/// Draws a device's pads in `area` without its summary lines (the view of several devices
/// has its own): tiles when they fit, else one line per pad.
pub(super) fn draw_pad_grid(frame: &mut Frame, area: Rect, state: &ViewState) {
    let arrangement = state.arrangement();
    if tiles_fit(area, &arrangement) {
        draw_tiles(frame, area, state, &arrangement);
    } else {
        frame.render_widget(
            Paragraph::new(compact_pad_lines(
                state,
                &arrangement,
                usize::from(area.height),
            )),
            area,
        );
    }
}

fn tiles_fit(grid_area: Rect, arrangement: &Arrangement) -> bool {
    let tile_width = grid_area.width / arrangement.columns.max(1);
    let tile_height = grid_area.height / arrangement.rows.max(1);
    tile_width >= MIN_TILE_INNER_WIDTH + 2 && tile_height >= MIN_TILE_INNER_HEIGHT + 2
}

fn draw_tiles(frame: &mut Frame, grid_area: Rect, state: &ViewState, arrangement: &Arrangement) {
    let rows = usize::from(arrangement.rows.max(1));
    let columns = usize::from(arrangement.columns.max(1));
    let row_areas = Split::vertical(vec![Constraint::Ratio(1, rows as u32); rows]).split(grid_area);
    for tile in &arrangement.tiles {
        let Some(row_area) = row_areas.get(usize::from(tile.place.row)) else {
            continue;
        };
        let cells =
            Split::horizontal(vec![Constraint::Ratio(1, columns as u32); columns]).split(*row_area);
        if let Some(cell) = cells.get(usize::from(tile.place.column)) {
            draw_tile(frame, *cell, tile, state);
        }
    }
}

/// Whether a tile's pad can be shown: the device's pad count and the pad's staleness.
fn tile_freshness(tile: &PadTile, state: &ViewState) -> PadFreshness {
    if tile.on_device == Some(false) {
        PadFreshness::NotOnDevice
    } else {
        state.pad_freshness(tile.place.index)
    }
}

fn tile_title(tile: &PadTile, width: u16) -> String {
    let name = &tile.place.name;
    let index = tile.place.index;
    let full = if !tile.in_layout {
        format!(" {name}, not in layout ")
    } else if name.ends_with(&format!("pad {index}")) {
        format!(" {name} ")
    } else {
        format!(" {name} (pad {index}) ")
    };
    if full.chars().count() + 2 <= usize::from(width) {
        full
    } else {
        format!(" {name} ")
    }
}

fn draw_tile(frame: &mut Frame, area: Rect, tile: &PadTile, state: &ViewState) {
    let freshness = tile_freshness(tile, state);
    let sample = state
        .pad_sample(tile.place.index)
        .filter(|_| freshness == PadFreshness::Live);
    let border_style = match (freshness, sample) {
        (PadFreshness::Live, Some(sample)) if sample.summary.contact => Style::default()
            .fg(Color::LightGreen)
            .add_modifier(Modifier::BOLD),
        (PadFreshness::Live, _) => Style::default(),
        (PadFreshness::Stale { .. }, _) => Style::default().fg(Color::LightRed),
        (PadFreshness::NoData | PadFreshness::NotOnDevice, _) => {
            Style::default().fg(Color::DarkGray)
        }
    };
    let block = Block::default()
        .borders(Borders::ALL)
        .border_style(border_style)
        .title(tile_title(tile, area.width));
    let inner = block.inner(area);
    frame.render_widget(block, area);
    let lines = match sample {
        Some(sample) => live_tile_lines(
            sample,
            &state.pad_geometry(sample.pad.get()),
            state.full_scale_kpa,
            inner.width,
            inner.height,
        ),
        None => absent_lines(freshness, state, usize::from(inner.width)),
    };
    frame.render_widget(Paragraph::new(lines), inner);
}

/// What a tile without live values says: never the last values.
fn absent_lines(freshness: PadFreshness, state: &ViewState, width: usize) -> Vec<Line<'static>> {
    let (headline, style, detail) = match freshness {
        PadFreshness::Stale { age_s } => (
            "STALE",
            Style::default()
                .fg(Color::White)
                .bg(Color::Red)
                .add_modifier(Modifier::BOLD),
            format!("no frame for {age_s:.1} s; last values hidden"),
        ),
        PadFreshness::NotOnDevice => {
            let pad_count = state.pad_count();
            (
                "not on this device",
                Style::default().fg(Color::DarkGray),
                format!(
                    "(the device has {pad_count} pad{})",
                    if pad_count == 1 { "" } else { "s" }
                ),
            )
        }
        PadFreshness::NoData | PadFreshness::Live => (
            "NO DATA",
            Style::default().fg(Color::DarkGray),
            "no frame from this pad yet".to_owned(),
        ),
    };
    let mut lines = vec![Line::from(Span::styled(headline, style))];
    lines.extend(wrap_words(&detail, width).into_iter().map(Line::from));
    lines
}

/// A tile with live values: heat map, force and contact, centre of pressure, flags,
/// temperature, as many as fit, in that order of importance (flags before the centre).
fn live_tile_lines(
    sample: &SampleFrame,
    geometry: &PadGeometry,
    full_scale_kpa: f32,
    width: u16,
    height: u16,
) -> Vec<Line<'static>> {
    // Six lines for the words (force, centre, flags, temperature); the map grows with the rest.
    let lines_per_taxel_row = (height.saturating_sub(6) / 2).clamp(1, 8);
    let mut lines = map_lines(sample, geometry, full_scale_kpa, width, lines_per_taxel_row);
    let width = usize::from(width);
    let mut remaining = usize::from(height).saturating_sub(lines.len());
    if remaining == 0 {
        return lines;
    }
    lines.push(force_line(sample, width));
    remaining -= 1;
    let (flag_text, flag_style) = flag_words(sample);
    let mut flag_lines = wrap_words(&flag_text, width);
    let show_centre = remaining >= 2;
    if show_centre {
        lines.push(Line::from(centre_text(sample)));
        remaining -= 1;
    }
    let flag_rows = flag_lines.len().min(remaining);
    if flag_rows < flag_lines.len() {
        flag_lines.truncate(flag_rows);
        if let Some(last) = flag_lines.last_mut() {
            last.pop();
            last.push('…');
        }
    }
    remaining -= flag_rows;
    lines.extend(
        flag_lines
            .into_iter()
            .map(|text| Line::from(Span::styled(text, flag_style))),
    );
    if remaining > 0 {
        lines.push(Line::from(temperature_text(sample)));
    }
    lines
}

/// Force in N and contact, the contact marked so that it is seen at a glance.
fn force_line(sample: &SampleFrame, width: usize) -> Line<'static> {
    let summary = &sample.summary;
    let force = match summary.force_n {
        Some(force_n) => format!("{force_n:.2} N"),
        None => "no force".to_owned(),
    };
    let room = width.saturating_sub(force.chars().count() + 1);
    let fits = |words: &'static str, short: &'static str| {
        if words.chars().count() <= room {
            words
        } else {
            short
        }
    };
    let contact = if summary.contact {
        Span::styled(
            fits("● CONTACT", "●"),
            Style::default()
                .fg(Color::Black)
                .bg(Color::LightGreen)
                .add_modifier(Modifier::BOLD),
        )
    } else {
        Span::styled(
            fits("○ no contact", "○"),
            Style::default().fg(Color::DarkGray),
        )
    };
    Line::from(vec![Span::raw(force), Span::raw(" "), contact])
}

fn centre_text(sample: &SampleFrame) -> String {
    match sample.summary.centre_of_pressure_mm {
        Some([x_mm, y_mm]) => format!("{CENTRE_MARKER} {x_mm:.1}, {y_mm:.1} mm"),
        None => format!("{CENTRE_MARKER} none"),
    }
}

fn temperature_text(sample: &SampleFrame) -> String {
    let source = temperature_source_words(sample.temperature_source);
    match sample.temperature_c {
        Some(temperature_c) => format!("{temperature_c:.1} °C ({source})"),
        None => format!("no temperature ({source})"),
    }
}

/// Adds `label` to the group of taxels with these `words`, in order of first appearance.
fn group_by_words(
    groups: &mut Vec<(String, Vec<&'static str>)>,
    words: String,
    label: &'static str,
) {
    match groups
        .iter_mut()
        .find(|(group_words, _)| *group_words == words)
    {
        Some((_, labels)) => labels.push(label),
        None => groups.push((words, vec![label])),
    }
}

/// The pad's faults and flags in words, faulted taxels first (taxels with the same words
/// together: "C11 C12 FAULT: not tared"), and their style: red with a fault, yellow with other
/// flags.
fn flag_words(sample: &SampleFrame) -> (String, Style) {
    let mut fault_groups = Vec::new();
    let mut other_groups = Vec::new();
    for (taxel, label) in sample.taxels.iter().zip(TAXEL_LABELS) {
        match (taxel.pressure_kpa, taxel.flags) {
            (None, 0) => group_by_words(&mut fault_groups, "FAULT".to_owned(), label),
            (None, _) => group_by_words(
                &mut fault_groups,
                format!("FAULT: {}", taxel_flag_words(taxel)),
                label,
            ),
            (Some(_), 0) => {}
            (Some(_), _) => group_by_words(&mut other_groups, taxel_flag_words(taxel), label),
        }
    }
    let in_words = |groups: Vec<(String, Vec<&str>)>| -> Vec<String> {
        groups
            .into_iter()
            .map(|(words, labels)| format!("{} {words}", labels.join(" ")))
            .collect()
    };
    let mut faults = in_words(fault_groups);
    let others = in_words(other_groups);
    if sample.summary.partial {
        faults.push("force partial".to_owned());
    }
    let style = if !faults.is_empty() {
        Style::default()
            .fg(Color::LightRed)
            .add_modifier(Modifier::BOLD)
    } else if !others.is_empty() {
        Style::default().fg(Color::Yellow)
    } else {
        Style::default()
    };
    faults.extend(others);
    if faults.is_empty() {
        ("all taxels ok".to_owned(), style)
    } else {
        (faults.join("; "), style)
    }
}

/// Greedy word wrap to `width` characters; a word longer than a line is cut across lines.
fn wrap_words(text: &str, width: usize) -> Vec<String> {
    let width = width.max(1);
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split(' ').filter(|word| !word.is_empty()) {
        let mut word: Vec<char> = word.chars().collect();
        let line_length = line.chars().count();
        if line_length > 0 && line_length + 1 + word.len() <= width {
            line.push(' ');
            line.extend(word);
            continue;
        }
        if line_length > 0 {
            lines.push(std::mem::take(&mut line));
        }
        while word.len() > width {
            lines.push(word.drain(..width).collect());
        }
        line.extend(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// The text of one map cell that fits in `cell_width` with a character to spare (for the
/// centre-of-pressure marker): kPa to one decimal with its unit when there is room.
fn cell_text(pressure_kpa: Option<f32>, cell_width: usize) -> String {
    let candidates = match pressure_kpa {
        Some(pressure_kpa) => vec![
            format!("{pressure_kpa:.1} kPa"),
            format!("{pressure_kpa:.1}kPa"),
            format!("{pressure_kpa:.1}"),
            format!("{pressure_kpa:.0}"),
        ],
        None => vec!["FAULT".to_owned(), "FLT".to_owned(), "F".to_owned()],
    };
    let fallback = candidates.last().cloned().unwrap_or_default();
    candidates
        .into_iter()
        .find(|text| text.chars().count() < cell_width)
        .unwrap_or(fallback)
}

/// One character of the mini map: the symbol, its style, and whether it is part of a value.
#[derive(Clone, Copy)]
struct MapCell {
    symbol: char,
    style: Style,
    is_text: bool,
}

/// The 2x2 heat map: each taxel a block of its heat colour (grey for a fault) with its kPa or
/// `FAULT`, C11 top left as on the pad, and the centre of pressure as [`CENTRE_MARKER`] on a
/// character no value uses, at its place between the taxel centres of the pad's geometry.
fn map_lines(
    sample: &SampleFrame,
    geometry: &PadGeometry,
    full_scale_kpa: f32,
    width: u16,
    lines_per_taxel_row: u16,
) -> Vec<Line<'static>> {
    let width = usize::from(width);
    let per_row = usize::from(lines_per_taxel_row.max(1));
    let left_width = width / 2;
    let cell_of = |taxel_column: usize| {
        if taxel_column == 0 {
            (0, left_width)
        } else {
            (left_width, width - left_width)
        }
    };
    let mut grid: Vec<Vec<MapCell>> = (0..2 * per_row)
        .map(|line| {
            (0..width)
                .map(|x| {
                    let taxel = (line / per_row) * 2 + usize::from(x >= left_width);
                    let pressure_kpa = sample.taxels.get(taxel).and_then(|t| t.pressure_kpa);
                    MapCell {
                        symbol: ' ',
                        style: pressure_style(pressure_kpa, full_scale_kpa),
                        is_text: false,
                    }
                })
                .collect()
        })
        .collect();
    // Every cell in the format the narrower (left) one allows, so that the four read alike.
    for (taxel, reading) in sample.taxels.iter().enumerate() {
        let (cell_x, cell_width) = cell_of(taxel % 2);
        let text: Vec<char> = cell_text(reading.pressure_kpa, left_width)
            .chars()
            .collect();
        let start = cell_x + cell_width.saturating_sub(text.len()) / 2;
        let line = (taxel / 2) * per_row + (per_row - 1) / 2;
        if let Some(row) = grid.get_mut(line) {
            for (offset, symbol) in text.into_iter().enumerate() {
                if let Some(cell) = row.get_mut(start + offset) {
                    cell.symbol = symbol;
                    cell.is_text = true;
                }
            }
        }
    }
    if let Some([x_mm, y_mm]) = sample.summary.centre_of_pressure_mm {
        place_centre_marker(&mut grid, geometry, [x_mm, y_mm], left_width, per_row);
    }
    grid.into_iter()
        .map(|row| {
            let mut spans: Vec<Span<'static>> = Vec::new();
            let mut text = String::new();
            let mut style = None;
            for cell in row {
                if style.is_some_and(|current| current != cell.style) {
                    spans.push(Span::styled(
                        std::mem::take(&mut text),
                        style.unwrap_or_default(),
                    ));
                }
                style = Some(cell.style);
                text.push(cell.symbol);
            }
            if !text.is_empty() {
                spans.push(Span::styled(text, style.unwrap_or_default()));
            }
            Line::from(spans)
        })
        .collect()
}

fn place_centre_marker(
    grid: &mut [Vec<MapCell>],
    geometry: &PadGeometry,
    [x_mm, y_mm]: [f32; 2],
    left_width: usize,
    per_row: usize,
) {
    if !x_mm.is_finite() || !y_mm.is_finite() {
        return;
    }
    let width = grid.first().map_or(0, Vec::len);
    // The map's cells are the taxels: the box of their centres spans the cells' centres.
    let (min, max) =
        geometry
            .taxels()
            .iter()
            .fold(([f32::MAX; 2], [f32::MIN; 2]), |(min, max), taxel| {
                (
                    [min[0].min(taxel.x_mm), min[1].min(taxel.y_mm)],
                    [max[0].max(taxel.x_mm), max[1].max(taxel.y_mm)],
                )
            });
    let fraction = |value: f32, low: f32, high: f32| {
        if high > low {
            ((value - low) / (high - low)).clamp(0.0, 1.0)
        } else {
            0.5
        }
    };
    // x grows towards C12 (right), y towards row 1 (up): the map's top line is +y.
    let x_fraction = fraction(x_mm, min[0], max[0]);
    let y_fraction = 1.0 - fraction(y_mm, min[1], max[1]);
    let left_centre = (left_width as f32 - 1.0) / 2.0;
    let right_centre = left_width as f32 + ((width - left_width) as f32 - 1.0) / 2.0;
    let top_centre = (per_row as f32 - 1.0) / 2.0;
    let bottom_centre = per_row as f32 + top_centre;
    let target_x = left_centre + x_fraction * (right_centre - left_centre);
    let target_line = top_centre + y_fraction * (bottom_centre - top_centre);
    let mut best: Option<(f32, usize, usize)> = None;
    for (line, row) in grid.iter().enumerate() {
        for (x, cell) in row.iter().enumerate() {
            if cell.is_text {
                continue;
            }
            // A line is about twice as tall as a column is wide.
            let distance =
                (x as f32 - target_x).powi(2) + (2.0 * (line as f32 - target_line)).powi(2);
            if best.is_none_or(|(best_distance, _, _)| distance < best_distance) {
                best = Some((distance, line, x));
            }
        }
    }
    if let Some((_, line, x)) = best {
        if let Some(cell) = grid.get_mut(line).and_then(|row| row.get_mut(x)) {
            cell.symbol = CENTRE_MARKER;
            cell.style = cell.style.add_modifier(Modifier::BOLD);
        }
    }
}

/// The lines under the tiles.
fn summary_lines(state: &ViewState, arrangement: &Arrangement) -> Vec<Line<'static>> {
    vec![
        Line::from(format!(
            "Samples: {} sets/s   {}",
            rate_text(state),
            layout_words(state, arrangement)
        )),
        Line::from(accounting_line(state)),
        Line::from(device_line(state, false)),
        status_line(state),
        Line::from(if state.device_label.is_some() {
            KEYS_LINE_DEVICES
        } else {
            KEYS_LINE_EVERY_PAD
        }),
    ]
}

fn pad_list(indices: &[u8]) -> String {
    let words: Vec<String> = indices.iter().map(u8::to_string).collect();
    format!(
        "pad{} {}",
        if indices.len() == 1 { "" } else { "s" },
        words.join(", ")
    )
}

/// The layout and how it fits the device: pads it names that the device does not have, pads
/// of the device it does not name.
fn layout_words(state: &ViewState, arrangement: &Arrangement) -> String {
    let mut words = format!("Layout: {}", arrangement.name);
    if let Some(info) = &state.info {
        words.push_str(&format!(
            ", device has {} pad{}",
            info.pad_count,
            if info.pad_count == 1 { "" } else { "s" }
        ));
    }
    let not_on_device = arrangement.not_on_device();
    if !not_on_device.is_empty() {
        words.push_str(&format!(
            "; not on this device: {}",
            pad_list(&not_on_device)
        ));
    }
    let not_in_layout = arrangement.not_in_layout();
    if !not_in_layout.is_empty() {
        words.push_str(&format!(
            "; not in the layout, added: {}",
            pad_list(&not_in_layout)
        ));
    }
    words
}

/// One line per pad: name, force and contact, faults; or stale, no data, not on this device.
fn compact_pad_line(tile: &PadTile, state: &ViewState, name_width: usize) -> Line<'static> {
    let name: String = tile.place.name.chars().take(name_width).collect();
    let mut spans = vec![Span::raw(format!("{name:<name_width$} "))];
    let freshness = tile_freshness(tile, state);
    match (freshness, state.pad_sample(tile.place.index)) {
        (PadFreshness::Live, Some(sample)) => {
            let summary = &sample.summary;
            spans.push(Span::raw(match summary.force_n {
                Some(force_n) => format!("{force_n:>5.2} N "),
                None => "    - N ".to_owned(),
            }));
            spans.push(if summary.contact {
                Span::styled(
                    "●CONTACT",
                    Style::default()
                        .fg(Color::Black)
                        .bg(Color::LightGreen)
                        .add_modifier(Modifier::BOLD),
                )
            } else {
                Span::styled("○", Style::default().fg(Color::DarkGray))
            });
            let (words, style) = flag_words(sample);
            if words != "all taxels ok" {
                spans.push(Span::styled(format!(" {words}"), style));
            }
        }
        (PadFreshness::Stale { age_s }, _) => spans.push(Span::styled(
            format!("STALE, no frame for {age_s:.1} s"),
            Style::default().fg(Color::LightRed),
        )),
        (PadFreshness::NotOnDevice, _) => spans.push(Span::styled(
            "not on this device",
            Style::default().fg(Color::DarkGray),
        )),
        _ => spans.push(Span::styled(
            "no data",
            Style::default().fg(Color::DarkGray),
        )),
    }
    Line::from(spans)
}

/// Every pad on one line each, in reading order of the layout, then as many summary lines as
/// fit; the status and the keys always show.
fn compact_lines(state: &ViewState, arrangement: &Arrangement, height: u16) -> Vec<Line<'static>> {
    let height = usize::from(height);
    let mut lines = compact_pad_lines(state, arrangement, height.saturating_sub(2));
    let spare = height.saturating_sub(lines.len() + 2);
    let optional = [
        Line::from(format!(
            "{} sets/s  {}",
            rate_text(state),
            layout_words(state, arrangement)
        )),
        Line::from(format!(
            "{} lost on link, {} dropped by device",
            state.accounting.lost_on_link(),
            state.accounting.device_dropped()
        )),
    ];
    lines.extend(optional.into_iter().take(spare));
    lines.push(status_line(state));
    lines.push(Line::from(if state.device_label.is_some() {
        COMPACT_KEYS_LINE_DEVICES
    } else {
        COMPACT_KEYS_LINE
    }));
    lines
}

/// Every pad on one line each, in reading order of the layout, in `pad_rows` lines at most
/// (the last one then says how many more there are).
fn compact_pad_lines(
    state: &ViewState,
    arrangement: &Arrangement,
    pad_rows: usize,
) -> Vec<Line<'static>> {
    let mut tiles: Vec<&PadTile> = arrangement.tiles.iter().collect();
    tiles.sort_by_key(|tile| (tile.place.row, tile.place.column));
    let name_width = tiles
        .iter()
        .map(|tile| tile.place.name.chars().count())
        .max()
        .unwrap_or(0)
        .min(COMPACT_NAME_WIDTH);
    let mut lines: Vec<Line<'static>> = Vec::new();
    if tiles.len() <= pad_rows {
        lines.extend(
            tiles
                .iter()
                .map(|tile| compact_pad_line(tile, state, name_width)),
        );
    } else {
        let shown = pad_rows.saturating_sub(1);
        lines.extend(
            tiles
                .iter()
                .take(shown)
                .map(|tile| compact_pad_line(tile, state, name_width)),
        );
        lines.push(Line::from(format!(
            "{} more pads: enlarge the terminal",
            tiles.len() - shown
        )));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where the centre marker lands on a blank map 20 columns wide, four lines per taxel row.
    fn marker_at(geometry: &PadGeometry, centre_mm: [f32; 2]) -> (usize, usize) {
        let blank = MapCell {
            symbol: ' ',
            style: Style::default(),
            is_text: false,
        };
        let mut grid = vec![vec![blank; 20]; 8];
        place_centre_marker(&mut grid, geometry, centre_mm, 10, 4);
        grid.iter()
            .enumerate()
            .find_map(|(line, row)| {
                row.iter()
                    .position(|cell| cell.symbol == CENTRE_MARKER)
                    .map(|x| (line, x))
            })
            .unwrap()
    }

    #[test]
    fn the_centre_marker_is_placed_on_the_pads_own_geometry() {
        // On C12's centre: the middle of the top-right cell, whatever the pad's size.
        let palm = PadGeometry::new(
            [(-6.0, 6.0), (6.0, 6.0), (-6.0, -6.0), (6.0, -6.0)]
                .map(|(x, y)| model_core::TaxelGeometry::new(x, y, 100.0)),
        )
        .unwrap();
        assert_eq!(marker_at(&PadGeometry::ARTICLE, [2.75, 2.75]), (1, 14));
        assert_eq!(marker_at(&palm, [6.0, 6.0]), (1, 14));
        // 2.75 mm on the palm is about halfway from the centre to C12's column, not on it.
        let (line, x) = marker_at(&palm, [2.75, 2.75]);
        assert!(
            (10..14).contains(&x) && (2..4).contains(&line),
            "{line}, {x}"
        );
    }

    #[test]
    fn words_wrap_at_the_width_and_long_words_are_cut() {
        assert_eq!(
            wrap_words("C12 FAULT: shorted; C21 over range", 12),
            ["C12 FAULT:", "shorted; C21", "over range"]
        );
        assert_eq!(wrap_words("abcdefgh", 3), ["abc", "def", "gh"]);
        assert!(wrap_words("", 5).is_empty());
    }

    #[test]
    fn taxels_with_the_same_words_are_named_together_faults_first() {
        let taxel = |pressure_kpa, flags| wire::TaxelSample {
            pressure_kpa,
            capacitance_pf: 4.6,
            flags,
        };
        let sample = SampleFrame {
            pad: wire::PadIndex::default(),
            sequence: 1,
            timestamp_us: 0,
            temperature_c: None,
            temperature_source: wire::TemperatureSource::None,
            taxels: [
                taxel(None, 0x0080),
                taxel(Some(50.0), 0x0002),
                taxel(None, 0x0080),
                taxel(None, 0x0004),
            ],
            summary: wire::PadSummary {
                partial: true,
                ..wire::PadSummary::default()
            },
        };
        let (words, style) = flag_words(&sample);
        assert_eq!(
            words,
            "C11 C21 FAULT: not tared; C22 FAULT: shorted; force partial; C12 over range"
        );
        assert_eq!(style.fg, Some(Color::LightRed));
    }

    #[test]
    fn a_map_cell_keeps_a_character_free_for_the_marker() {
        assert_eq!(cell_text(Some(12.5), 9), "12.5 kPa");
        assert_eq!(cell_text(Some(12.5), 8), "12.5kPa");
        assert_eq!(cell_text(Some(12.5), 5), "12.5");
        assert_eq!(cell_text(None, 6), "FAULT");
        assert_eq!(cell_text(None, 4), "FLT");
    }
}
