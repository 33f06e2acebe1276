//! The live view rendered into ratatui's TestBackend: kPa values, flag words, temperature and
//! its source, frame rate and dropped frames, pause.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use support::sample;
use taxel::view::{render_to_string, ViewState};
use wire::{
    CalibrationSource, CountersFrame, DeviceFrame, FirmwareVersion, InfoFrame, ReplyFrame,
    ReplyPayload,
};

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
        rate_sps: 200,
        model_tier: 2,
        streaming: true,
        text_mode: false,
    }
}

fn state_with_samples() -> ViewState {
    let mut state = ViewState::new("/dev/ttyACM0");
    state.connected_to("/dev/ttyACM0 (board 0123ABCD)");
    let taxels = [
        (Some(12.5), 4.75, 0),
        (None, -0.25, 0x0005),
        (None, 4.5, 0x0080),
        (Some(48.0), 5.6, 0x0002),
    ];
    state.apply_frame(&DeviceFrame::Sample(sample(10, 1_000_000, taxels)));
    state.apply_frame(&DeviceFrame::Sample(sample(11, 1_005_000, taxels)));
    // Sequence 12 lost.
    state.apply_frame(&DeviceFrame::Sample(sample(13, 1_015_000, taxels)));
    state.apply_frame(&DeviceFrame::Reply(ReplyFrame {
        request_id: 1,
        result: Ok(ReplyPayload::Info(info())),
    }));
    state.apply_frame(&DeviceFrame::Counters(CountersFrame {
        dropped_sample_sets: 2,
        ..CountersFrame::default()
    }));
    state
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
        "Frames: 133.3/s, 3 received, 3 dropped (gaps 1, device 2), 0 bad",
        "Device: firmware 0.3.1, calibration 7 (Flash), tier monotone-cubic, 200/s",
        "connected",
        "keys: t tare   p pause   q quit",
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
    state.apply_frame(&DeviceFrame::Sample(sample(
        14,
        1_020_000,
        [(Some(33.0), 5.2, 0); 4],
    )));
    let text = render_to_string(&state, 100, 30);
    assert!(text.contains("12.50 kPa"));
    assert!(!text.contains("33.00 kPa"));
    assert!(text.contains("PAUSED"));
    assert!(text.contains("4 received"));
    state.paused = false;
    state.apply_frame(&DeviceFrame::Sample(sample(
        15,
        1_025_000,
        [(Some(33.0), 5.2, 0); 4],
    )));
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
    // The device restarted: its sequence starts again without counting a gap.
    state.apply_frame(&DeviceFrame::Sample(sample(
        0,
        10,
        [(Some(1.0), 4.6, 0); 4],
    )));
    assert_eq!(state.sequence_gap_samples, 1);
    assert!(render_to_string(&state, 100, 30).contains("/dev/ttyACM1"));
}

#[test]
fn an_empty_view_renders_without_data() {
    let state = ViewState::new("nothing yet");
    let text = render_to_string(&state, 80, 24);
    assert!(text.contains("no data"));
    assert!(text.contains("Temperature: -"));
    assert!(text.contains("Frames: -/s, 0 received"));
}
