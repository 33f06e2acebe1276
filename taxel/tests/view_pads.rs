//! The view of every pad, rendered into ratatui's TestBackend from synthetic sample frames: the
//! gripper and glove layouts and the automatic grid, each pad's name, force, contact, centre of
//! pressure, faults in words, stale and missing pads, a layout that does not match the device,
//! layout files with errors, and `taxel view --once --layout` against the simulated device with
//! several pads.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::info;

use taxel::layout::{Layout, LayoutProblem};
use taxel::view::{render_to_string, PadFreshness, ViewState, CENTRE_MARKER};
use wire::{PadSummary, SampleFrame, TaxelSample};

/// SHORTED: a fault (the taxel has no pressure).
const SHORTED: u16 = 0x0004;
/// NOT_TARED: a fault.
const NOT_TARED: u16 = 0x0080;
/// OVER_RANGE: not a fault (the pressure is the top of the calibration).
const OVER_RANGE: u16 = 0x0002;

/// What one pad reads in one set.
#[derive(Clone, Copy)]
struct PadReading {
    pressures_kpa: [Option<f32>; 4],
    flags: [u16; 4],
    force_n: Option<f32>,
    centre_mm: Option<[f32; 2]>,
    contact: bool,
}

impl PadReading {
    /// Every taxel at `pressure_kpa`, the force of four 25 mm² taxels, centred, no contact.
    fn even(pressure_kpa: f32) -> Self {
        Self {
            pressures_kpa: [Some(pressure_kpa); 4],
            flags: [0; 4],
            force_n: Some(pressure_kpa * 0.1),
            centre_mm: Some([0.0, 0.0]),
            contact: false,
        }
    }
}

fn frame(pad: u8, sequence: u32, reading: PadReading) -> SampleFrame {
    SampleFrame {
        sequence,
        // 10 ms sets, the pads of one set 300 µs apart.
        timestamp_us: u64::from(sequence) * 10_000 + u64::from(pad) * 300,
        temperature_c: Some(24.0 + f32::from(pad)),
        taxels: std::array::from_fn(|taxel| TaxelSample {
            pressure_kpa: reading.pressures_kpa[taxel],
            capacitance_pf: 4.6,
            flags: reading.flags[taxel],
        }),
        summary: PadSummary {
            force_n: reading.force_n,
            centre_of_pressure_mm: reading.centre_mm,
            partial: reading.pressures_kpa.iter().any(Option::is_none),
            contact: reading.contact,
        },
        ..wire::testing::sample_frame(pad)
    }
}

fn state_on_device(pad_count: u8, layout: Option<Layout>) -> ViewState {
    let mut state = ViewState::new("/dev/ttyACM0");
    state.connected_to("/dev/ttyACM0 (board 0707)");
    state.info = Some(info(pad_count));
    state.layout = layout;
    state
}

fn gripper() -> Layout {
    Layout::built_in("gripper").unwrap().unwrap()
}

fn glove() -> Layout {
    Layout::built_in("glove").unwrap().unwrap()
}

/// (row, column in characters) of the first occurrence of `needle`.
fn position(text: &str, needle: &str) -> (usize, usize) {
    text.lines()
        .enumerate()
        .find_map(|(row, line)| {
            line.find(needle)
                .map(|byte| (row, line[..byte].chars().count()))
        })
        .unwrap_or_else(|| panic!("'{needle}' missing in\n{text}"))
}

fn assert_fits(text: &str, width: u16, height: u16) {
    assert_eq!(text.lines().count(), usize::from(height), "{text}");
    assert!(
        text.lines()
            .all(|line| line.chars().count() <= usize::from(width)),
        "{text}"
    );
}

fn assert_contains_all(text: &str, expected: &[&str], size: &str) {
    for needle in expected {
        assert!(
            text.contains(needle),
            "{size}: '{needle}' missing in\n{text}"
        );
    }
}

