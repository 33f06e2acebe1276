//! `taxel record` with several devices: every sample set on one host timeline.
//!
//! In process: two simulated boards, their crystals +100 and -100 ppm off and their clocks
//! started at different times, each behind a port that the host library reads as it reads a
//! serial port — a `DeviceSession` per board (identity, state, stream) set up one after the
//! other as `taxel record` does, then the `Worker`'s threads and the `Recorder` (CSV and MCAP).
//! A small discrete-event world owns the host clock the worker stamps arrivals with: it steps
//! the boards, delivers their bytes after a jittery USB latency, and moves time on only when
//! every reader waits for bytes (a port nobody reads holds its bytes, as a serial port does), so
//! each frame is stamped with the instant it was delivered. The recording is compared with the
//! simulations' true sampling instants, which the recorder never sees.
//!
//! Through the binary: two `taxel sim` processes recorded by one `taxel record`.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::SimulatorProcess;

use std::collections::{HashMap, VecDeque};
use std::io::{self, BufReader, Read, Write};
use std::path::Path;
use std::process::Command;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use sim_device::{ClockError, MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use taxel_host::device_link::DeviceLink;
use taxel_host::host_clock::{HostClock, UnixClock};
use taxel_host::recorder::{Recorder, RecordingPaths};
use taxel_host::schema::{header, PadRow, RowReader};
use taxel_host::session::{DeviceSession, SessionConfig};
use taxel_host::worker::{EndReason, EventQueue, Overflow, Worker, WorkerEvent};
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
    /// Nobody reads the port (before its session is opened, and between its set-up and the
    /// worker's first read): its bytes wait in the port and time goes on without it.
    parked: bool,
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
    /// Every reader waits with nothing delivered (or nobody reads): time may move on.
    fn idle(&self) -> bool {
        self.boards.iter().all(|board| {
            board.gone || board.parked || (board.waiting && board.delivered.is_empty())
        })
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
                    // A delivery to a port nobody reads does not stop time.
                    delivered |= !board.parked;
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

impl Shared {
    /// Nobody reads board `index` until its next read.
    fn park(&self, index: usize) {
        self.world.lock().unwrap().boards[index].parked = true;
        self.changed.notify_all();
    }
}

/// The host end of one board's link, as the host library reads a serial port.
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
            board.parked = false;
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

/// The world's clock: the host clock the worker stamps every arrival with.
struct WorldClock(Arc<Shared>);

impl HostClock for WorldClock {
    fn now_us(&self) -> u64 {
        self.0.world.lock().unwrap().time_us
    }
}

fn board(seed: u64, clock_error: ClockError, host_start_us: u64) -> Board {
    let device = SimulatedDevice::with_clock_error(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1).with_seed(seed),
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
        parked: true,
        gone: false,
    }
}

/// Every row of a recording, read with the schema's reader.
fn read_rows(path: &Path) -> Vec<PadRow> {
    let file = BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = RowReader::new(file).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

fn first_line(path: &Path) -> String {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_owned()
}

/// The pressure messages of an MCAP file: (topic, sequence) -> (publish time, log time), ns.
fn pressure_messages(path: &Path) -> HashMap<(String, u32), (u64, u64)> {
    let bytes = std::fs::read(path).unwrap();
    let mut messages = HashMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        if message.channel.topic.ends_with("/pressure") {
            let previous = messages.insert(
                (message.channel.topic.clone(), message.sequence),
                (message.publish_time, message.log_time),
            );
            assert!(previous.is_none(), "{} written twice", message.sequence);
        }
    }
    messages
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
    let directory = tempfile::tempdir().unwrap();
    let csv_path = directory.path().join("rec.csv");
    let mcap_path = directory.path().join("rec.mcap");
    // The recorder turns the world's µs into Unix time from this clock's origin.
    let unix_clock = UnixClock::new();
    let origin_unix_us = unix_clock.origin_unix_us();
    let mut recorder = Recorder::create(
        RecordingPaths {
            csv: Some(csv_path.clone()),
            mcap: Some(mcap_path.clone()),
        },
        2,
        unix_clock,
        None,
    )
    .unwrap();
    let started = Instant::now();
    // As `taxel record` does: each device identified, its state read, its raw log in place
    // and its stream started, one after the other; then every device on its own thread.
    let mut sessions = Vec::new();
    for index in 0..2 {
        let link = DeviceLink::new(WorldPort {
            shared: Arc::clone(&shared),
            index,
        });
        let config = SessionConfig {
            request_timeout: Duration::from_secs(2),
            follow_state: true,
        };
        let mut session = DeviceSession::open(link, config).unwrap();
        session
            .link_mut()
            .set_raw_log(recorder.raw_log(index).unwrap());
        session.start().unwrap();
        shared.park(index);
        sessions.push(session);
    }
    let queue = Arc::new(EventQueue::new(100_000, Overflow::Wait));
    let clock: Arc<dyn HostClock> = Arc::new(WorldClock(Arc::clone(&shared)));
    let worker = Worker::start(sessions, Arc::clone(&queue), clock).unwrap();
    let mut ended = 0;
    while ended < 2 {
        let Some(arrived) = queue.pop_until(Instant::now() + Duration::from_millis(100)) else {
            assert!(
                started.elapsed() < Duration::from_secs(300),
                "the world stalled"
            );
            continue;
        };
        if matches!(arrived.event, WorkerEvent::Ended(_)) {
            ended += 1;
        }
        recorder.take(arrived).unwrap();
    }
    for mut session in worker.finish().into_iter().flatten() {
        if let Some(mut raw) = session.link_mut().take_raw_log() {
            raw.flush().unwrap();
        }
    }
    for arrived in queue.drain() {
        recorder.take(arrived).unwrap();
    }
    let summary = recorder.finish().unwrap();
    eprintln!("recorded in {:?}", started.elapsed());
    for name in [
        "rec.csv",
        "rec.mcap",
        "rec.csv.dev0.raw",
        "rec.csv.dev1.raw",
        "rec.csv.dev0.device.json",
        "rec.csv.dev1.device.json",
    ] {
        assert!(directory.path().join(name).exists(), "{name}");
    }

    assert_eq!(first_line(&csv_path), header().join(","));
    let rows = read_rows(&csv_path);
    let mcap = pressure_messages(&mcap_path);
    assert_eq!(mcap.len(), rows.len(), "a pressure message per row");

    let world = shared.world.lock().unwrap();
    let mut worst_us = [0_i64; 2];
    let mut covered = 0_usize;
    for (device, board) in world.boards.iter().enumerate() {
        let device_summary = &summary.devices[device];
        let end = device_summary.end.as_ref().unwrap();
        // The world ended: each board was unplugged.
        assert!(
            matches!(&end.reason, EndReason::Disconnected(_)),
            "device {device}: {:?}",
            end.reason
        );
        let recorded: Vec<&PadRow> = rows
            .iter()
            .filter(|row| row.device as usize == device)
            .collect();
        assert_eq!(device_summary.rows, recorded.len() as u64);
        assert_eq!(device_summary.sets, recorded.len() as u64, "one pad");
        assert_eq!(
            device_summary.stamped_at_arrival, 0,
            "device {device}: every set had a clock estimate within the wait"
        );
        assert!(
            recorded
                .windows(2)
                .all(|pair| pair[0].host_time_us <= pair[1].host_time_us),
            "device {device}: rows in host-time order"
        );
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
        assert_eq!(end.accounting.received(), sequences.len() as u64);
        assert_eq!(end.accounting.lost_on_link(), 0);
        assert!(
            sequences.len() > 900,
            "device {device}: {}",
            sequences.len()
        );
        for row in &recorded {
            let (device_us, true_us) = board.truth[&row.sequence];
            assert_eq!(row.reading.unwrap().device_time_us, device_us);
            // Finite (a number) on every row: every set had an estimate.
            let sync_error_us = row.sync_error_us.unwrap();
            let host_us = row.host_time_us - origin_unix_us;
            let error_us = host_us as i64 - true_us as i64;
            worst_us[device] = worst_us[device].max(error_us.abs());
            if error_us.unsigned_abs() <= sync_error_us {
                covered += 1;
            }
            // The MCAP message of the same set: the same stamp, never after its arrival, which
            // is never before the truth.
            let topic = format!("/taxel/device{device}/pad0/pressure");
            let (publish_ns, log_ns) = mcap[&(topic, row.sequence)];
            assert_eq!(publish_ns, row.host_time_us * 1_000, "device {device}");
            assert!(publish_ns <= log_ns, "stamped after its arrival");
            assert!(
                log_ns >= (origin_unix_us + true_us) * 1_000,
                "arrived early"
            );
        }
        let estimate = device_summary.clock.unwrap();
        let drift_error_ppm = estimate.drift_ppm - clock_errors[device].rate_ppm;
        eprintln!(
            "device {device}: {} rows; worst |host - true| {} us; drift {:+.2} ppm (true {:+}), \
             offset {} us, synchronisation error {} us; {}",
            recorded.len(),
            worst_us[device],
            estimate.drift_ppm,
            clock_errors[device].rate_ppm,
            estimate.offset_us,
            estimate.uncertainty_us,
            end.accounting.summary()
        );
        assert!(drift_error_ppm.abs() < 5.0, "drift {}", estimate.drift_ppm);
        assert!(estimate.uncertainty_us < 1_000);
    }
    // One timeline: the rows of both devices by host time (the file holds each device's rows
    // in order, interleaved as they were stamped), samples more than 2 ms apart in truth in
    // their true order.
    let mut timeline: Vec<(u64, u64)> = rows
        .iter()
        .map(|row| {
            let (_, true_us) = world.boards[row.device as usize].truth[&row.sequence];
            (row.host_time_us, true_us)
        })
        .collect();
    timeline.sort_by_key(|&(host_us, _)| host_us);
    for pair in timeline.windows(2) {
        let (earlier, later) = (pair[0].1, pair[1].1);
        assert!(earlier <= later + 2_000, "{earlier} then {later}");
    }
    let covered_share = covered as f64 / rows.len() as f64;
    eprintln!(
        "sync_error_ms >= |host - true| on {covered} of {} rows ({:.2} %)",
        rows.len(),
        covered_share * 100.0
    );
    // Every row, from the first: a set waits for its device's first clock estimate.
    for (device, worst_us) in worst_us.iter().enumerate() {
        assert!(*worst_us <= 1_000, "device {device}: {worst_us} us");
    }
    // The rule: the error column covers the actual error on every row.
    assert_eq!(covered, rows.len(), "{covered_share}");
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
            "300 sample sets recorded",
            "received",
            "lost on the link",
            "dropped by the device",
            "clock offset",
            "drift",
            "sync error",
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
    // A device's raw log converts with that device's state, found beside it.
    let converted = directory.path().join("dev1.csv");
    let state = directory.path().join("rec.csv.dev1.device.json");
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
        convert_messages.contains(&format!(
            "converting with the device state in {}",
            state.display()
        )),
        "{convert_messages}"
    );
    assert!(
        !convert_messages.contains("no recorded state"),
        "{convert_messages}"
    );
    assert_eq!(first_line(&csv_path), header().join(","));
    let rows = read_rows(&csv_path);
    assert_eq!(rows.len(), 600);
    for device in 0..2 {
        let recorded: Vec<&PadRow> = rows.iter().filter(|row| row.device == device).collect();
        // --samples N: N sets of each device.
        assert_eq!(recorded.len(), 300, "device {device}");
        assert!(
            recorded
                .windows(2)
                .all(|pair| pair[0].host_time_us <= pair[1].host_time_us
                    && pair[1].sequence == pair[0].sequence + 1),
            "device {device}: consecutive sets in host-time order"
        );
        assert!(
            recorded.iter().all(|row| row.sync_error_us.is_some()),
            "device {device}: every set had a clock estimate"
        );
    }
    // Both devices on one timeline: the recording's Unix times, within the few seconds it ran.
    let (earliest, latest) = rows.iter().fold((u64::MAX, 0), |(low, high), row| {
        (low.min(row.host_time_us), high.max(row.host_time_us))
    });
    assert!(latest - earliest < 30_000_000, "{earliest} to {latest}");
}
