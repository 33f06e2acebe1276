//! The bridge checked by clients we did not write: Python's eclipse-zenoh subscribing and
//! rosbags decoding (bridge/tests/python/subscribe_bridge.py), and the Python MCAP readers
//! (bridge/tests/python/read_mcap.py), and a plain-mode subscriber with nothing but `struct`
//! (bridge/tests/python/subscribe_plain.py), each against `taxel-bridge --sim` playing
//! bridge/tests/python/plateau.toml; and the Python MCAP readers again on what
//! `taxel record --mcap` wrote of a simulated device playing the same scene.
//!
//! The Python interpreter is `$TAXEL_PYTHON`, a virtual environment with the packages of
//! bridge/tests/python/requirements.txt (`.ci/run` makes it). Without it the tests say so and
//! pass, except under CI (`CI=true`), where they fail.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Command;

fn python() -> Option<String> {
    match std::env::var("TAXEL_PYTHON") {
        Ok(python) if !python.is_empty() => Some(python),
        _ => {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "CI needs TAXEL_PYTHON: the Python clients' tests would not run"
            );
            eprintln!("TAXEL_PYTHON is not set: the Python clients' test is skipped");
            None
        }
    }
}

fn script(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../bridge/tests/python")
        .join(name)
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn run_script(python: &str, name: &str, extra: &[String]) {
    let output = Command::new(python)
        .arg(script(name))
        .arg("--bridge")
        .arg(env!("CARGO_BIN_EXE_taxel-bridge"))
        .arg("--scene")
        .arg(script("plateau.toml"))
        .args(extra)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let failures: Vec<&str> = stdout
        .lines()
        .filter(|line| line.starts_with("FAILED") || line.contains(" passed, "))
        .collect();
    assert!(
        output.status.success(),
        "{name} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    eprintln!("{name}: {}", failures.join("; "));
}

#[test]
fn a_python_zenoh_subscriber_decodes_what_the_scene_says() {
    let Some(python) = python() else {
        return;
    };
    run_script(
        &python,
        "subscribe_bridge.py",
        &["--port".to_owned(), free_port().to_string()],
    );
}

#[test]
fn with_no_network_option_the_bridge_is_loopback_only_and_reaches_the_local_router() {
    let Some(python) = python() else {
        return;
    };
    run_script(
        &python,
        "subscribe_bridge.py",
        &[
            "--default-network".to_owned(),
            "--devices".to_owned(),
            "1".to_owned(),
        ],
    );
}

#[test]
fn the_python_mcap_readers_decode_every_message() {
    let Some(python) = python() else {
        return;
    };
    run_script(&python, "read_mcap.py", &[]);
}

#[test]
fn the_python_mcap_readers_decode_a_taxel_record_mcap_file() {
    let Some(python) = python() else {
        return;
    };
    let directory = tempfile::tempdir().unwrap();
    let scene = script("plateau.toml");
    let config = sim_device::scene_config(Some(&scene), None, Some(2.0), 3).unwrap();
    let simulator = sim_device::SimulatorThread::start(config, Some(60.0)).unwrap();
    let recording = directory.path().join("rec.mcap");
    let port = simulator.path().display().to_string();
    let recording_arg = recording.display().to_string();
    let result = std::process::Command::new(taxel_cli())
        .args([
            "record",
            port.as_str(),
            "--samples",
            "700",
            "--mcap",
            recording_arg.as_str(),
        ])
        .output()
        .unwrap();
    simulator.stop();
    assert!(
        result.status.success(),
        "taxel record: {}",
        String::from_utf8_lossy(&result.stderr)
    );
    run_script(
        &python,
        "read_mcap.py",
        &[
            "--file".to_owned(),
            recording_arg,
            "--devices".to_owned(),
            "1".to_owned(),
        ],
    );
}

#[test]
fn a_plain_zenoh_subscriber_reads_the_documented_records() {
    let Some(python) = python() else {
        return;
    };
    run_script(
        &python,
        "subscribe_plain.py",
        &["--port".to_owned(), free_port().to_string()],
    );
}

/// The `taxel` command line, another package of the workspace: `cargo test` builds it before
/// the bridge's tests run (CI does), or `cargo build -p taxel` does.
fn taxel_cli() -> std::path::PathBuf {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), std::path::PathBuf::from);
    let cli = target.join("debug").join("taxel");
    assert!(
        cli.is_file(),
        "{} is missing: build the command line first (cargo build -p taxel)",
        cli.display()
    );
    cli
}