/// The gripper: left finger pressed (contact, centre of pressure towards C11), right finger
/// with a shorted taxel and a partial force.
fn gripper_state() -> ViewState {
    let mut state = state_on_device(2, Some(gripper()));
    let left = PadReading {
        pressures_kpa: [Some(30.0), Some(10.0), Some(10.0), Some(0.0)],
        flags: [0; 4],
        force_n: Some(1.25),
        centre_mm: Some([-1.5, 1.5]),
        contact: true,
    };
    let right = PadReading {
        pressures_kpa: [Some(4.0), None, Some(2.0), Some(50.0)],
        flags: [0, SHORTED, 0, OVER_RANGE],
        force_n: Some(1.4),
        centre_mm: Some([2.5, -2.5]),
        contact: false,
    };
    for sequence in 1..=3 {
        state.apply_sample(&frame(0, sequence, left), 0);
        state.apply_sample(&frame(1, sequence, right), 0);
    }
    state
}

#[test]
fn the_gripper_shows_both_fingers_with_force_contact_centre_and_faults() {
    let state = gripper_state();
    assert!(state.shows_every_pad());
    for (width, height) in [(80, 24), (120, 32), (160, 48)] {
        let text = render_to_string(&state, width, height);
        println!("{width}x{height}:\n{text}");
        assert_fits(&text, width, height);
        assert_contains_all(
            &text,
            &[
                "left finger",
                "right finger",
                "1.25 N",
                "1.40 N",
                "● CONTACT",
                "○ no contact",
                "FAULT",
                "C12 FAULT: shorted",
                "C22 over range",
                "force partial",
                "-1.5, 1.5 mm",
                "2.5, -2.5 mm",
                "30.0 kPa",
                "50.0 kPa",
                "layout gripper",
                "Layout: gripper, device has 2 pads",
                "sets/s",
                "keys: t tare  p pause  r record  m marker  q quit  0-7 one pad",
            ],
            &format!("{width}x{height}"),
        );
        assert!(text.contains(CENTRE_MARKER), "{text}");
        assert!(!text.contains("not on this device"), "{text}");
        // Left finger left of the right finger, on one row; the contact is the left one's, the
        // fault the right one's.
        let (left, right) = (
            position(&text, "left finger"),
            position(&text, "right finger"),
        );
        assert_eq!(left.0, right.0);
        assert!(left.1 < right.1);
        assert!(position(&text, "● CONTACT").1 < right.1);
        assert!(position(&text, "FAULT").1 >= right.1);
        assert!(position(&text, "○ no contact").1 >= right.1);
    }
}

#[test]
fn a_faulted_taxel_never_shows_a_pressure() {
    let mut state = state_on_device(2, Some(gripper()));
    let faulted = PadReading {
        pressures_kpa: [None, Some(0.0), Some(0.0), Some(0.0)],
        flags: [NOT_TARED, 0, 0, 0],
        force_n: Some(0.0),
        centre_mm: None,
        contact: false,
    };
    state.apply_sample(&frame(0, 1, faulted), 0);
    state.apply_sample(&frame(1, 1, PadReading::even(0.0)), 0);
    let text = render_to_string(&state, 160, 48);
    println!("{text}");
    // Pad 0 has three taxels at 0.0 kPa and C11 faulted; pad 1 has four at 0.0 kPa.
    assert_eq!(text.matches("0.0 kPa").count(), 7, "{text}");
    assert_eq!(text.matches("FAULT").count(), 2, "{text}");
    assert!(text.contains("C11 FAULT: not tared"), "{text}");
    let (fault_row, fault_column) = position(&text, "FAULT");
    let (_, right_column) = position(&text, "right finger");
    assert!(fault_column < right_column);
    // C11 is the top-left cell: the first map line of the left tile.
    let c12 = text.lines().nth(fault_row).unwrap();
    assert!(c12.contains("0.0 kPa"), "C12 on C11's line: {c12}");
}

