//! The bad-input matrix: every way a person can hand the tool a wrong file, a wrong port or a
//! closed output, with the exit status and the message they get, and the guarantee that an
//! existing output file is never touched by a run that fails.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use support::taxel_binary;

/// 4.5 pF unloaded; the article's table at 10 kPa is dC/C0 = 0.0829.
const LOADED_10_KPA_PF: f64 = 4.5 * 1.0829;

const PRECIOUS: &str = "precious data\n";

fn good_csv() -> String {
    format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0.0,25,4.5,4.5,4.5,4.5\n\
         0.1,25,{LOADED_10_KPA_PF},4.5,4.5,4.5\n"
    )
}

/// What one row of the matrix expects.
struct Case {
    name: &'static str,
    /// Files to create in the working directory before the run: name and bytes.
    files: Vec<(&'static str, Vec<u8>)>,
    /// Arguments after `taxel`; `{dir}` is replaced by the working directory.
    arguments: Vec<&'static str>,
    /// Exit status.
    status: i32,
    /// Text the messages on stderr must contain.
    message: &'static str,
}

fn case(
    name: &'static str,
    files: Vec<(&'static str, Vec<u8>)>,
    arguments: &[&'static str],
    status: i32,
    message: &'static str,
) -> Case {
    Case {
        name,
        files,
        arguments: arguments.to_vec(),
        status,
        message,
    }
}

fn run_in(directory: &Path, arguments: &[&str]) -> Output {
    let arguments: Vec<String> = arguments
        .iter()
        .map(|argument| argument.replace("{dir}", &directory.to_string_lossy()))
        .collect();
    Command::new(taxel_binary())
        .current_dir(directory)
        .args(&arguments)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

fn binary_garbage(len: usize) -> Vec<u8> {
    // A fixed pseudo-random byte stream (xorshift), zeros included so frames start and end.
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    (0..len)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 24) as u8
        })
        .collect()
}

#[test]
fn bad_input_matrix() {
    let good = good_csv().into_bytes();
    let header_only = b"time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n".to_vec();
    let semicolons = format!(
        "time_s;temp_c;c11_pf;c12_pf;c21_pf;c22_pf\n0,0;25;4,5;4,5;4,5;4,5\n0,1;25;{};4,5;4,5;4,5\n",
        format!("{LOADED_10_KPA_PF}").replace('.', ",")
    )
    .into_bytes();
    let quoted_commas =
        b"time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n0,25,\"4,5\",4.5,4.5,4.5\n".to_vec();
    let bad_time = |time: &str| {
        format!("time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n0,25,4.5,4.5,4.5,4.5\n{time},25,4.5,4.5,4.5,4.5\n")
            .into_bytes()
    };
    let pressures_with_inf =
        b"time_s,p11_kpa,p12_kpa,p21_kpa,p22_kpa\n0,1,1,1,1\ninf,2,2,2,2\n1,3,3,3,3\n".to_vec();
    let pressures_all_bad =
        b"time_s,p11_kpa,p12_kpa,p21_kpa,p22_kpa\ninf,1,1,1,1\nNaN,2,2,2,2\n".to_vec();
    let loads = b"pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n0,4.5,4.5,4.5,4.5\n10,4.87,4.87,4.87,4.87\n20,5.2,5.2,5.2,5.2\n".to_vec();

    let cases = [
        // convert: the output file must survive every failure.
        case(
            "missing input",
            vec![],
            &["convert", "missing.csv", "-o", "out.csv"],
            1,
            "opening missing.csv",
        ),
        case(
            "input is a directory",
            vec![],
            &["convert", ".", "-o", "out.csv"],
            1,
            "is a directory",
        ),
        case(
            "empty file",
            vec![("in.csv", vec![])],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "the file is empty",
        ),
        case(
            "header only",
            vec![("in.csv", header_only.clone())],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "no data rows",
        ),
        case(
            "wrong columns",
            vec![("in.csv", b"a,b,c\n1,2,3\n".to_vec())],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "lacks the column(s) time_s, temp_c",
        ),
        case(
            "binary garbage as CSV",
            vec![("in.csv", binary_garbage(4096))],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "header",
        ),
        case(
            "binary garbage as raw log",
            vec![("in.raw", binary_garbage(4096))],
            &["convert", "--raw", "in.raw", "-o", "out.csv"],
            1,
            "no sample frame",
        ),
        case(
            "a CSV given as raw log",
            vec![("in.csv", good.clone())],
            &["convert", "--raw", "in.csv", "-o", "out.csv"],
            1,
            "not a raw log",
        ),
        case(
            "';' CSV with ',' decimals",
            vec![("in.csv", semicolons)],
            &["convert", "in.csv", "-o", "out.csv"],
            0,
            "';'-separated with ',' decimals",
        ),
        case(
            "same input and output",
            vec![("out.csv", good.clone())],
            &["convert", "out.csv", "-o", "out.csv"],
            1,
            "is the input",
        ),
        case(
            "same file, other spelling",
            vec![("out.csv", good.clone())],
            &["convert", "out.csv", "-o", "./out.csv"],
            1,
            "is the input",
        ),
        case(
            "inf time",
            vec![("in.csv", bad_time("inf"))],
            &["convert", "in.csv", "-o", "out.csv"],
            3,
            "line 3: time_s 'inf' is not a finite time",
        ),
        case(
            "NaN time",
            vec![("in.csv", bad_time("NaN"))],
            &["convert", "in.csv", "-o", "out.csv"],
            3,
            "line 3: time_s 'NaN' is not a finite time",
        ),
        case(
            "huge time",
            vec![("in.csv", bad_time("1e300"))],
            &["convert", "in.csv", "-o", "out.csv"],
            3,
            "not a plausible time",
        ),
        case(
            "',' decimals in a ',' file",
            vec![("in.csv", quoted_commas)],
            &["convert", "in.csv", "-o", "out.csv"],
            3,
            "write decimals with '.'",
        ),
        case(
            "output is a directory",
            vec![("in.csv", good.clone())],
            &["convert", "in.csv", "-o", "."],
            1,
            "is a directory",
        ),
        case(
            "missing output directory",
            vec![("in.csv", good.clone())],
            &["convert", "in.csv", "-o", "nowhere/out.csv"],
            1,
            "creating a file in nowhere",
        ),
        case(
            "empty calibration file",
            vec![("in.csv", good.clone()), ("cal.json", vec![])],
            &[
                "convert",
                "in.csv",
                "--calibration",
                "cal.json",
                "-o",
                "out.csv",
            ],
            1,
            "EOF while parsing",
        ),
        case(
            "calibration of another format",
            vec![
                ("in.csv", good.clone()),
                ("cal.json", b"{\"format\": \"other\"}".to_vec()),
            ],
            &[
                "convert",
                "in.csv",
                "--calibration",
                "cal.json",
                "-o",
                "out.csv",
            ],
            1,
            "not a calibration file",
        ),
        // plot: bounded work whatever the data.
        case(
            "plot skips an inf time",
            vec![("in.csv", pressures_with_inf)],
            &["plot", "in.csv", "-o", "out.svg"],
            0,
            "line 3: skipped: time_s 'inf'",
        ),
        case(
            "plot with no readable time",
            vec![("in.csv", pressures_all_bad)],
            &["plot", "in.csv", "-o", "out.svg"],
            1,
            "nothing to plot",
        ),
        case(
            "plot of an empty file",
            vec![("in.csv", vec![])],
            &["plot", "in.csv", "-o", "out.svg"],
            1,
            "lacks the column time_s",
        ),
        case(
            "plot into its input",
            vec![("out.svg", good.clone())],
            &["plot", "out.svg", "-o", "out.svg"],
            1,
            "is the input",
        ),
        // calibrate
        case(
            "calibrate into its input",
            vec![("loads.csv", loads.clone())],
            &["calibrate", "loads.csv", "-o", "loads.csv"],
            1,
            "is the input",
        ),
        case(
            "calibrate from binary garbage",
            vec![("loads.csv", binary_garbage(2048))],
            &["calibrate", "loads.csv", "-o", "out.csv"],
            1,
            "loads.csv",
        ),
        // ports
        case(
            "record: missing port",
            vec![],
            &["record", "/nonexistent/ttyACM9", "-o", "out.csv"],
            1,
            "/nonexistent/ttyACM9 does not exist",
        ),
        case(
            "record: regular file as port",
            vec![("port", vec![])],
            &["record", "{dir}/port", "-o", "out.csv"],
            1,
            "is not a serial port (a regular file)",
        ),
        case(
            "record: /dev/null as port",
            vec![],
            &["record", "/dev/null", "-o", "out.csv"],
            1,
            "/dev/null is not a serial port (a device that is not a terminal)",
        ),
        case(
            "view --once: regular file as port",
            vec![("port", vec![])],
            &["view", "--once", "{dir}/port"],
            1,
            "is not a serial port (a regular file)",
        ),
        case(
            "view --once: /dev/null as port",
            vec![],
            &["view", "--once", "/dev/null"],
            1,
            "is not a serial port",
        ),
        case(
            "calibration pull: missing port",
            vec![],
            &[
                "calibration",
                "pull",
                "/nonexistent/ttyACM9",
                "-o",
                "out.csv",
            ],
            1,
            "does not exist",
        ),
    ];
    let mut failures = Vec::new();
    for case in &cases {
        let directory = tempfile::tempdir().unwrap();
        for (name, bytes) in &case.files {
            std::fs::write(directory.path().join(name), bytes).unwrap();
        }
        let output_path = directory.path().join("out.csv");
        let precious_before = if output_path.exists() {
            std::fs::read(&output_path).unwrap()
        } else {
            std::fs::write(&output_path, PRECIOUS).unwrap();
            PRECIOUS.as_bytes().to_vec()
        };
        let started = Instant::now();
        let output = run_in(directory.path(), &case.arguments);
        let stderr = String::from_utf8_lossy(&output.stderr);
        let mut problems = Vec::new();
        if output.status.code() != Some(case.status) {
            problems.push(format!(
                "status {:?}, expected {}",
                output.status.code(),
                case.status
            ));
        }
        if !stderr.contains(case.message) {
            problems.push(format!("message lacks {:?}", case.message));
        }
        if stderr.contains("panicked") || stderr.contains(" { ") {
            problems.push("a panic or a struct dump reached the user".to_owned());
        }
        for line in stderr.lines().filter(|line| line.starts_with("error: ")) {
            let parts: Vec<&str> = line.split(": ").map(str::trim).collect();
            let repeated = parts
                .iter()
                .enumerate()
                .any(|(index, part)| parts[index + 1..].contains(part));
            if repeated {
                problems.push(format!("the message repeats itself: {line}"));
            }
        }
        if case.status == 1 && std::fs::read(&output_path).unwrap() != precious_before {
            problems.push("the existing output file was changed by a failed run".to_owned());
        }
        let leftovers: Vec<String> = std::fs::read_dir(directory.path())
            .unwrap()
            .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|name| name.contains(".partial"))
            .collect();
        if !leftovers.is_empty() {
            problems.push(format!("temporary files left behind: {leftovers:?}"));
        }
        if started.elapsed() > Duration::from_secs(60) {
            problems.push(format!("took {:?}", started.elapsed()));
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {}\n  stderr: {stderr}",
                case.name,
                problems.join("; ")
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn semicolon_files_with_comma_decimals_are_read_and_said_so() {
    let directory = tempfile::tempdir().unwrap();
    let input = format!(
        "time_s;temp_c;c11_pf;c12_pf;c21_pf;c22_pf\n0,0;25;4,5;4,5;4,5;4,5\n0,1;25;{};4,5;4,5;4,5\n",
        format!("{LOADED_10_KPA_PF}").replace('.', ",")
    );
    std::fs::write(directory.path().join("in.csv"), input).unwrap();
    let output = run_in(directory.path(), &["convert", "in.csv", "-o", "out.csv"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("';'-separated with ',' decimals"),
        "{stderr}"
    );
    let text = std::fs::read_to_string(directory.path().join("out.csv")).unwrap();
    let row: Vec<&str> = text.lines().nth(2).unwrap().split(',').collect();
    let pressure_kpa: f64 = row[2].parse().unwrap();
    assert!((pressure_kpa - 10.0).abs() < 0.01, "{text}");
}

#[test]
fn non_finite_and_huge_capacitances_are_flagged_never_pressures() {
    let directory = tempfile::tempdir().unwrap();
    let input = "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
                 0,25,4.5,4.5,4.5,4.5\n\
                 1,25,NaN,inf,1e300,-inf\n";
    std::fs::write(directory.path().join("in.csv"), input).unwrap();
    let output = run_in(directory.path(), &["convert", "in.csv", "-o", "out.csv"]);
    assert_eq!(output.status.code(), Some(0));
    let text = std::fs::read_to_string(directory.path().join("out.csv")).unwrap();
    let row: Vec<&str> = text.lines().nth(2).unwrap().split(',').collect();
    for taxel in 0..4 {
        assert_eq!(
            row[2 + taxel],
            "",
            "no pressure from a non-measurement: {text}"
        );
        assert!(!row[6 + taxel].is_empty(), "flagged: {text}");
    }
}

#[test]
fn a_200_mb_file_ends_quickly_with_a_clear_message() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("big.csv");
    {
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let chunk = vec![b'x'; 1 << 20];
        for _ in 0..200 {
            file.write_all(&chunk).unwrap();
        }
    }
    for arguments in [
        &["convert", "big.csv", "-o", "out.csv"][..],
        &["plot", "big.csv", "-o", "out.svg"][..],
    ] {
        let started = Instant::now();
        let output = run_in(directory.path(), arguments);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("longer than 64 KiB"), "{stderr}");
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "{:?}",
            started.elapsed()
        );
    }
    assert!(!directory.path().join("out.csv").exists());
}

/// Runs with stdout connected to a pipe whose reading end is already closed.
fn run_with_closed_stdout(directory: &Path, arguments: &[&str]) -> Output {
    let mut child = Command::new(taxel_binary())
        .current_dir(directory)
        .args(arguments)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child.wait_with_output().unwrap()
}

#[test]
fn a_closed_stdout_is_a_clean_failure_and_files_are_written_first() {
    let directory = tempfile::tempdir().unwrap();
    let big: String = good_csv()
        + &(2..20_000)
            .map(|row| format!("{}.0,25,4.5,4.5,4.5,4.5\n", row))
            .collect::<String>();
    std::fs::write(directory.path().join("in.csv"), big).unwrap();
    let output = run_with_closed_stdout(directory.path(), &["convert", "in.csv"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("output pipe was closed"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");

    let loads = "pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n0,4.5,4.5,4.5,4.5\n10,4.87,4.87,4.87,4.87\n20,5.2,5.2,5.2,5.2\n30,5.4,5.4,5.4,5.4\n";
    std::fs::write(directory.path().join("loads.csv"), loads).unwrap();
    let output = run_with_closed_stdout(
        directory.path(),
        &["calibrate", "loads.csv", "-o", "c.json"],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let written = taxel_host::calibration_file::read(&directory.path().join("c.json"));
    assert!(
        written.is_ok(),
        "the calibration is written before the report: {stderr}"
    );
}

#[test]
fn a_full_disk_is_a_clean_failure() {
    let directory = tempfile::tempdir().unwrap();
    std::fs::write(directory.path().join("in.csv"), good_csv()).unwrap();
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full");
    let Ok(full) = full else {
        // Not every system has /dev/full; the matrix above still runs.
        return;
    };
    let output = Command::new(taxel_binary())
        .current_dir(directory.path())
        .args(["convert", "in.csv"])
        .stdout(full)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("No space left"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    // Writing into a device is writing into it, never replacing it by a file.
    let output = run_in(directory.path(), &["convert", "in.csv", "-o", "/dev/null"]);
    assert_eq!(output.status.code(), Some(0));
    assert!(Path::new("/dev/null").exists());
}
