//! The live view rendered into ratatui's TestBackend at the sizes people use (40x12, 80x24,
//! 160x48): kPa values, flag words, faults, the colour scale, the time series (tall enough to
//! read at 80x24), temperature and its source, rates with their units, the session's honest
//! accounting, recording and pause.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::time::Duration;

use support::sample;
use taxel::view::{render_to_string, RecordingStatus, ViewState, CHART_MIN_ROWS};
use taxel_host::device_link::DeviceLink;
use taxel_host::session::{DeviceSession, SessionConfig, SessionEvent};
use taxel_host::stream_accounting::StreamAccounting;
use wire::{
    CalibrationSource, CountersFrame, DeviceFrame, FirmwareVersion, InfoFrame, ReplyFrame,
    ReplyPayload, SampleFrame,
};

/// A view and the accounting its device's session would keep, fed together.
struct Fed {
    state: ViewState,
    accounting: StreamAccounting,
}

impl Fed {
    fn connected(source: &str) -> Self {
        let mut state = ViewState::new(source);
        state.connected_to(source);
        Self {
            state,
            accounting: StreamAccounting::new(),
        }
    }

    fn sample(&mut self, sample: SampleFrame) {
        self.accounting.sample(&sample);
        self.state.apply_sample(&sample, 0);
        self.state.set_accounting(self.accounting.clone(), 0);
    }

    fn counters(&mut self, counters: CountersFrame) {
        self.accounting.counters(&counters);
        self.state.apply_event(&SessionEvent::Counters(counters), 0);
        self.state.set_accounting(self.accounting.clone(), 0);
    }
}

/// A set of one pad's frame.
fn set_of(frame: SampleFrame) -> taxel_host::pad_set::PadSet {
    taxel_host::pad_set::PadSet {
        sequence: frame.sequence,
        pads: vec![Some(frame)],
    }
}

fn info() -> InfoFrame {
    InfoFrame {
        protocol_version: 1,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 3,
            patch: 1,
        },
        board_serial: [0; 12],
        calibration_id: 7,
        calibration_source: CalibrationSource::Flash,
        rate: wire::SampleRate::Sps200,
        ..wire::testing::info_frame(1)
    }
}

fn state_with_samples() -> ViewState {
    let mut fed = Fed::connected("/dev/ttyACM0 (board 0123ABCD)");
    let taxels = [
        (Some(12.5), 4.75, 0),
        (None, -0.25, 0x0005),
        (None, 4.5, 0x0080),
        (Some(48.0), 5.6, 0x0002),
    ];
    fed.sample(sample(10, 1_000_000, taxels));
    fed.sample(sample(11, 1_005_000, taxels));
    // Sequence 12 lost.
    fed.sample(sample(13, 1_015_000, taxels));
    fed.state.apply_event(&SessionEvent::Info(info()), 0);
    fed.counters(CountersFrame {
        dropped_sample_frames: 2,
        ..CountersFrame::default()
    });
    fed.state
}