#[test]
fn the_glove_places_a_right_hand_seen_from_the_palm() {
    let mut state = state_on_device(6, Some(glove()));
    for pad in 0..6u8 {
        let mut reading = PadReading::even(5.0 * f32::from(pad + 1));
        reading.force_n = Some(f32::from(pad) + 0.25);
        reading.contact = pad == 1;
        state.apply_sample(&frame(pad, 1, reading), 0);
    }
    for (width, height) in [(80, 24), (160, 48)] {
        let text = render_to_string(&state, width, height);
        println!("{width}x{height}:\n{text}");
        assert_fits(&text, width, height);
        assert_contains_all(
            &text,
            &[
                "thumb", "index", "middle", "ring", "little", "palm", "0.25 N", "1.25 N", "2.25 N",
                "3.25 N", "4.25 N", "5.25 N", "CONTACT",
            ],
            &format!("{width}x{height}"),
        );
        let spot = |name: &str| position(&text, &format!(" {name} (pad"));
        let (little, ring, middle, index) =
            (spot("little"), spot("ring"), spot("middle"), spot("index"));
        // The fingertips along the top row, little finger on the left, index on the right.
        assert!(little.0 == ring.0 && ring.0 == middle.0 && middle.0 == index.0);
        assert!(little.1 < ring.1 && ring.1 < middle.1 && middle.1 < index.1);
        // The thumb below the index, the palm below the middle finger.
        let (thumb, palm) = (spot("thumb"), spot("palm"));
        assert!(
            thumb.0 > index.0 && thumb.1 == index.1,
            "{thumb:?} {index:?}"
        );
        assert!(
            palm.0 > middle.0 && palm.1 == middle.1,
            "{palm:?} {middle:?}"
        );
        // Nothing in the empty cells under the little and ring fingers.
        let left_of_palm: String = text
            .lines()
            .nth(palm.0)
            .unwrap()
            .chars()
            .take(palm.1 - 1)
            .collect();
        assert!(
            left_of_palm.trim_matches(['│', ' ']).is_empty(),
            "{left_of_palm}"
        );
    }
}

#[test]
fn eight_pads_fit_80x24_and_40x12() {
    let mut state = state_on_device(8, None);
    for pad in 0..8u8 {
        let mut reading = PadReading::even(2.0);
        reading.force_n = Some(f32::from(pad) + 0.5);
        reading.contact = pad % 2 == 0;
        if pad == 5 {
            reading.pressures_kpa[2] = None;
            reading.flags[2] = SHORTED;
        }
        state.apply_sample(&frame(pad, 1, reading), 0);
    }
    assert!(state.shows_every_pad());
    let text = render_to_string(&state, 80, 24);
    println!("{text}");
    assert_fits(&text, 80, 24);
    for pad in 0..8 {
        assert!(text.contains(&format!(" pad {pad} ")), "pad {pad}\n{text}");
        assert!(text.contains(&format!("{pad}.50 N")), "pad {pad}\n{text}");
    }
    assert_eq!(text.matches("● CONTACT").count(), 4, "{text}");
    assert!(text.contains("FAULT"), "{text}");
    assert!(
        text.contains("Layout: automatic, device has 8 pads"),
        "{text}"
    );
    assert!(text.contains("0-7 one pad"), "{text}");
    // Pads 0-3 on the first row of tiles, 4-7 on the second.
    assert_eq!(position(&text, " pad 0 ").0, position(&text, " pad 3 ").0);
    assert!(position(&text, " pad 4 ").0 > position(&text, " pad 0 ").0);

    let small = render_to_string(&state, 40, 12);
    println!("{small}");
    assert_fits(&small, 40, 12);
    for pad in 0..8 {
        assert!(small.contains(&format!("pad {pad}  {pad}.50 N")), "{small}");
    }
    assert_eq!(small.matches("●CONTACT").count(), 4, "{small}");
    assert!(small.contains("C21 FAULT: shorted"), "{small}");
    assert!(small.contains("q quit"), "{small}");
}

