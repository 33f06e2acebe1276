//! The one stream loop, against the simulated device (the firmware's own code on a
//! pseudo-terminal): sessions on the worker's threads deliver every pad's frame of every set in
//! order, answer requests while streaming without losing a set, follow a tare's baselines, and
//! end with their accounting; a live queue drops its oldest sets, counted, and keeps events.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use sim_device::{scene_config, SimulatorThread};
use taxel_host::device_link::{open_serial, DeviceLink};
use taxel_host::host_clock::MonotonicClock;
use taxel_host::session::{DeviceSession, SessionConfig, SessionEvent};
use taxel_host::worker::{EndReason, EventQueue, Overflow, Worker, WorkerEvent};
use wire::{Command, DeviceEvent, ReplyPayload};

/// An unloaded pad at room temperature: the device accepts a tare at any time.
const STILL_SCENE: &str = "name = \"still\"\n\
[[keyframe]]\ntime_s = 0.0\npressure_kpa = [0.0, 0.0, 0.0, 0.0]\ntemperature_c = 25.0\n";

fn simulator(pads: Option<u8>) -> SimulatorThread {
    let directory = tempfile::tempdir().unwrap();
    let scene = directory.path().join("still.toml");
    std::fs::write(&scene, STILL_SCENE).unwrap();
    let config = scene_config(Some(&scene), pads, Some(10.0), 3).unwrap();
    let simulator = SimulatorThread::start(config, None).unwrap();
    // The device tares itself on its first sets after boot (0.26 s here): let that pass, so
    // that the only tare a test sees is its own.
    std::thread::sleep(Duration::from_secs(1));
    simulator
}

fn session(
    simulator: &SimulatorThread,
    follow_state: bool,
) -> DeviceSession<Box<dyn serialport::SerialPort>> {
    let port = open_serial(
        &simulator.path().display().to_string(),
        Duration::from_millis(20),
    )
    .unwrap();
    let config = SessionConfig {
        request_timeout: Duration::from_secs(5),
        follow_state,
    };
    let mut session = DeviceSession::open(DeviceLink::new(port.port), config).unwrap();
    session.start().unwrap();
    session
}

#[test]
fn two_devices_deliver_every_set_in_order_and_answer_requests_while_streaming() {
    let one = simulator(None);
    let three = simulator(Some(3));
    let queue = Arc::new(EventQueue::new(100_000, Overflow::Wait));
    let worker = Worker::start(
        vec![session(&one, true), session(&three, true)],
        Arc::clone(&queue),
        Arc::new(MonotonicClock::new()),
    )
    .unwrap();
    let mut sequences: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
    let mut baselines = [0usize; 2];
    let mut tare_finished = [false; 2];
    let mut last_arrival = [0u64; 2];
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut tared = false;
    while sequences.iter().any(|device| device.len() < 300)
        || !tare_finished.iter().all(|done| *done)
    {
        assert!(
            Instant::now() < deadline,
            "sets so far: {} and {}",
            sequences[0].len(),
            sequences[1].len()
        );
        if !tared && sequences.iter().all(|device| device.len() >= 50) {
            // A request in the middle of the stream, for each device: no set may go missing.
            for device in 0..2 {
                let reply = worker
                    .request(
                        device,
                        Command::Tare {
                            sample_sets: 8,
                            pad: None,
                        },
                        Duration::from_secs(5),
                    )
                    .unwrap();
                assert_eq!(reply, ReplyPayload::Ack);
            }
            tared = true;
        }
        let Some(arrived) = queue.pop_until(Instant::now() + Duration::from_millis(100)) else {
            continue;
        };
        assert!(
            arrived.arrival_us >= last_arrival[arrived.device],
            "arrivals go forward per device"
        );
        last_arrival[arrived.device] = arrived.arrival_us;
        match arrived.event {
            WorkerEvent::Session(SessionEvent::Set {
                set,
                sets_missing_before,
            }) => {
                assert_eq!(sets_missing_before, 0);
                assert_eq!(set.pads.len(), [1, 3][arrived.device]);
                assert!(set.is_complete(), "{set:?}");
                for (pad, frame) in set.pads.iter().enumerate() {
                    let frame = frame.as_ref().unwrap();
                    assert_eq!(usize::from(frame.pad.get()), pad);
                    assert_eq!(frame.sequence, set.sequence);
                }
                sequences[arrived.device].push(set.sequence);
            }
            WorkerEvent::Session(SessionEvent::Baselines { change, .. }) => {
                assert!(change.taxels.iter().all(Option::is_some));
                baselines[arrived.device] += 1;
            }
            WorkerEvent::Session(SessionEvent::Device(event)) => {
                if let DeviceEvent::TareFinished { .. } = event.event {
                    tare_finished[arrived.device] = true;
                }
            }
            WorkerEvent::Ended(end) => panic!("device {} ended: {:?}", arrived.device, end.reason),
            _ => {}
        }
    }
    for device in &sequences {
        assert!(
            device.windows(2).all(|pair| pair[1] == pair[0] + 1),
            "consecutive sets"
        );
    }
    // A pad's new baselines apply from its next frame: every pad of each device got one.
    let sessions = worker.finish();
    let mut ended = [false; 2];
    for arrived in queue.drain() {
        match arrived.event {
            WorkerEvent::Session(SessionEvent::Baselines { .. }) => baselines[arrived.device] += 1,
            WorkerEvent::Ended(end) => {
                assert_eq!(end.reason, EndReason::Stopped);
                assert_eq!(end.accounting.lost_on_link(), 0);
                assert_eq!(end.accounting.sequence_gap_sets(), 0);
                assert!(end.counters.is_some(), "counters read at the stop");
                let state = end.state.unwrap();
                let history = &state.pad_state(0).unwrap().baselines;
                assert_eq!(
                    history.len(),
                    2,
                    "the first read and the tare's: {history:?}"
                );
                ended[arrived.device] = true;
            }
            _ => {}
        }
    }
    assert_eq!(ended, [true, true]);
    assert_eq!(baselines, [1, 3], "one baseline change per tared pad");
    assert!(sessions.iter().all(Option::is_some));
    one.stop();
    three.stop();
}