/// The 40x12, 80x24 and 160x48 layouts keep every taxel's pressure or fault and its flags
/// visible, with units, and stay within the terminal.
#[test]
fn every_layout_keeps_pressures_faults_and_flags_visible() {
    let state = state_with_samples();
    for (width, height) in [(40, 12), (80, 24), (160, 48)] {
        let text = render_to_string(&state, width, height);
        println!("{width}x{height}:\n{text}");
        for expected in [
            "C11",
            "C12",
            "C21",
            "C22",
            "12.50 kPa",
            "48.00 kPa",
            "FAULT",
        ] {
            assert!(
                text.contains(expected),
                "{width}x{height}: '{expected}' missing in\n{text}"
            );
        }
        for flag_words in ["shorted", "not tared", "over range"] {
            assert!(
                text.contains(flag_words),
                "{width}x{height}: '{flag_words}' missing in\n{text}"
            );
        }
        assert!(text.contains("°C"), "{width}x{height}\n{text}");
        assert!(text.contains("sets/s"), "{width}x{height}\n{text}");
        assert_eq!(text.lines().count(), usize::from(height));
        assert!(text
            .lines()
            .all(|line| line.chars().count() <= usize::from(width)));
    }
    let wide = render_to_string(&state, 160, 48);
    for words in [
        "Device: firmware 0.3.1, protocol 1, board 000000000000000000000000",
        "converter 200 conversions/s",
        "= 50 sample",
    ] {
        assert!(wide.contains(words), "{words}\n{wide}");
    }
    let normal = render_to_string(&state, 80, 24);
    let roomy = render_to_string(&state, 100, 30);
    for text in [&wide, &normal, &roomy] {
        assert!(text.contains("pressure (kPa), last 10 s"), "{text}");
        assert!(text.contains("scale (kPa): 0"), "{text}");
        assert!(text.contains("-10 s") && text.contains("now"), "{text}");
    }
    // Wide and 80x24: the time series beside the heat map; with room, below it.
    let row_of = |text: &str, needle: &str| text.lines().position(|line| line.contains(needle));
    assert!(row_of(&wide, "pressure (kPa)") < row_of(&wide, " C21 "));
    assert!(row_of(&normal, "pressure (kPa)") < row_of(&normal, " C21 "));
    assert!(row_of(&roomy, "pressure (kPa)") > row_of(&roomy, " C21 "));
}

/// (top row, rows) of the time series' box, its border included.
fn chart_box(text: &str) -> (usize, usize) {
    let lines: Vec<Vec<char>> = text.lines().map(|line| line.chars().collect()).collect();
    let (top, column) = text
        .lines()
        .enumerate()
        .find_map(|(row, line)| {
            line.find("┌ pressure (kPa)")
                .map(|byte| (row, line[..byte].chars().count()))
        })
        .unwrap_or_else(|| panic!("no time series in\n{text}"));
    let bottom = (top + 1..lines.len())
        .find(|row| lines[*row].get(column) == Some(&'└'))
        .unwrap_or_else(|| panic!("the time series has no bottom in\n{text}"));
    (top, bottom - top + 1)
}

/// The issue "the default view at 80x24 draws its 'pressure, last 10 s' chart one text row
/// high": at 80x24 the time series sits beside the heat map, as tall as it (16 rows, 12 of
/// them points: 48 braille dots from 0 to full scale), with its y-axis labels far apart; every
/// size the detailed view draws at gives it at least CHART_MIN_ROWS.
#[test]
fn the_80x24_time_series_is_tall_enough_to_read() {
    let mut fed = Fed::connected("series");
    for index in 0..500u32 {
        let pressure_kpa = (index % 100) as f32 / 2.0;
        fed.sample(sample(
            index,
            u64::from(index) * 10_000,
            [(Some(pressure_kpa), 4.6, 0); 4],
        ));
    }
    let text = render_to_string(&fed.state, 80, 24);
    println!("{text}");
    let (top, rows) = chart_box(&text);
    assert!(rows >= 16, "{rows} rows:\n{text}");
    // The y axis: "50" on the first row inside the box, "0" on the last row of points.
    let row_starting = |label: &str| {
        text.lines()
            .enumerate()
            .skip(top + 1)
            .find(|(_, line)| {
                line.split('│')
                    .any(|cell| cell.starts_with(label) && cell[label.len()..].starts_with(' '))
            })
            .map(|(row, _)| row)
            .unwrap_or_else(|| panic!("no y label {label} in\n{text}"))
    };
    let (full, zero) = (row_starting("50"), row_starting("0 "));
    assert!(zero - full >= 10, "{full}..{zero}\n{text}");
    // Points are drawn (braille), and every taxel and its words are still there.
    assert!(
        text.chars()
            .filter(|c| ('\u{2801}'..='\u{28ff}').contains(c))
            .count()
            > 50,
        "{text}"
    );
    for (width, height) in [
        (80, 24),
        (80, 26),
        (90, 28),
        (100, 30),
        (100, 31),
        (119, 40),
        (120, 32),
        (160, 48),
    ] {
        let text = render_to_string(&fed.state, width, height);
        let (_, rows) = chart_box(&text);
        assert!(
            rows >= usize::from(CHART_MIN_ROWS),
            "{width}x{height}: {rows} rows\n{text}"
        );
    }
}