#[test]
fn a_pad_whose_frames_stop_is_stale_and_its_last_values_hidden() {
    // Arrivals in µs on the host clock.
    let start = 5_000_000u64;
    let mut state = state_on_device(2, Some(gripper()));
    let mut right = PadReading::even(20.0);
    right.force_n = Some(3.33);
    right.contact = true;
    state.apply_sample(&frame(0, 1, PadReading::even(1.0)), start);
    state.apply_sample(&frame(1, 1, right), start);
    assert_eq!(state.pad_freshness(1), PadFreshness::Live);
    assert!(render_to_string(&state, 100, 30).contains("3.33 N"));
    // The right finger is unplugged: the device goes on sending the left finger for 1 s.
    for sequence in 2..=101 {
        let at = start + 10_000 * u64::from(sequence - 1);
        state.apply_sample(&frame(0, sequence, PadReading::even(1.0)), at);
    }
    assert!(matches!(state.pad_freshness(1), PadFreshness::Stale { age_s } if age_s > 0.9));
    assert_eq!(state.pad_freshness(0), PadFreshness::Live);
    for (width, height) in [(100, 30), (40, 12)] {
        let text = render_to_string(&state, width, height);
        println!("{text}");
        assert!(text.contains("STALE"), "{text}");
        assert!(text.contains("no frame for 1.0 s"), "{text}");
        assert!(
            !text.contains("3.33 N"),
            "stale values shown as live:\n{text}"
        );
        assert!(
            !text.contains("20.0"),
            "stale values shown as live:\n{text}"
        );
        assert!(
            text.contains("0.10 N"),
            "the live pad is still shown:\n{text}"
        );
    }
    // Nothing at all for 0.6 s on the host clock: the device stalled; every pad is stale.
    state.refresh(start + 1_600_000);
    assert!(
        matches!(state.pad_freshness(0), PadFreshness::Stale { age_s } if (age_s - 0.6).abs() < 1e-6)
    );
    let text = render_to_string(&state, 100, 30);
    assert_eq!(text.matches("STALE").count(), 2, "{text}");
    assert!(!text.contains("0.10 N"), "{text}");
    // It comes back.
    state.apply_sample(&frame(1, 170, right), start + 1_700_000);
    assert_eq!(state.pad_freshness(1), PadFreshness::Live);
    assert!(render_to_string(&state, 100, 30).contains("3.33 N"));
}

#[test]
fn a_disconnected_device_shows_every_pad_stale_and_a_silent_pad_as_no_data() {
    let mut state = state_on_device(3, None);
    state.apply_sample(&frame(0, 1, PadReading::even(1.0)), 0);
    state.apply_sample(&frame(1, 1, PadReading::even(1.0)), 0);
    let text = render_to_string(&state, 100, 30);
    println!("{text}");
    assert!(
        text.contains("NO DATA") && text.contains("no frame from this pad yet"),
        "{text}"
    );
    assert_eq!(text.matches("0.10 N").count(), 2, "{text}");
    state.connection_lost("waiting for board 0707");
    let text = render_to_string(&state, 100, 30);
    assert_eq!(text.matches("STALE").count(), 2, "{text}");
    assert!(!text.contains("0.10 N"), "{text}");
    assert!(text.contains("disconnected"), "{text}");
}

#[test]
fn a_layout_naming_pads_the_device_lacks_marks_them_and_unnamed_pads_are_added() {
    // The glove on a two-pad device: thumb and index live, the rest not on this device.
    let mut state = state_on_device(2, Some(glove()));
    state.apply_sample(&frame(0, 1, PadReading::even(1.0)), 0);
    state.apply_sample(&frame(1, 1, PadReading::even(2.0)), 0);
    let text = render_to_string(&state, 100, 30);
    println!("{text}");
    assert_eq!(text.matches("not on this device").count(), 5, "{text}");
    assert!(
        text.contains("Layout: glove, device has 2 pads; not on this device: pads 2, 3, 4, 5"),
        "{text}"
    );
    assert!(text.contains("0.10 N") && text.contains("0.20 N"), "{text}");
    let small = render_to_string(&state, 40, 12);
    println!("{small}");
    assert_eq!(small.matches("not on this device").count(), 4, "{small}");

    // The gripper on a four-pad device: pads 2 and 3 are shown anyway, below it.
    let mut state = state_on_device(4, Some(gripper()));
    for pad in 0..4 {
        let mut reading = PadReading::even(1.0);
        reading.force_n = Some(f32::from(pad) + 0.75);
        state.apply_sample(&frame(pad, 1, reading), 0);
    }
    let text = render_to_string(&state, 100, 30);
    println!("{text}");
    assert!(text.contains("pad 2, not in layout") && text.contains("pad 3, not in layout"));
    assert!(
        text.contains("not in the layout, added: pads 2, 3"),
        "{text}"
    );
    for force in ["0.75 N", "1.75 N", "2.75 N", "3.75 N"] {
        assert!(text.contains(force), "{force}\n{text}");
    }
    assert!(position(&text, "pad 2, not in layout").0 > position(&text, "left finger").0);

    // A one-pad device with a layout gets the tiles too: the layout asked for them.
    let mut state = state_on_device(1, Some(gripper()));
    state.apply_sample(&frame(0, 1, PadReading::even(1.0)), 0);
    let text = render_to_string(&state, 80, 24);
    assert!(
        text.contains("left finger") && text.contains("not on this device"),
        "{text}"
    );
}

