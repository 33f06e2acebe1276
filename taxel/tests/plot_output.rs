//! `taxel plot` writes valid, non-empty SVG and PNG files, and text renders with the embedded
//! font (no system fonts needed).
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use support::taxel_binary;

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

fn write_recording(path: &Path) {
    let mut text = String::from("seq,time_s,temp_c,p11_kpa,p12_kpa,p21_kpa,p22_kpa,flags11\n");
    for row in 0..50u32 {
        let time_s = f64::from(row) * 0.005;
        let pressure = f64::from(row % 25);
        // A gap on taxel C12 (faulted rows have empty pressure cells).
        let c12 = if (20..25).contains(&row) {
            String::new()
        } else {
            format!("{:.3}", pressure * 0.5)
        };
        let _ = writeln!(
            text,
            "{row},{time_s:.6},24.0,{pressure},{c12},0,{},",
            50.0 - pressure
        );
    }
    std::fs::write(path, text).unwrap();
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
fn refuses_unknown_extensions_and_recordings_without_pressures() {
    let directory = tempfile::tempdir().unwrap();
    let recording = directory.path().join("recording.csv");
    write_recording(&recording);
    let result = plot(&[recording.to_str().unwrap(), "-o", "plot.jpg"]);
    assert_eq!(result.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&result.stderr).contains(".svg or .png"));
    let capacitances = directory.path().join("capacitances.csv");
    std::fs::write(&capacitances, "time_s,c11_pf\n0,4.5\n").unwrap();
    let output = directory.path().join("plot.svg");
    let result = plot(&[
        capacitances.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ]);
    assert_eq!(result.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&result.stderr).contains("taxel convert"));
}

#[test]
fn embedded_font_measures_text() {
    use plotters::style::{FontDesc, FontFamily, FontStyle};
    taxel::plot::register_embedded_font().unwrap();
    let font = FontDesc::new(FontFamily::SansSerif, 20.0, FontStyle::Normal);
    let (width, height) = font.box_size("12.5 kPa").unwrap();
    assert!(width > 40 && height > 10, "{width} x {height}");
}