/// Force, centre of pressure and contact, as the device sent them, in every layout; a pad
/// whose taxels are all faulted has no force and says so.
#[test]
fn every_layout_shows_the_pads_force_and_contact() {
    let mut state = state_with_samples();
    let taxels = [
        (Some(12.5), 4.75, 0),
        (None, -0.25, 0x0005),
        (None, 4.5, 0x0080),
        (Some(0.0), 4.25, 1),
    ];
    let mut pressed = sample(14, 1_020_000, taxels);
    pressed.summary = wire::PadSummary {
        force_n: Some(0.3125),
        centre_of_pressure_mm: Some([-2.75, 2.75]),
        partial: true,
        contact: true,
    };
    state.apply_sample(&pressed, 0);
    for (width, height, expected) in [
        (40, 12, "0.31 N contact"),
        (80, 24, "Force: 0.312 N at (-2.8, 2.8) mm, in contact"),
        (
            160,
            48,
            "Force: 0.312 N at (-2.8, 2.8) mm, in contact (faulted taxels left out)",
        ),
    ] {
        let text = render_to_string(&state, width, height);
        assert!(
            text.contains(expected),
            "{width}x{height}: {expected}\n{text}"
        );
    }
    let mut dead = pressed;
    dead.sequence = 15;
    dead.summary = wire::PadSummary::default();
    state.apply_sample(&dead, 0);
    let text = render_to_string(&state, 80, 24);
    assert!(text.contains("Force: none (no taxel reads)"), "{text}");
}

#[test]
fn a_terminal_too_small_gets_a_notice() {
    let text = render_to_string(&state_with_samples(), 30, 8);
    assert!(
        text.contains("terminal too small") && text.contains("40x12") && text.contains("30x8"),
        "{text}"
    );
}

#[test]
fn the_time_series_shows_the_last_seconds_with_faults_as_gaps() {
    let mut state = ViewState::new("series");
    state.connected_to("series");
    state.history_s = 2.0;
    for index in 0..400u32 {
        let pressure_kpa = (index % 50) as f32;
        let c12 = if (100..200).contains(&index) {
            None
        } else {
            Some(5.0)
        };
        state.apply_sample(
            &sample(
                index,
                u64::from(index) * 10_000,
                [
                    (Some(pressure_kpa), 4.6, 0),
                    (c12, 4.6, if c12.is_none() { 0x0004 } else { 0 }),
                    (Some(0.0), 4.5, 0),
                    (Some(0.0), 4.5, 0),
                ],
            ),
            0,
        );
    }
    let c11 = state.history_of(0);
    assert_eq!(c11.len(), 201, "2 s of 10 ms sets, both ends included");
    assert_eq!(c11.last().map(|point| point.0), Some(0.0));
    assert!(c11.iter().all(|(age_s, _)| (-2.0..=0.0).contains(age_s)));
    // C12 was faulted from set 100 to 199: none of those are in its series.
    let c12 = state.history_of(1);
    assert!(c12.iter().all(|(_, pressure_kpa)| *pressure_kpa == 5.0));
}

#[test]
fn the_recording_shows_in_the_status_line() {
    let mut state = state_with_samples();
    state.recording = Some(RecordingStatus {
        file: "taxel-20261123-231125.csv".to_owned(),
        sets: 1988,
        markers: 2,
    });
    for (width, height) in [(40, 12), (80, 24), (160, 48)] {
        let text = render_to_string(&state, width, height);
        assert!(text.contains("● REC"), "{width}x{height}\n{text}");
    }
    assert!(render_to_string(&state, 160, 48)
        .contains("● REC taxel-20261123-231125.csv (1988 sets, 2 markers)"));
}