#[test]
fn one_pad_of_several_in_the_detailed_view() {
    let mut state = gripper_state();
    state.show_pad(Some(1));
    assert!(!state.shows_every_pad());
    let text = render_to_string(&state, 100, 30);
    println!("{text}");
    assert_contains_all(
        &text,
        &[
            "pad 1: right finger",
            " C12 ",
            "FAULT",
            "50.00 kPa",
            "4.00 kPa",
            "Force: 1.400 N at (2.5, -2.5) mm, no contact",
            "a all pads",
        ],
        "100x30",
    );
    assert!(!text.contains("30.00 kPa"), "the left finger's\n{text}");
    state.show_pad(None);
    assert!(render_to_string(&state, 100, 30).contains("left finger"));
    // A single-pad device without a layout keeps today's view.
    let mut single = state_on_device(1, None);
    single.apply_sample(&frame(0, 1, PadReading::even(12.5)), 0);
    assert!(!single.shows_every_pad());
    let text = render_to_string(&single, 80, 24);
    assert!(
        text.contains(" taxel view: /dev/ttyACM0 (board 0707) "),
        "{text}"
    );
    assert!(
        !text.contains("pad 0") && !text.contains("a all pads"),
        "{text}"
    );
}

#[test]
fn layout_files_are_checked_with_the_line_of_each_problem() {
    let pads = |entries: &[(i64, &str, i64, i64)]| {
        let mut text = String::from("name = \"test\"\n");
        for (index, name, column, row) in entries {
            text.push_str(&format!(
                "[[pad]]\nindex = {index}\nname = \"{name}\"\ncolumn = {column}\nrow = {row}\n"
            ));
        }
        text
    };
    let error = |text: &str| Layout::parse(text, "test.toml").unwrap_err();

    let parsed = Layout::parse(&pads(&[(0, "a", 0, 0), (7, "b", 7, 7)]), "test.toml").unwrap();
    assert_eq!(parsed.name, "test");
    assert_eq!(parsed.pads.len(), 2);

    let duplicate = error(&pads(&[(0, "a", 0, 0), (0, "b", 1, 0)]));
    assert_eq!(duplicate.line, Some(8));
    assert_eq!(
        duplicate.to_string(),
        "layout test.toml, line 8: pad index 0 is given twice (\"a\" and \"b\")"
    );
    let same_cell = error(&pads(&[(0, "a", 1, 2), (1, "b", 1, 2)]));
    assert_eq!(
        same_cell.to_string(),
        "layout test.toml, line 8: \"a\" and \"b\" are both in column 1, row 2"
    );
    let beyond = error(&pads(&[(0, "a", 0, 0), (8, "b", 1, 0)]));
    assert_eq!(
        beyond.to_string(),
        "layout test.toml, line 8: pad \"b\" has index 8; a device has pads 0 to 7"
    );
    assert!(matches!(
        error(&pads(&[(-1, "a", 0, 0)])).problem,
        LayoutProblem::IndexOutOfRange { index: -1, .. }
    ));
    assert!(error(&pads(&[(0, "a", 9, 0)]))
        .to_string()
        .contains("columns and rows are 0 to 7"));
    assert!(matches!(
        error(&pads(&[(0, " ", 0, 0)])).problem,
        LayoutProblem::EmptyName { index: 0 }
    ));
    assert_eq!(
        error("name = \"empty\"\n").to_string(),
        "layout test.toml: no pads; add [[pad]] tables with index, name, column and row"
    );

    let syntax = error("name = \"x\"\n[[pad]]\nindex = 0\nname = left finger\n");
    assert_eq!(syntax.line, Some(4), "{syntax}");
    assert!(
        syntax
            .to_string()
            .starts_with("layout test.toml, line 4, column"),
        "{syntax}"
    );
    let unknown_key =
        error("[[pad]]\nindex = 0\nname = \"a\"\ncolumn = 0\nrow = 0\nrotation = 90\n");
    assert!(
        unknown_key.to_string().contains("rotation") && unknown_key.line.is_some(),
        "{unknown_key}"
    );
    let missing_key = error("[[pad]]\nindex = 0\nname = \"a\"\ncolumn = 0\n");
    assert!(missing_key.to_string().contains("row"), "{missing_key}");
    let wrong_type = error("[[pad]]\nindex = \"zero\"\nname = \"a\"\ncolumn = 0\nrow = 0\n");
    assert_eq!(wrong_type.line, Some(2), "{wrong_type}");

    let unknown = Layout::load("octopus").unwrap_err();
    assert_eq!(unknown.problem, LayoutProblem::UnknownBuiltIn);
    assert!(unknown.to_string().contains("gripper, glove"), "{unknown}");
    let missing = Layout::load("/nonexistent/hand.toml").unwrap_err();
    assert!(
        matches!(missing.problem, LayoutProblem::Read { .. }),
        "{missing}"
    );
    assert!(missing
        .to_string()
        .starts_with("cannot read layout file /nonexistent/hand.toml"));

    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("hand.toml");
    std::fs::write(&path, pads(&[(3, "wrist", 0, 0)])).unwrap();
    let loaded = Layout::load(path.to_str().unwrap()).unwrap();
    assert_eq!(loaded.pads[0].name, "wrist");
    assert_eq!(loaded.pads[0].index, 3);
}

