//! The bad-input matrix: every way a person can hand the tool a wrong file, a wrong port or a
//! closed output, with the exit status and the message they get, and the guarantee that an
//! existing output file is never touched by a run that fails. A recording that cannot be read
//! as a whole is refused with the reason; a row that cannot be read is named by its line and
//! left out, never converted into something that looks like data, and the rows around it are
//! kept.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use model_core::{TaxelFlags, TAXEL_COUNT};
use support::taxel_binary;
use taxel_host::schema::{header, PadReading, PadRow, RowReader, RowWriter};
use wire::TemperatureSource;

/// 4.5 pF unloaded; the article's table at 10 kPa is dC/C0 = 0.0829.
const LOADED_10_KPA_PF: f32 = 4.5 * 1.0829;

const PRECIOUS: &str = "precious data\n";

/// The longest message a bad input may produce: a message quotes what it found, never all of
/// it.
const LONGEST_MESSAGE: usize = 4096;

/// Device 0 pad 0's row of set `sequence`, read at `time_us` with these capacitances at 25 °C
/// (pressures and flags left empty: `convert` computes them).
fn row(sequence: u32, time_us: u64, capacitance_pf: [Option<f32>; TAXEL_COUNT]) -> PadRow {
    PadRow {
        host_time_us: 1_700_000_000_000_000 + time_us,
        device: 0,
        pad: 0,
        sequence,
        sync_error_us: Some(250),
        reading: Some(PadReading::unconverted(
            time_us,
            Some(25.0),
            TemperatureSource::Tmp117,
            capacitance_pf,
        )),
        marker: String::new(),
    }
}

fn unloaded(sequence: u32) -> PadRow {
    row(sequence, u64::from(sequence) * 10_000, [Some(4.5); 4])
}

/// A recording of these rows, written by the schema's writer.
fn recording(rows: &[PadRow]) -> Vec<u8> {
    let mut writer = RowWriter::new(Vec::new()).unwrap();
    for row in rows {
        writer.write(row).unwrap();
    }
    writer.into_inner()
}

/// An unloaded set, then one with C11 at 10 kPa.
fn good_recording() -> Vec<u8> {
    recording(&[
        unloaded(1),
        row(
            2,
            20_000,
            [Some(LOADED_10_KPA_PF), Some(4.5), Some(4.5), Some(4.5)],
        ),
    ])
}

/// The cells of set `sequence`'s good row, as the writer spells them.
fn good_cells(sequence: u32) -> Vec<String> {
    let text = String::from_utf8(recording(&[unloaded(sequence)])).unwrap();
    text.lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect()
}

/// Set 2's row with some cells replaced (column index, text).
fn row_with(cells: &[(usize, &str)]) -> Vec<u8> {
    let mut row = good_cells(2);
    for (column, text) in cells {
        row[*column] = (*text).to_owned();
    }
    row.join(",").into_bytes()
}

/// A recording whose line 3 is `bad` (bytes as given), between good rows of sets 1 and 3: the
/// output must hold sets 1 and 3 and nothing of line 3.
fn with_bad_line_3(bad: &[u8]) -> Vec<u8> {
    let text = String::from_utf8(recording(&[unloaded(1)])).unwrap();
    let mut bytes = text.into_bytes();
    bytes.extend_from_slice(bad);
    bytes.push(b'\n');
    bytes.extend_from_slice(good_cells(3).join(",").as_bytes());
    bytes.push(b'\n');
    bytes
}

