//! `taxel plot` writes valid, non-empty SVG and PNG files from recordings of the recording schema
//! (`taxel_host::schema`), one panel per pad of each device, refuses files of other shapes, and
//! text renders with the embedded font (no system fonts needed).
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::path::Path;
use std::process::Command;

use model_core::TaxelFlags;
use support::taxel_binary;
use taxel::plot::read_pressure_series;
use taxel_host::schema::{PadReading, PadRow, RowWriter};
use wire::TemperatureSource;

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

/// The host clock when the recordings' device clocks read 0 (2026-01-01, Unix µs): plots time
/// from the first row's host time, not from the epoch.
const HOST_EPOCH_US: u64 = 1_767_225_600_000_000;

/// A reading of one pad at `device_time_us`: 24 °C, a capacitance on every taxel and the
/// given pressures (`None`: faulted, an empty cell).
fn reading(device_time_us: u64, pressure_kpa: [Option<f32>; 4]) -> PadReading {
    PadReading {
        device_time_us,
        temperature_c: Some(24.0),
        temperature_source: TemperatureSource::Tmp117,
        capacitance_pf: [Some(4.5); 4],
        pressure_kpa,
        flags: pressure_kpa.map(|pressure| {
            if pressure.is_some() {
                TaxelFlags::empty()
            } else {
                TaxelFlags::OPEN
            }
        }),
        force_n: None,
        centre_of_pressure_mm: None,
        partial: pressure_kpa.iter().any(Option::is_none),
        contact: false,
    }
}

/// One row of the schema: set `sequence` of `device`'s `pad`, its host time the device time
/// from [`HOST_EPOCH_US`], no sync error (`None` reading: the pad's frame never arrived).
fn row(device: u32, pad: u8, sequence: u32, time_us: u64, reading: Option<PadReading>) -> PadRow {
    PadRow {
        host_time_us: HOST_EPOCH_US + time_us,
        device,
        pad,
        sequence,
        sync_error_us: None,
        reading,
        marker: String::new(),
    }
}

fn write_rows(path: &Path, rows: &[PadRow]) {
    let mut writer = RowWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    for row in rows {
        writer.write(row).unwrap();
    }
    writer.flush().unwrap();
}

/// One pad (device 0, pad 0), 50 sets 5 ms apart, with a gap on taxel C12 (faulted rows have
/// empty pressure cells).
fn write_recording(path: &Path) {
    let rows: Vec<PadRow> = (0..50u32)
        .map(|set| {
            let time_us = u64::from(set) * 5_000;
            let pressure = (set % 25) as f32;
            let c12 = (!(20..25).contains(&set)).then_some(pressure * 0.5);
            row(
                0,
                0,
                set,
                time_us,
                Some(reading(
                    time_us,
                    [Some(pressure), c12, Some(0.0), Some(50.0 - pressure)],
                )),
            )
        })
        .collect();
    write_rows(path, &rows);
}

/// The pads of the several-pad recording: device 0 with three pads, device 1 with two.
const PADS: [(u32, u8); 5] = [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1)];

/// A pressure that tells the pads apart: (device 10 + pad + 1) kPa on every taxel.
fn pad_pressure(device: u32, pad: u8) -> f32 {
    (device * 10 + u32::from(pad) + 1) as f32
}

/// Two devices, 20 sets each, their pads' rows interleaved as `taxel record` writes them; set 10
/// of device 0 pad 1 never arrived.
fn write_several_pads(path: &Path) {
    let mut rows = Vec::new();
    for set in 0..20u32 {
        let time_us = u64::from(set) * 10_000;
        for (device, pad) in PADS {
            let pressure = pad_pressure(device, pad);
            let reading = (!(device == 0 && pad == 1 && set == 10))
                .then(|| reading(time_us, [Some(pressure); 4]));
            rows.push(row(device, pad, 100 + set, time_us, reading));
        }
    }
    write_rows(path, &rows);
}

fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(bytes[..8], PNG_SIGNATURE);
    assert_eq!(&bytes[12..16], b"IHDR");
    let width = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let height = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (width, height)
}

fn assert_svg(text: &str) {
    assert!(
        text.trim_start().starts_with("<svg"),
        "{}",
        &text[..80.min(text.len())]
    );
    assert!(text.trim_end().ends_with("</svg>"));
    assert!(text.contains("xmlns=\"http://www.w3.org/2000/svg\""));
    assert!(text.contains("<text"));
}