/// Counters are the device's since its boot: the view shows the growth since the connection,
/// never the absolute count; gaps the device's drops explain are not link loss.
#[test]
fn device_drops_are_deltas_since_the_connection() {
    let mut fed = Fed::connected("counters");
    let counters = |dropped| CountersFrame {
        dropped_sample_frames: dropped,
        // Frames of other kinds the device could not send are not lost sample sets.
        frames_dropped_no_host: dropped * 2,
        ..CountersFrame::default()
    };
    fed.counters(counters(91_843));
    fed.sample(sample(1, 10_000, [(Some(1.0), 4.6, 0); 4]));
    fed.sample(sample(5, 50_000, [(Some(1.0), 4.6, 0); 4]));
    fed.counters(counters(91_846));
    let text = render_to_string(&fed.state, 160, 48);
    assert!(
        text.contains("2 received, 0 lost on link, 3 dropped by device"),
        "{text}"
    );
    assert!(!text.contains("91843") && !text.contains("91846"), "{text}");
}

/// Sets the view skipped because it fell behind are said, and are not link losses.
#[test]
fn sets_the_view_skipped_are_said_apart_from_losses() {
    let mut state = state_with_samples();
    state.view_dropped_sets = 7;
    let text = render_to_string(&state, 160, 48);
    assert!(
        text.contains("3 received, 1 lost on link, 0 dropped by device, 0 bad frames, 7 sets skipped by the view"),
        "{text}"
    );
}

/// A device that streamed before the connection leaves stale frames in the port: its session
/// discards everything before the Info reply and counts it, and the view shows that count.
#[test]
fn stale_frames_at_connection_are_discarded() {
    let mut device = support::FakeDevice::new(Box::new(|request| match request.command {
        wire::Command::Info => vec![
            DeviceFrame::Reply(ReplyFrame {
                request_id: request.request_id,
                result: Ok(ReplyPayload::Info(info())),
            }),
            DeviceFrame::Sample(sample(1218, 12_180_000, [(Some(1.0), 4.6, 0); 4])),
        ],
        wire::Command::ReadCounters => vec![DeviceFrame::Reply(ReplyFrame {
            request_id: request.request_id,
            result: Ok(ReplyPayload::Counters(CountersFrame::default())),
        })],
        _ => vec![support::ack(request)],
    }));
    for sequence in 0..50 {
        device.send(&DeviceFrame::Sample(sample(
            sequence,
            u64::from(sequence) * 10_000,
            [(Some(9.0), 4.6, 0); 4],
        )));
    }
    let config = SessionConfig {
        request_timeout: Duration::from_millis(500),
        follow_state: false,
    };
    let mut session = DeviceSession::open(DeviceLink::new(device), config).unwrap();
    assert_eq!(*session.info(), info());
    session.start().unwrap();
    let mut state = ViewState::new("stale");
    state.connected_to("stale");
    let until = std::time::Instant::now() + Duration::from_millis(200);
    while let Ok(Some(event)) = session.next_event(until) {
        state.apply_event(&event, 0);
    }
    state.set_accounting(
        session.accounting().clone(),
        session.link_statistics().frames_rejected,
    );
    assert_eq!(state.sample.map(|sample| sample.sequence), Some(1218));
    assert_eq!(state.accounting.received(), 1);
    assert_eq!(state.accounting.stale_frames(), 50);
    assert_eq!(state.accounting.lost_on_link(), 0);
    assert!(render_to_string(&state, 160, 48).contains("50 stale"));
}