/// The sequence numbers of a recording's rows; panics on a row that cannot be read.
fn sequences(bytes: &[u8]) -> Vec<u32> {
    let mut reader = RowReader::new(bytes).unwrap();
    let mut sequences = Vec::new();
    while let Some(row) = reader.next_row() {
        sequences.push(row.unwrap().sequence);
    }
    sequences
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

/// `convert in.csv -o out.csv` of a recording whose line 3 is `bad`: status 3, the line named.
fn bad_row_case(name: &'static str, bad: &[u8], message: &'static str) -> Case {
    case(
        name,
        vec![("in.csv", with_bad_line_3(bad))],
        &["convert", "in.csv", "-o", "out.csv"],
        3,
        message,
    )
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
    let good = good_recording();
    let header_only = format!("{}\n", header().join(",")).into_bytes();
    let earlier_version = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n0.0,25,4.5,4.5,4.5,4.5\n0.1,25,{LOADED_10_KPA_PF},4.5,4.5,4.5\n"
    )
    .into_bytes();
    let mut reordered_header = header();
    reordered_header.swap(0, 3);
    let reordered = format!(
        "{}\n{}\n",
        reordered_header.join(","),
        good_cells(1).join(",")
    )
    .into_bytes();
    // The schema as a spreadsheet in a ',' decimal locale saves it.
    let semicolons = format!(
        "{}\n{}\n",
        header().join(";"),
        good_cells(1).join(";").replace('.', ",")
    )
    .into_bytes();
    let bad_time = |time: &'static str| row_with(&[(0, time)]);
    let pressures_with_inf = with_bad_line_3(&bad_time("inf"));
    let pressures_all_bad = {
        let mut bytes = header_only.clone();
        for time in ["inf", "NaN"] {
            bytes.extend(bad_time(time));
            bytes.push(b'\n');
        }
        bytes
    };
    let loads = b"pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n0,4.5,4.5,4.5,4.5\n10,4.87,4.87,4.87,4.87\n20,5.2,5.2,5.2,5.2\n".to_vec();
    let missing_frame_with_stray_cell = {
        let mut cells = good_cells(2);
        for cell in &mut cells[4..] {
            cell.clear();
        }
        cells[6] = "25".to_owned();
        cells.join(",").into_bytes()
    };
    let mut not_utf8 = row_with(&[]);
    not_utf8.extend_from_slice(b"\xff\xfe");

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
            "the recording has no rows",
        ),
        case(
            "wrong columns",
            vec![("in.csv", b"a,b,c\n1,2,3\n".to_vec())],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "the header is not a taxel recording's",
        ),
        case(
            "a recording of an earlier version",
            vec![("in.csv", earlier_version.clone())],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "earlier versions are not read",
        ),
        case(
            "the schema's columns in another order",
            vec![("in.csv", reordered)],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "the header is not a taxel recording's",
        ),
        case(
            "';'-separated with ',' decimals",
            vec![("in.csv", semicolons)],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "the header is not a taxel recording's",
        ),
        case(
            "binary garbage as a recording",
            vec![("in.csv", binary_garbage(4096))],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "the header is not a taxel recording's",
        ),
        case(
            "binary garbage as raw log",
            vec![("in.raw", binary_garbage(4096))],
            &["convert", "--raw", "in.raw", "-o", "out.csv"],
            1,
            "the raw log holds no sample frames",
        ),
        case(
            "a recording given as raw log",
            vec![("in.csv", good.clone())],
            &["convert", "--raw", "in.csv", "-o", "out.csv"],
            1,
            "the raw log holds no sample frames",
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
        bad_row_case(
            "inf time",
            &bad_time("inf"),
            "line 3: host_time_s 'inf' is not a non-negative number",
        ),
        bad_row_case(
            "NaN time",
            &bad_time("NaN"),
            "line 3: host_time_s 'NaN' is not a non-negative number",
        ),
        bad_row_case(
            "huge time in exponent form",
            &bad_time("1e300"),
            "line 3: host_time_s '1e300' is not a non-negative number",
        ),
        bad_row_case(
            "time beyond 64 bits of microseconds",
            &bad_time("99999999999999999999.5"),
            "line 3: host_time_s '99999999999999999999.5' is out of range",
        ),
        bad_row_case(
            "negative time",
            &bad_time("-1.5"),
            "line 3: host_time_s '-1.5' is not a non-negative number",
        ),
        bad_row_case(
            "time finer than a microsecond",
            &bad_time("1.0000001"),
            "line 3: host_time_s '1.0000001' is not a non-negative number with at most 6 decimals",
        ),
        bad_row_case(
            "',' decimals in a ',' file",
            &row_with(&[(8, "\"4,5\"")]),
            "line 3: c11_pf '4,5' is not a",
        ),
        bad_row_case(
            "a word for a number",
            &row_with(&[(9, "abc")]),
            "line 3: c12_pf 'abc' is not a",
        ),
        bad_row_case(
            "NaN capacitance",
            &row_with(&[(10, "NaN")]),
            "line 3: c21_pf 'NaN' is not a",
        ),
        bad_row_case(
            "a malformed exponent",
            &row_with(&[(11, "1e")]),
            "line 3: c22_pf '1e' is not a",
        ),
        bad_row_case(
            "sequence number beyond 32 bits",
            &row_with(&[(3, "4294967296")]),
            "line 3: seq '4294967296' is not a whole number in range",
        ),
        bad_row_case(
            "negative device",
            &row_with(&[(1, "-1")]),
            "line 3: device '-1' is not a whole number in range",
        ),
        bad_row_case(
            "pad beyond the protocol",
            &row_with(&[(2, "9")]),
            "line 3: pad 9 is beyond the protocol's 8 pads",
        ),
        bad_row_case(
            "too few cells",
            b"1.5,0,0,2,0.02,,25,tmp117,4.5,4.5",
            "line 3: 10 cells where the header has 26",
        ),
        bad_row_case(
            "too many cells",
            &[row_with(&[]), b",9".to_vec()].concat(),
            "line 3: 27 cells where the header has 26",
        ),
        bad_row_case(
            "a missing frame's row with a stray cell",
            &missing_frame_with_stray_cell,
            "line 3: device_time_s is empty (a missing frame) but other cells are not",
        ),
        bad_row_case(
            "a cell that is not UTF-8",
            &not_utf8,
            "line 3: a cell is not UTF-8 text",
        ),
        bad_row_case(
            "an unknown flag",
            &row_with(&[(16, "shorted|bogus")]),
            "line 3: flags11: unknown flag 'bogus'",
        ),
        bad_row_case(
            "half a centre of pressure",
            &row_with(&[(21, "1.5")]),
            "line 3: cop_x_mm and cop_y_mm must be both given or both empty",
        ),
        bad_row_case(
            "contact neither 0 nor 1",
            &row_with(&[(24, "yes")]),
            "line 3: contact must be 0 or 1",
        ),
        bad_row_case(
            "an unknown temperature source",
            &row_with(&[(7, "warm")]),
            "line 3: temp_source 'warm' is not tmp117, mcu_internal, last_known or none",
        ),
        bad_row_case(
            "a sync error finer than a microsecond",
            &row_with(&[(5, "0.2505")]),
            "line 3: sync_error_ms '0.2505' is not a non-negative number with at most 3 decimals",
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
        case(
            "a device state beside the recording that is garbage",
            vec![
                ("in.csv", good.clone()),
                ("in.csv.dev0.device.json", binary_garbage(512)),
            ],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "in.csv.dev0.device.json",
        ),
        case(
            "a device state beside the recording of another format",
            vec![
                ("in.csv", good.clone()),
                (
                    "in.csv.dev0.device.json",
                    b"{\"format\": \"other\", \"version\": 1}".to_vec(),
                ),
            ],
            &["convert", "in.csv", "-o", "out.csv"],
            1,
            "in.csv.dev0.device.json",
        ),
        // plot: bounded work whatever the data.
        case(
            "plot skips an inf time",
            vec![("in.csv", pressures_with_inf)],
            &["plot", "in.csv", "-o", "out.svg"],
            0,
            "line 3: skipped: host_time_s 'inf'",
        ),
        case(
            "plot with no readable row",
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
            "the file is empty",
        ),
        case(
            "plot of a recording of an earlier version",
            vec![("in.csv", earlier_version)],
            &["plot", "in.csv", "-o", "out.svg"],
            1,
            "earlier versions are not read",
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
        if stderr.len() > LONGEST_MESSAGE {
            problems.push(format!("{} bytes of messages", stderr.len()));
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
        let output_after = std::fs::read(&output_path).unwrap();
        if case.status == 1 && output_after != precious_before {
            problems.push("the existing output file was changed by a failed run".to_owned());
        }
        if case.status == 3 {
            // The bad line is left out, the rows around it are converted: sets 1 and 3.
            let kept = std::panic::catch_unwind(|| sequences(&output_after));
            if kept.as_deref().ok() != Some(&[1, 3][..]) {
                problems.push(format!(
                    "the output does not hold exactly the readable rows: {kept:?}"
                ));
            }
            if !stderr.contains("1 rows could not be read (left out); 2 rows converted") {
                problems.push("no count of the rows left out".to_owned());
            }
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

/// Replaces the test of ';'-separated files being read: the schema is one exact shape, so a
/// recording saved by a spreadsheet in a ',' decimal locale is refused as a whole, saying what
/// was expected, rather than read into wrong numbers; a quoted ',' decimal in a recording is a
/// row named by its line, never a number.
#[test]
fn a_recording_resaved_with_comma_decimals_is_refused_never_misread() {
    let directory = tempfile::tempdir().unwrap();
    let cells = good_cells(1);
    let semicolons = format!(
        "{}\n{}\n",
        header().join(";"),
        cells.join(";").replace('.', ",")
    );
    std::fs::write(directory.path().join("in.csv"), semicolons).unwrap();
    let output = run_in(directory.path(), &["convert", "in.csv", "-o", "out.csv"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!("expected {}", header().join(","))),
        "the message says which header is expected: {stderr}"
    );
    assert!(stderr.contains("earlier versions are not read"), "{stderr}");
    assert!(!directory.path().join("out.csv").exists());

    // Quoted ',' decimals in every number cell of a set: the row is named, nothing is guessed.
    let mut quoted = cells.clone();
    for column in [8, 9, 10, 11] {
        quoted[column] = format!("\"{}\"", quoted[column].replace('.', ","));
    }
    quoted[3] = "2".to_owned();
    let mut input = recording(&[unloaded(1)]);
    input.extend_from_slice(quoted.join(",").as_bytes());
    input.push(b'\n');
    std::fs::write(directory.path().join("in.csv"), input).unwrap();
    let output = run_in(directory.path(), &["convert", "in.csv", "-o", "out.csv"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("line 3: c11_pf '4,5' is not a"), "{stderr}");
    let converted = std::fs::read(directory.path().join("out.csv")).unwrap();
    assert_eq!(sequences(&converted), [1]);
}

/// Capacitances no converter can read are flagged `invalid_input` and carry no pressure; a
/// cell that is not a number at all (NaN) is not a reading: its row is named and left out. An
/// infinite cell is either of the two, never a pressure.
#[test]
fn non_finite_and_huge_capacitances_are_never_pressures() {
    let directory = tempfile::tempdir().unwrap();
    let out_of_reach = row(
        2,
        20_000,
        [Some(1e30), Some(-1e30), Some(f32::MAX), Some(200.0)],
    );
    let mut input = recording(&[unloaded(1), out_of_reach]);
    for (sequence, cells) in [
        (3, ["NaN", "4.5", "4.5", "4.5"]),
        (4, ["inf", "-inf", "1e300", "-1e39"]),
    ] {
        let mut row = good_cells(sequence);
        for (taxel, cell) in cells.into_iter().enumerate() {
            row[8 + taxel] = cell.to_owned();
        }
        input.extend_from_slice(row.join(",").as_bytes());
        input.push(b'\n');
    }
    std::fs::write(directory.path().join("in.csv"), input).unwrap();
    let output = run_in(directory.path(), &["convert", "in.csv", "-o", "out.csv"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("line 4: c11_pf 'NaN' is not a"), "{stderr}");
    let converted = std::fs::read(directory.path().join("out.csv")).unwrap();
    let mut reader = RowReader::new(converted.as_slice()).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    let sequences: Vec<u32> = rows.iter().map(|row| row.sequence).collect();
    let infinite_kept = match sequences[..] {
        [1, 2] => {
            assert!(stderr.contains("line 5: c11_pf 'inf'"), "{stderr}");
            false
        }
        [1, 2, 4] => true,
        _ => panic!("rows {sequences:?}: NaN's row must be left out, the others kept"),
    };
    assert_eq!(
        rows[1].reading.unwrap().capacitance_pf,
        [Some(1e30), Some(-1e30), Some(f32::MAX), Some(200.0)],
        "the recorded values are kept as they were"
    );
    if infinite_kept {
        let capacitance_pf = rows[2].reading.unwrap().capacitance_pf;
        assert_eq!(
            capacitance_pf[..2],
            [Some(f32::INFINITY), Some(f32::NEG_INFINITY)]
        );
        assert!(capacitance_pf[2..]
            .iter()
            .all(|value| value.is_some_and(f32::is_infinite)));
    }
    for row in &rows[1..] {
        let reading = row.reading.unwrap();
        for taxel in 0..TAXEL_COUNT {
            assert_eq!(
                reading.pressure_kpa[taxel], None,
                "set {}: no pressure from a non-measurement",
                row.sequence
            );
            assert!(
                reading.flags[taxel].contains(TaxelFlags::INVALID_INPUT),
                "set {}: flagged: {:?}",
                row.sequence,
                reading.flags[taxel]
            );
        }
        assert_eq!(reading.force_n, None);
    }
}

/// What a huge input does: it ends quickly with a message of bounded length (it quotes what it
/// found, not all of it) and writes nothing.
fn assert_ends_quickly_with_a_short_message(
    directory: &Path,
    input: &str,
    status: i32,
    messages: &[&str],
) {
    for arguments in [
        &["convert", input, "-o", "out.csv"][..],
        &["plot", input, "-o", "out.svg"][..],
    ] {
        let started = Instant::now();
        let output = run_in(directory, arguments);
        let stderr = String::from_utf8_lossy(&output.stderr);
        let shown: String = stderr.chars().take(2000).collect();
        let expected_status = if arguments[0] == "plot" && status == 3 {
            0
        } else {
            status
        };
        assert_eq!(
            output.status.code(),
            Some(expected_status),
            "{arguments:?}: {shown}"
        );
        for message in messages {
            assert!(stderr.contains(message), "{arguments:?}: {shown}");
        }
        assert!(
            stderr.len() <= LONGEST_MESSAGE,
            "{arguments:?}: {} bytes of messages: {shown}...",
            stderr.len()
        );
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "{arguments:?}: {:?}",
            started.elapsed()
        );
    }
}

#[test]
fn a_200_mb_file_without_a_line_break_ends_quickly_with_a_clear_message() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("big.csv");
    {
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let chunk = vec![b'x'; 1 << 20];
        for _ in 0..200 {
            file.write_all(&chunk).unwrap();
        }
    }
    assert_ends_quickly_with_a_short_message(
        directory.path(),
        "big.csv",
        1,
        &["the header is not a taxel recording's"],
    );
    assert!(!directory.path().join("out.csv").exists());
    assert!(!directory.path().join("out.svg").exists());
}

#[test]
fn a_megabyte_cell_is_a_row_named_in_a_short_message() {
    let directory = tempfile::tempdir().unwrap();
    // A megabyte of digits with a letter at the end: not a number, however numbers are read.
    let huge_cell = "7".repeat(1 << 20) + "x";
    let bad = row_with(&[(8, &huge_cell)]);
    std::fs::write(directory.path().join("in.csv"), with_bad_line_3(&bad)).unwrap();
    assert_ends_quickly_with_a_short_message(
        directory.path(),
        "in.csv",
        3,
        &["line 3: ", "c11_pf '777"],
    );
    let converted = std::fs::read(directory.path().join("out.csv")).unwrap();
    assert_eq!(sequences(&converted), [1, 3]);
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
    let rows: Vec<PadRow> = (1..20_000).map(unloaded).collect();
    std::fs::write(directory.path().join("in.csv"), recording(&rows)).unwrap();
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
    std::fs::write(directory.path().join("in.csv"), good_recording()).unwrap();
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