fn plot(arguments: &[&str]) -> std::process::Output {
    Command::new(taxel_binary())
        .arg("plot")
        .args(arguments)
        .output()
        .unwrap()
}

#[test]
fn recording_plots_as_svg_and_png() {
    let directory = tempfile::tempdir().unwrap();
    let recording = directory.path().join("recording.csv");
    write_recording(&recording);
    let svg = directory.path().join("pressure.svg");
    let png = directory.path().join("pressure.png");
    for output in [&svg, &png] {
        let result = plot(&[recording.to_str().unwrap(), "-o", output.to_str().unwrap()]);
        assert!(
            result.status.success(),
            "{}",
            String::from_utf8_lossy(&result.stderr)
        );
    }
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_svg(&text);
    for label in ["C11", "C12", "C21", "C22", "time (s)", "pressure (kPa)"] {
        assert!(text.contains(label), "{label} missing");
    }
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(png_size(&bytes), (1200, 600));
    assert!(bytes.len() > 10_000);
}

#[test]
fn calibration_plots_with_residuals() {
    let directory = tempfile::tempdir().unwrap();
    let calibration = directory.path().join("calibration.json");
    taxel_host::calibration_file::write(&calibration, &model_core::Calibration::default()).unwrap();
    let loads = directory.path().join("loads.csv");
    std::fs::write(
        &loads,
        "pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n0,4.5,4.5,4.5,4.5\n\
         10,4.87,4.88,4.86,4.87\n20,5.16,5.17,5.16,5.17\n50,5.65,5.66,5.65,5.66\n",
    )
    .unwrap();
    let svg = directory.path().join("calibration.svg");
    let result = plot(&[
        "--calibration",
        calibration.to_str().unwrap(),
        "--loads",
        loads.to_str().unwrap(),
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_svg(&text);
    for label in [
        "C22: dC/C0 against pressure",
        "residual per tier",
        "monotone-cubic",
        "saturating-micromath",
    ] {
        assert!(text.contains(label), "{label} missing");
    }
    let png = directory.path().join("calibration.png");
    let result = plot(&[
        "--calibration",
        calibration.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--width",
        "640",
        "--height",
        "480",
    ]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    assert_eq!(png_size(&std::fs::read(&png).unwrap()), (640, 480));
}

#[test]
fn recording_of_several_pads_and_devices_plots_one_panel_per_pad() {
    let directory = tempfile::tempdir().unwrap();
    let recording = directory.path().join("several.csv");
    write_several_pads(&recording);

    // One series per (device, pad), in that order, timed from the first row's host time.
    let series = read_pressure_series(std::fs::File::open(&recording).unwrap()).unwrap();
    assert_eq!(series.rows, 20 * PADS.len());
    assert!(series.skipped_rows.is_empty(), "{:?}", series.skipped_rows);
    let pads: Vec<(u32, u8)> = series
        .pads
        .iter()
        .map(|pad| (pad.device, pad.pad))
        .collect();
    assert_eq!(pads, PADS);
    for pad in &series.pads {
        assert_eq!(pad.time_s.len(), 20, "{pad:?}");
        assert_eq!(pad.time_s[0], 0.0);
        assert!((pad.time_s[19] - 0.19).abs() < 1e-9, "{:?}", pad.time_s);
        let pressure = f64::from(pad_pressure(pad.device, pad.pad));
        for (set, value) in pad.pressures_kpa[0].iter().enumerate() {
            if (pad.device, pad.pad, set) == (0, 1, 10) {
                assert_eq!(*value, None, "a missing frame is a gap");
            } else {
                assert_eq!(*value, Some(pressure), "{pad:?} set {set}");
            }
        }
    }

    // The picture: a titled panel per pad.
    let svg = directory.path().join("several.svg");
    let result = plot(&[recording.to_str().unwrap(), "-o", svg.to_str().unwrap()]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_svg(&text);
    assert_eq!(
        text.matches(": pressure per taxel").count(),
        PADS.len(),
        "one panel per pad"
    );
    for (device, pad) in PADS {
        let caption = format!("Device {device} pad {pad}: pressure per taxel");
        assert_eq!(text.matches(&caption).count(), 1, "{caption}");
    }
    assert_eq!(text.matches("time (s)").count(), PADS.len());
    let png = directory.path().join("several.png");
    let result = plot(&[recording.to_str().unwrap(), "-o", png.to_str().unwrap()]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let (width, height) = png_size(&std::fs::read(&png).unwrap());
    assert_eq!(width, 1200);
    assert!(height >= 600, "{height}");
}

#[test]
fn refuses_unknown_extensions_and_files_that_are_not_recordings() {
    let directory = tempfile::tempdir().unwrap();
    let recording = directory.path().join("recording.csv");
    write_recording(&recording);
    let result = plot(&[recording.to_str().unwrap(), "-o", "plot.jpg"]);
    assert_eq!(result.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&result.stderr).contains(".svg or .png"));
    // Files of the earlier shapes — capacitances only, pressures by time_s, the pad-prefixed
    // layout — are refused, naming the schema's header; nothing is written.
    let output = directory.path().join("plot.svg");
    for (name, text) in [
        ("capacitances.csv", "time_s,c11_pf\n0,4.5\n"),
        (
            "pressures.csv",
            "seq,time_s,temp_c,p11_kpa,p12_kpa,p21_kpa,p22_kpa,flags11\n0,0.0,24.0,1,2,3,4,\n",
        ),
        (
            "pads.csv",
            "time_s,pad0_p11_kpa,pad0_p12_kpa,pad0_p21_kpa,pad0_p22_kpa\n0,1,2,3,4\n",
        ),
    ] {
        let path = directory.path().join(name);
        std::fs::write(&path, text).unwrap();
        let result = plot(&[path.to_str().unwrap(), "-o", output.to_str().unwrap()]);
        assert_eq!(result.status.code(), Some(1), "{name}");
        let messages = String::from_utf8_lossy(&result.stderr);
        assert!(
            messages.contains("not a taxel recording") && messages.contains("host_time_s"),
            "{name}: {messages}"
        );
        assert!(!output.exists(), "{name}");
    }
}

/// A recording whose pressure cells are empty (capacitances only) draws no pressure until
/// `taxel convert` computes them; the converted file plots with them.
#[test]
fn capacitances_plot_as_pressures_after_convert() {
    let directory = tempfile::tempdir().unwrap();
    let recording = directory.path().join("capacitances.csv");
    let rows: Vec<PadRow> = (0..40u32)
        .map(|set| {
            let time_us = u64::from(set) * 10_000;
            // Unloaded for the tare (the first row), then pressed: 0.3 pF more on every taxel.
            let capacitance_pf = if set < 10 { 4.5 } else { 4.8 };
            let reading = PadReading {
                capacitance_pf: [Some(capacitance_pf); 4],
                flags: [TaxelFlags::empty(); 4],
                partial: false,
                ..reading(time_us, [None; 4])
            };
            row(0, 0, set, time_us, Some(reading))
        })
        .collect();
    write_rows(&recording, &rows);
    let before = read_pressure_series(std::fs::File::open(&recording).unwrap()).unwrap();
    assert!(before.pads[0]
        .pressures_kpa
        .iter()
        .flatten()
        .all(Option::is_none));

    let converted = directory.path().join("converted.csv");
    let output = Command::new(taxel_binary())
        .args(["convert", recording.to_str().unwrap(), "-o"])
        .arg(&converted)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let after = read_pressure_series(std::fs::File::open(&converted).unwrap()).unwrap();
    assert_eq!(after.rows, 40);
    for values in &after.pads[0].pressures_kpa {
        assert!(
            values[10..]
                .iter()
                .all(|value| value.is_some_and(|kpa| kpa > 1.0)),
            "{values:?}"
        );
    }
    let svg = directory.path().join("converted.svg");
    let result = plot(&[converted.to_str().unwrap(), "-o", svg.to_str().unwrap()]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    assert_svg(&std::fs::read_to_string(&svg).unwrap());
}

#[test]
fn embedded_font_measures_text() {
    use plotters::style::{FontDesc, FontFamily, FontStyle};
    taxel::plot::register_embedded_font().unwrap();
    let font = FontDesc::new(FontFamily::SansSerif, 20.0, FontStyle::Normal);
    let (width, height) = font.box_size("12.5 kPa").unwrap();
    assert!(width > 40 && height > 10, "{width} x {height}");
}