#[test]
fn a_live_queue_drops_its_oldest_sets_counted_and_keeps_every_other_event() {
    let device = simulator(None);
    let queue = Arc::new(EventQueue::new(20, Overflow::DropOldestSet));
    let worker = Worker::start(
        vec![session(&device, false)],
        Arc::clone(&queue),
        Arc::new(MonotonicClock::new()),
    )
    .unwrap();
    // Nobody reads for a while; then a tare, whose events must survive the full queue.
    std::thread::sleep(Duration::from_millis(500));
    worker
        .request(
            0,
            Command::Tare {
                sample_sets: 4,
                pad: None,
            },
            Duration::from_secs(5),
        )
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let events = queue.drain();
    assert!(queue.dropped_sets() > 0, "the queue never filled");
    let sets: Vec<u32> = events
        .iter()
        .filter_map(|arrived| match &arrived.event {
            WorkerEvent::Session(SessionEvent::Set { set, .. }) => Some(set.sequence),
            _ => None,
        })
        .collect();
    assert!(sets.len() <= 20);
    assert!(
        sets.windows(2).all(|pair| pair[1] == pair[0] + 1),
        "the newest sets, in order: {sets:?}"
    );
    let tare_events = events
        .iter()
        .filter(|arrived| {
            matches!(
                &arrived.event,
                WorkerEvent::Session(SessionEvent::Device(event))
                    if matches!(event.event, DeviceEvent::TareFinished { .. })
            )
        })
        .count();
    assert_eq!(tare_events, 1, "the tare's event is kept");
    drop(worker);
    device.stop();
}

#[test]
fn a_device_that_went_away_is_read_again_under_its_number_when_it_is_back() {
    let first = simulator(None);
    let queue = Arc::new(EventQueue::new(100_000, Overflow::Wait));
    let mut worker = Worker::start(
        vec![session(&first, false)],
        Arc::clone(&queue),
        Arc::new(MonotonicClock::new()),
    )
    .unwrap();
    let next_set = |deadline: Instant| loop {
        assert!(Instant::now() < deadline, "no set");
        if let Some(arrived) = queue.pop_until(deadline) {
            if let WorkerEvent::Session(SessionEvent::Set { .. }) = arrived.event {
                return arrived.device;
            }
        }
    };
    assert_eq!(next_set(Instant::now() + Duration::from_secs(10)), 0);
    // A device still streaming cannot be replaced.
    let other = simulator(None);
    let refused = worker.reattach(0, session(&other, false)).unwrap_err();
    assert!(refused.to_string().contains("has not ended"), "{refused}");
    other.stop();
    let second = simulator(None);
    // Unplugged: its stream ends, as a disconnection.
    first.stop();
    let deadline = Instant::now() + Duration::from_secs(10);
    let reason = loop {
        assert!(Instant::now() < deadline, "no end");
        if let Some(arrived) = queue.pop_until(deadline) {
            if let WorkerEvent::Ended(end) = arrived.event {
                assert_eq!(arrived.device, 0);
                break end.reason;
            }
        }
    };
    assert!(matches!(reason, EndReason::Disconnected(_)), "{reason:?}");
    // Back (here another board): its sets come as device 0 again, and requests reach it.
    let mut back = Some(session(&second, false));
    let deadline = Instant::now() + Duration::from_secs(5);
    while let Some(session) = back.take() {
        if let Err(error) = worker.reattach(0, session) {
            // The end was taken a moment before the thread marked it: open again.
            assert!(Instant::now() < deadline, "{error}");
            std::thread::sleep(Duration::from_millis(100));
            back = Some(self::session(&second, false));
        }
    }
    assert_eq!(next_set(Instant::now() + Duration::from_secs(10)), 0);
    let reply = worker
        .request(0, Command::ReadCounters, Duration::from_secs(5))
        .unwrap();
    assert!(matches!(reply, ReplyPayload::Counters(_)), "{reply:?}");
    drop(worker);
    second.stop();
}
