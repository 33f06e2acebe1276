//! `taxel record` with several devices: every sample on one host timeline.
//!
//! In process: two simulated boards, their crystals +100 and -100 ppm off and their clocks
//! started at different times, each behind a port that the recorder reads from its own thread
//! as it reads a serial port. A small discrete-event world owns the host clock: it steps the
//! boards, delivers their bytes after a jittery USB latency, and moves time on only when every
//! reader waits for bytes, so each frame is stamped with the instant it was delivered. The
//! recording's CSV is compared with the simulations' true sampling instants, which the
//! recorder never sees.
//!
//! Through the binary: two `taxel sim` processes recorded by one `taxel record`.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::SimulatorProcess;

use std::collections::{HashMap, VecDeque};
use std::io::{self, Read, Write};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use sim_device::{ClockError, MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use taxel_host::multi_record::{record_devices, DeviceInput, HostClock, MultiRecordOptions};
use taxel_host::record::StopReason;
use taxel_host::timeline_files::timeline_header;
use wire::{DeviceFrame, DeviceFrameDecoder};

/// A small xorshift for the latency (the test's own, seeded), as in multi_device_timeline.rs.
struct Latency(u64);

impl Latency {
    fn next_us(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        // 0.1 to 1 ms, and 2 % of the deliveries 5 to 30 ms late (a busy host).
        let jitter_us = 100 + self.0 % 900;
        if self.0.is_multiple_of(50) {
            jitter_us + 5_000 + (self.0 >> 8) % 25_000
        } else {
            jitter_us
        }
    }
}

/// Bytes on their way to the host: when they arrive, and the sample frames among them.
struct InFlight {
    delivery_us: u64,
    bytes: Vec<u8>,
    sequences: Vec<u32>,
}

/// One simulated board and what is between it and its reader.
struct Board {
    device: SimulatedDevice,
    port: MemoryPort,
    /// Host time at which the board's simulation starts.
    host_start_us: u64,
    decoder: DeviceFrameDecoder,
    in_flight: VecDeque<InFlight>,
    last_delivery_us: u64,
    delivered: VecDeque<u8>,
    /// Sequence numbers of the sample frames delivered to the reader, in order.
    delivered_sequences: Vec<u32>,
    /// Sequence number -> (device timestamp, true host instant) of every sample frame.
    truth: HashMap<u32, (u64, u64)>,
    /// The reader waits for bytes (it is not between a read and its stamping).
    waiting: bool,
    /// The reader dropped its port.
    gone: bool,
}

impl Board {
    fn next_step_us(&self) -> u64 {
        self.host_start_us + self.device.simulation().now_us()
    }
}

struct World {
    time_us: u64,
    end_us: u64,
    boards: Vec<Board>,
    latency: Latency,
}

impl World {
    /// Every reader waits with nothing delivered: time may move on.
    fn idle(&self) -> bool {
        self.boards
            .iter()
            .all(|board| board.gone || (board.waiting && board.delivered.is_empty()))
    }

    /// Moves time on to the next delivery (or the end), stepping the boards on the way.
    fn advance(&mut self) {
        let World {
            time_us,
            end_us,
            boards,
            latency,
        } = self;
        loop {
            for board in boards.iter_mut().filter(|board| !board.gone) {
                while board.next_step_us() <= *time_us {
                    board.device.step(&mut board.port);
                    // The frame was stamped at the end of the cycle: the simulation's time now.
                    let true_us = board.next_step_us();
                    let bytes = board.port.take_for_host(usize::MAX);
                    if bytes.is_empty() {
                        continue;
                    }
                    let mut sequences = Vec::new();
                    for frame in board.decoder.feed(&bytes) {
                        if let Ok(DeviceFrame::Sample(sample)) = frame {
                            board
                                .truth
                                .insert(sample.sequence, (sample.timestamp_us, true_us));
                            sequences.push(sample.sequence);
                        }
                    }
                    // Bytes keep their order on the link.
                    let delivery_us = (true_us + latency.next_us()).max(board.last_delivery_us);
                    board.last_delivery_us = delivery_us;
                    board.in_flight.push_back(InFlight {
                        delivery_us,
                        bytes,
                        sequences,
                    });
                }
            }
            let mut delivered = false;
            for board in boards.iter_mut() {
                while board
                    .in_flight
                    .front()
                    .is_some_and(|flight| flight.delivery_us <= *time_us)
                {
                    let flight = board.in_flight.pop_front().unwrap();
                    board.delivered.extend(flight.bytes);
                    board.delivered_sequences.extend(flight.sequences);
                    delivered = true;
                }
            }
            if delivered || *time_us >= *end_us {
                return;
            }
            let next_us = boards
                .iter()
                .filter(|board| !board.gone)
                .flat_map(|board| {
                    [
                        Some(board.next_step_us()),
                        board.in_flight.front().map(|flight| flight.delivery_us),
                    ]
                })
                .flatten()
                .min()
                .unwrap_or(*end_us);
            *time_us = next_us.clamp(*time_us, *end_us);
        }
    }
}

struct Shared {
    world: Mutex<World>,
    changed: Condvar,
}

/// The host end of one board's link, as the recorder reads a serial port.
struct WorldPort {
    shared: Arc<Shared>,
    index: usize,
}

impl Read for WorldPort {
    fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
        // Like a serial port's read timeout, so that the reader sees its stop flag.
        let deadline = Instant::now() + Duration::from_millis(50);
        let mut world = self.shared.world.lock().unwrap();
        loop {
            let (time_us, end_us) = (world.time_us, world.end_us);
            let board = &mut world.boards[self.index];
            if !board.delivered.is_empty() {
                board.waiting = false;
                let count = buffer.len().min(board.delivered.len());
                for (slot, byte) in buffer.iter_mut().zip(board.delivered.drain(..count)) {
                    *slot = byte;
                }
                return Ok(count);
            }
            if time_us >= end_us {
                // Unplugged.
                return Ok(0);
            }
            board.waiting = true;
            if world.idle() {
                world.advance();
                self.shared.changed.notify_all();
                continue;
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(io::ErrorKind::TimedOut.into());
            }
            world = self
                .shared
                .changed
                .wait_timeout(world, deadline - now)
                .unwrap()
                .0;
        }
    }
}

