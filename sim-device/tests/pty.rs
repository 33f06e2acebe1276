//! The simulated device on a pseudo-terminal, read by a client that opens the terminal end as a
//! serial port: the Info frame on connect, sample frames, a request answered, nothing while no
//! host is connected.

// Test helpers may unwrap: a failure is the test failing.
#![allow(clippy::unwrap_used)]

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;

use nix::fcntl::OFlag;
use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{Command, DeviceFrame, DeviceFrameDecoder, ReplyPayload, Request};

fn device() -> SimulatedDevice {
    SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1).with_seed(7),
    )
    .unwrap()
}

fn open_terminal(port: &PtyPort) -> File {
    OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags((OFlag::O_NOCTTY | OFlag::O_NONBLOCK).bits())
        .open(port.path())
        .unwrap()
}

fn read_frames(terminal: &mut File, decoder: &mut DeviceFrameDecoder) -> Vec<DeviceFrame> {
    let mut frames = Vec::new();
    let mut buffer = [0u8; 4096];
    while let Ok(length) = terminal.read(&mut buffer) {
        if length == 0 {
            break;
        }
        for result in decoder.feed(&buffer[..length]) {
            frames.push(result.unwrap());
        }
    }
    frames
}

#[test]
fn a_client_on_the_terminal_end_gets_info_samples_and_replies() {
    let mut device = device();
    let mut port = PtyPort::open().unwrap();
    // Nobody connected: the device runs and drops, counting.
    for _ in 0..20 {
        device.step(&mut port);
    }
    assert!(device.device_mut().host_counters().frames_dropped_no_host > 0);

    let mut terminal = open_terminal(&port);
    let mut decoder = DeviceFrameDecoder::new();
    let mut frames = Vec::new();
    for _ in 0..50 {
        device.step(&mut port);
        frames.extend(read_frames(&mut terminal, &mut decoder));
    }
    assert!(
        matches!(frames.first(), Some(DeviceFrame::Info(_))),
        "{:?}",
        frames.first()
    );
    let samples: Vec<_> = frames
        .iter()
        .filter_map(|frame| match frame {
            DeviceFrame::Sample(sample) => Some(sample),
            _ => None,
        })
        .collect();
    assert!(samples.len() >= 45, "{} samples", samples.len());
    for pair in samples.windows(2) {
        assert_eq!(pair[1].sequence, pair[0].sequence + 1);
    }

    let mut request = [0u8; 64];
    let length = wire::encode_frame(
        &Request {
            request_id: 41,
            command: Command::ReadCalibration {
                pad: wire::PadIndex::default(),
                taxel_index: 2,
            },
        },
        &mut request,
    )
    .unwrap();
    terminal.write_all(&request[..length]).unwrap();
    let mut reply = None;
    for _ in 0..20 {
        device.step(&mut port);
        for frame in read_frames(&mut terminal, &mut decoder) {
            if let DeviceFrame::Reply(frame) = frame {
                reply = Some(frame);
            }
        }
    }
    let reply = reply.expect("a reply");
    assert_eq!(reply.request_id, 41);
    match reply.result {
        Ok(ReplyPayload::Calibration(record)) => {
            assert_eq!(record.taxel_index, 2);
            let factory = device
                .simulation()
                .physics()
                .matching_calibration()
                .unwrap();
            let point_count = factory.taxels()[2].curve().points().len();
            assert_eq!(record.calibration.points.len(), point_count);
        }
        other => panic!("unexpected {other:?}"),
    }
}

#[test]
fn garbage_from_the_host_is_counted_and_the_stream_goes_on() {
    let mut device = device();
    let mut port = PtyPort::open().unwrap();
    let mut terminal = open_terminal(&port);
    terminal
        .write_all(&[0x13, 0x37, 0xFF, 0x00, 0x42, 0x00, b'x', b'\n', 0x00])
        .unwrap();
    let mut decoder = DeviceFrameDecoder::new();
    let mut samples = 0;
    for _ in 0..30 {
        device.step(&mut port);
        samples += read_frames(&mut terminal, &mut decoder)
            .iter()
            .filter(|frame| matches!(frame, DeviceFrame::Sample(_)))
            .count();
    }
    assert!(samples >= 25);
    assert!(device.device_mut().host_counters().host_frames_rejected >= 2);
}