#[test]
fn the_command_line_reports_a_bad_layout_before_anything_else() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("bad.toml");
    std::fs::write(
        &path,
        "name = \"bad\"\n[[pad]]\nindex = 0\nname = \"a\"\ncolumn = 0\nrow = 0\n\
         [[pad]]\nindex = 0\nname = \"b\"\ncolumn = 1\nrow = 0\n",
    )
    .unwrap();
    for (layout, expected) in [
        ("octopus", "unknown layout \"octopus\""),
        (path.to_str().unwrap(), "line 8: pad index 0 is given twice"),
    ] {
        let output = std::process::Command::new(support::taxel_binary())
            .args(["view", "--once", "--layout", layout, "/nonexistent-port"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success());
        assert!(stderr.contains(expected), "{stderr}");
    }
}

/// The real thing: `taxel view --once --layout glove` on the simulated device reading three
/// pads behind its multiplexer.
#[test]
fn a_snapshot_of_the_simulated_device_with_three_pads_in_the_glove_layout() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};

    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 3)
            .with_seed(3)
            .with_speed(Some(1.0)),
    )
    .unwrap();
    let mut port = PtyPort::open().unwrap();
    let path = port.path().to_string_lossy().into_owned();
    let stop = Arc::new(AtomicBool::new(false));
    let device_thread = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || device.run(&mut port, Some(30.0), &stop))
    };
    let output = std::process::Command::new(support::taxel_binary())
        .args([
            "view", "--once", "--layout", "glove", "--width", "120", "--height", "32", &path,
        ])
        .output()
        .unwrap();
    stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
    let text = String::from_utf8_lossy(&output.stdout);
    println!("{text}");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_contains_all(
        &text,
        &[
            "layout glove",
            "Layout: glove, device has 3 pads; not on this device: pads 3, 4, 5",
            " thumb (pad 0) ",
            " index (pad 1) ",
            " middle (pad 2) ",
            "°C",
        ],
        "120x32",
    );
    assert_eq!(text.matches("not on this device").count(), 4, "{text}");
    assert!(
        !text.contains("STALE") && !text.contains("NO DATA"),
        "{text}"
    );
}

/// The layout format as the help and the README show it is a valid layout.
#[test]
fn the_documented_layout_examples_parse() {
    let help = taxel::view::LONG_ABOUT;
    let start = help.find("TOML:\n\n").unwrap() + "TOML:\n\n".len();
    let end = start + help[start..].find("\n\n").unwrap();
    let from_help = Layout::parse(&help[start..end], "help").unwrap();
    assert_eq!(from_help.name, "two-finger gripper");
    assert_eq!(from_help.pads.len(), 2);
    let readme = include_str!("../README.md");
    let start = readme.find("```toml\n").unwrap() + "```toml\n".len();
    let end = start + readme[start..].find("```").unwrap();
    let from_readme = Layout::parse(&readme[start..end], "README").unwrap();
    assert_eq!(from_readme, from_help);
}