#[test]
fn snapshot_shows_pressures_flags_temperature_and_rates() {
    let state = state_with_samples();
    let text = render_to_string(&state, 100, 30);
    println!("{text}");
    for expected in [
        "taxel view: /dev/ttyACM0 (board 0123ABCD)",
        "C11",
        "12.50 kPa",
        "4.7500 pF",
        "FAULT",
        "below baseline, shorted",
        "not tared",
        "48.00 kPa",
        "over range",
        "Temperature: 23.50 °C (TMP117)",
        "Samples: 133.3 sets/s",
        "3 received, 1 lost on link, 0 dropped by device, 0 bad frames",
        "Device: fw 0.3.1, cal. 7 (from flash), monotone-cubic, 200 conversions/s",
        "connected",
        "scale (kPa): 0",
        "pressure (kPa), last 10 s",
        "keys: t tare  p pause  r record  m marker  q quit",
    ] {
        assert!(text.contains(expected), "'{expected}' missing in\n{text}");
    }
    assert_eq!(text.lines().count(), 30);
    assert!(text.lines().all(|line| line.chars().count() <= 100));
}

#[test]
fn the_2x2_layout_puts_each_taxel_in_its_place() {
    let text = render_to_string(&state_with_samples(), 100, 30);
    let position = |needle: &str| {
        text.lines()
            .enumerate()
            .find_map(|(row, line)| {
                line.find(needle)
                    .map(|byte| (row, line[..byte].chars().count()))
            })
            .unwrap_or_else(|| panic!("{needle} missing"))
    };
    let (c11, c12, c21, c22) = (
        position(" C11 "),
        position(" C12 "),
        position(" C21 "),
        position(" C22 "),
    );
    assert_eq!(c11.0, c12.0);
    assert_eq!(c21.0, c22.0);
    assert!(c21.0 > c11.0);
    assert!(c12.1 > c11.1 && c22.1 > c21.1);
    assert_eq!(c11.1, c21.1);
}

#[test]
fn pause_freezes_the_display_but_keeps_counting() {
    let mut state = state_with_samples();
    state.paused = true;
    state.apply_event(
        &SessionEvent::Set {
            set: set_of(sample(14, 1_020_000, [(Some(33.0), 5.2, 0); 4])),
            sets_missing_before: 0,
        },
        0,
    );
    let text = render_to_string(&state, 100, 30);
    assert!(text.contains("12.50 kPa"));
    assert!(!text.contains("33.00 kPa"));
    assert!(text.contains("PAUSED"));
    assert_eq!(state.sets_received(), 1, "the set is taken while paused");
    state.paused = false;
    state.apply_sample(&sample(15, 1_025_000, [(Some(33.0), 5.2, 0); 4]), 0);
    assert!(render_to_string(&state, 100, 30).contains("33.00 kPa"));
}

#[test]
fn disconnection_is_shown_and_a_reconnect_restarts_sequence_tracking() {
    let mut state = state_with_samples();
    state.connection_lost("waiting for board 0123ABCD to be plugged in");
    let text = render_to_string(&state, 100, 30);
    assert!(text.contains("disconnected"));
    assert!(text.contains("waiting for board 0123ABCD"));
    state.connected_to("/dev/ttyACM1 (board 0123ABCD)");
    assert_eq!(
        state.accounting.received(),
        0,
        "a new connection counts afresh"
    );
    // The device restarted: its clock starts again, and its history with it.
    state.apply_sample(&sample(0, 10, [(Some(1.0), 4.6, 0); 4]), 0);
    assert_eq!(state.history_of(0).len(), 1);
    assert!(render_to_string(&state, 100, 30).contains("/dev/ttyACM1"));
}

#[test]
fn an_empty_view_renders_without_data() {
    let state = ViewState::new("nothing yet");
    let text = render_to_string(&state, 80, 24);
    assert!(text.contains("no data"));
    assert!(text.contains("Temperature: -"));
    assert!(text.contains("Samples: - sets/s"));
    assert!(text.contains("0 received, 0 lost on link"));
}