impl Write for WorldPort {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let mut world = self.shared.world.lock().unwrap();
        world.boards[self.index].port.to_device.extend(bytes);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Drop for WorldPort {
    fn drop(&mut self) {
        if let Ok(mut world) = self.shared.world.lock() {
            world.boards[self.index].gone = true;
        }
        self.shared.changed.notify_all();
    }
}

/// The world's clock: the host clock every reader stamps with.
struct WorldClock(Arc<Shared>);

impl HostClock for WorldClock {
    fn now_us(&self) -> u64 {
        self.0.world.lock().unwrap().time_us
    }
}

fn board(seed: u64, clock_error: ClockError, host_start_us: u64) -> Board {
    let device = SimulatedDevice::with_clock_error(
        SimulatedDeviceConfig {
            scene: SceneFile::default_scene().unwrap(),
            seed,
            speed: None,
            topology: sim_device::pads_topology(1),
            bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
        },
        clock_error,
    )
    .unwrap();
    Board {
        device,
        port: MemoryPort::new(usize::MAX),
        host_start_us,
        decoder: DeviceFrameDecoder::new(),
        in_flight: VecDeque::new(),
        last_delivery_us: 0,
        delivered: VecDeque::new(),
        delivered_sequences: Vec::new(),
        truth: HashMap::new(),
        waiting: false,
        gone: false,
    }
}

/// "12.345678" as µs, exactly.
fn parse_us(cell: &str) -> u64 {
    let (seconds, micros) = cell.split_once('.').unwrap();
    assert_eq!(micros.len(), 6, "{cell}");
    seconds.parse::<u64>().unwrap() * 1_000_000 + micros.parse::<u64>().unwrap()
}

/// "1.234" ms as µs, exactly.
fn parse_error_us(cell: &str) -> u64 {
    let (millis, micros) = cell.split_once('.').unwrap();
    assert_eq!(micros.len(), 3, "{cell}");
    millis.parse::<u64>().unwrap() * 1_000 + micros.parse::<u64>().unwrap()
}

struct Row {
    host_us: u64,
    device: usize,
    sequence: u32,
    device_us: u64,
    sync_error_us: u64,
}

fn read_rows(path: &Path) -> (Vec<String>, Vec<csv::StringRecord>) {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let header = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    let records = reader.records().map(Result::unwrap).collect();
    (header, records)
}

#[test]
fn two_boards_at_plus_and_minus_100_ppm_are_recorded_on_one_host_timeline() {
    let clock_errors = [
        ClockError {
            rate_ppm: 100.0,
            offset_us: 3_200_000,
        },
        ClockError {
            rate_ppm: -100.0,
            offset_us: 0,
        },
    ];
    let shared = Arc::new(Shared {
        world: Mutex::new(World {
            time_us: 0,
            end_us: 11_000_000,
            boards: vec![
                board(1, clock_errors[0], 0),
                board(2, clock_errors[1], 700_000),
            ],
            latency: Latency(0x9E37_79B9_7F4A_7C15),
        }),
        changed: Condvar::new(),
    });
    let devices: Vec<DeviceInput<WorldPort>> = (0..2)
        .map(|index| DeviceInput {
            name: format!("simulated board {index}"),
            port: WorldPort {
                shared: Arc::clone(&shared),
                index,
            },
        })
        .collect();
    let directory = tempfile::tempdir().unwrap();
    let csv_path = directory.path().join("rec.csv");
    let stop = AtomicBool::new(false);
    let started = Instant::now();
    let summary = record_devices(
        devices,
        &csv_path,
        &WorldClock(Arc::clone(&shared)),
        &stop,
        &MultiRecordOptions::default(),
        &|message| eprintln!("{message}"),
    )
    .unwrap();
    eprintln!("recorded in {:?}", started.elapsed());
    for name in [
        "rec.csv",
        "rec.csv.dev0.raw",
        "rec.csv.dev1.raw",
        "rec.csv.dev0.device.json",
        "rec.csv.dev1.device.json",
    ] {
        assert!(directory.path().join(name).exists(), "{name}");
    }
    assert!(
        matches!(&summary.stop_reason, StopReason::Disconnected(message) if message.starts_with("device 0")),
        "{:?}",
        summary.stop_reason
    );

    let (header, records) = read_rows(&csv_path);
    assert_eq!(header, timeline_header());
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let rows: Vec<Row> = records
        .iter()
        .map(|record| Row {
            host_us: parse_us(&record[column("host_time_s")]),
            device: record[column("device")].parse().unwrap(),
            sequence: record[column("seq")].parse().unwrap(),
            device_us: parse_us(&record[column("device_time_s")]),
            // Finite (a number) on every row: both boards always have an estimate.
            sync_error_us: parse_error_us(&record[column("sync_error_ms")]),
        })
        .collect();
    assert_eq!(summary.rows, rows.len() as u64);
    assert!(
        rows.windows(2)
            .all(|pair| pair[0].host_us <= pair[1].host_us),
        "rows in host-time order"
    );

    let world = shared.world.lock().unwrap();
    let mut worst_us = [0_i64; 2];
    let mut covered = 0_usize;
    for (device, board) in world.boards.iter().enumerate() {
        let recorded: Vec<&Row> = rows.iter().filter(|row| row.device == device).collect();
        let sequences: Vec<u32> = recorded.iter().map(|row| row.sequence).collect();
        // Every frame the host received from the start of the stream on, once, in order.
        let first = board
            .delivered_sequences
            .iter()
            .position(|&sequence| sequence == sequences[0])
            .unwrap();
        assert_eq!(
            sequences,
            board.delivered_sequences[first..],
            "device {device}"
        );
        let accounting = &summary.devices[device].accounting;
        assert_eq!(accounting.received(), sequences.len() as u64);
        assert_eq!(accounting.lost_on_link(), 0);
        assert!(
            sequences.len() > 900,
            "device {device}: {}",
            sequences.len()
        );
        for row in &recorded {
            let (device_us, true_us) = board.truth[&row.sequence];
            assert_eq!(row.device_us, device_us);
            let error_us = row.host_us as i64 - true_us as i64;
            worst_us[device] = worst_us[device].max(error_us.abs());
            if error_us.unsigned_abs() <= row.sync_error_us {
                covered += 1;
            }
        }
        let estimate = summary.devices[device].estimate.unwrap();
        let drift_error_ppm = estimate.drift_ppm - clock_errors[device].rate_ppm;
        eprintln!(
            "device {device}: {} rows; worst |host - true| {} us; drift {:+.2} ppm (true {:+}), \
             offset {} us, synchronisation error {} us",
            recorded.len(),
            worst_us[device],
            estimate.drift_ppm,
            clock_errors[device].rate_ppm,
            estimate.offset_us,
            estimate.uncertainty_us
        );
        assert!(drift_error_ppm.abs() < 5.0, "drift {}", estimate.drift_ppm);
        assert!(estimate.uncertainty_us < 1_000);
        eprintln!("device {device}: {}", summary.devices[device].words());
    }
    let covered_share = covered as f64 / rows.len() as f64;
    eprintln!(
        "sync_error_ms >= |host - true| on {covered} of {} rows ({:.2} %)",
        rows.len(),
        covered_share * 100.0
    );
    // Every row, from the first: the estimator settles in about 1.5 s of frames and a row is
    // written with the estimate of the hold (4 s) after it, so no row is written unsettled.
    for (device, worst_us) in worst_us.iter().enumerate() {
        assert!(*worst_us <= 1_000, "device {device}: {worst_us} us");
    }
    // The rule: the error column covers the actual error on at least 99 % of the rows.
    assert!(covered_share >= 0.99, "{covered_share}");
}

fn taxel() -> Command {
    Command::new(support::taxel_binary())
}

#[test]
fn two_simulators_recorded_through_the_binary() {
    let directory = tempfile::tempdir().unwrap();
    let mut first = SimulatorProcess::start(directory.path(), "port1", &["--seed", "1"]);
    let first_port = first.port.clone();
    let mut second = SimulatorProcess::start(directory.path(), "port2", &["--seed", "2"]);
    let second_port = second.port.clone();
    let csv_path = directory.path().join("rec.csv");
    let output = taxel()
        .args([
            "record",
            &first_port,
            &second_port,
            "--samples",
            "300",
            "-o",
        ])
        .arg(&csv_path)
        .output()
        .unwrap();
    first.stop();
    second.stop();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    eprintln!("{messages}");
    assert!(output.status.success(), "{messages}");
    for device in 0..2 {
        let line = messages
            .lines()
            .find(|line| line.starts_with(&format!("device {device} (")))
            .unwrap_or_else(|| panic!("no summary of device {device}: {messages}"));
        for words in [
            "300 sample sets received",
            "lost on the link",
            "dropped by the device",
            "clock offset",
            "drift",
            "synchronisation error",
        ] {
            assert!(line.contains(words), "{words}: {line}");
        }
        assert!(directory
            .path()
            .join(format!("rec.csv.dev{device}.raw"))
            .exists());
        assert!(directory
            .path()
            .join(format!("rec.csv.dev{device}.device.json"))
            .exists());
    }
    assert!(
        messages.contains("sample limit reached on every device"),
        "{messages}"
    );
    // A device's raw log converts with that device's state, found beside it.
    let converted = directory.path().join("dev1.csv");
    let output = taxel()
        .arg("convert")
        .arg("--raw")
        .arg(directory.path().join("rec.csv.dev1.raw"))
        .arg("-o")
        .arg(&converted)
        .output()
        .unwrap();
    let convert_messages = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{convert_messages}");
    assert!(
        convert_messages.contains("the device's calibration recorded with it"),
        "{convert_messages}"
    );
    let (header, records) = read_rows(&csv_path);
    assert_eq!(header, timeline_header());
    assert_eq!(records.len(), 600);
    let host = header.iter().position(|h| h == "host_time_s").unwrap();
    let device = header.iter().position(|h| h == "device").unwrap();
    let times: Vec<u64> = records
        .iter()
        .map(|record| parse_us(&record[host]))
        .collect();
    assert!(times.windows(2).all(|pair| pair[0] <= pair[1]));
    for index in ["0", "1"] {
        assert_eq!(
            records
                .iter()
                .filter(|record| &record[device] == index)
                .count(),
            300
        );
    }
}
