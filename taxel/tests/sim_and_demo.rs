//! `taxel sim` and `taxel demo` as a user runs them.

// Test helpers may unwrap: a failure is the test failing.
#![allow(clippy::unwrap_used)]

use std::process::Command;

#[test]
fn sim_serves_a_terminal_and_stops_after_its_duration() {
    let directory = tempfile::tempdir().unwrap();
    let path_file = directory.path().join("port");
    let output = Command::new(env!("CARGO_BIN_EXE_taxel"))
        .args(["sim", "--fast", "--duration", "3", "--path-file"])
        .arg(&path_file)
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let printed = String::from_utf8(output.stdout).unwrap();
    let written = std::fs::read_to_string(&path_file).unwrap();
    assert!(printed.trim().starts_with("/dev/pts/"), "{printed}");
    assert_eq!(printed.trim(), written.trim());
}

#[test]
fn sim_refuses_a_bad_scene_with_a_reason() {
    let directory = tempfile::tempdir().unwrap();
    let scene = directory.path().join("bad.toml");
    std::fs::write(&scene, "[[keyframe]]\ntime_s = 1.0\n").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_taxel"))
        .args(["sim", "--fast", "--duration", "1", "--scene"])
        .arg(&scene)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(message.contains("scene"), "{message}");
}

#[test]
fn demo_shows_the_light_press_of_its_scene() {
    // 5 s into the built-in scene one taxel holds a light 3 kPa press (run at 4x real time).
    let output = Command::new(env!("CARGO_BIN_EXE_taxel"))
        .args(["demo", "--speed", "4", "--snapshot-after", "5.5"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let screen = String::from_utf8(output.stdout).unwrap();
    assert!(screen.contains("C11") && screen.contains("C22"), "{screen}");
    assert!(screen.contains("(TMP117)"), "{screen}");
    let pressures: Vec<f64> = screen
        .split_whitespace()
        .collect::<Vec<_>>()
        .windows(2)
        .filter(|pair| pair[1] == "kPa")
        .filter_map(|pair| pair[0].parse().ok())
        .collect();
    assert_eq!(pressures.len(), 4, "{screen}");
    assert!((pressures[0] - 3.0).abs() < 0.3, "{pressures:?}\n{screen}");
    assert!(
        pressures[1..].iter().all(|pressure| pressure.abs() < 0.3),
        "{pressures:?}"
    );
}
