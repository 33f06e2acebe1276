//! The host side of the command tests: a simulated device on a memory port, driven through
//! the real encoder and decoder.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic, dead_code)]

use sim_device::{MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{
    Command, DeviceFrame, DeviceFrameDecoder, ErrorCode, InfoFrame, ReplyPayload, Request,
    SampleFrame,
};

/// A host on the simulated device's port: requests through the real encoder, every frame
/// through the real decoder, the sample frames kept.
pub struct Host {
    pub device: SimulatedDevice,
    pub link: MemoryPort,
    pub decoder: DeviceFrameDecoder,
    pub next_request_id: u16,
    pub samples: Vec<SampleFrame>,
}

impl Host {
    /// The default scene on one pad, after 20 sample sets.
    pub fn new() -> Self {
        Self::with_pads(1)
    }

    /// The default scene on `pads` pads, after 20 sample sets.
    pub fn with_pads(pads: usize) -> Self {
        Self::with_scene(SceneFile::default_scene().unwrap(), pads)
    }

    /// `scene` on `pads` pads, after 20 sample sets.
    pub fn with_scene(scene: SceneFile, pads: usize) -> Self {
        let device = SimulatedDevice::new(SimulatedDeviceConfig {
            scene,
            seed: 9,
            speed: None,
            topology: sim_device::pads_topology(pads),
            bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
        })
        .unwrap();
        let mut host = Self {
            device,
            link: MemoryPort::new(usize::MAX),
            decoder: DeviceFrameDecoder::new(),
            next_request_id: 1,
            samples: Vec::new(),
        };
        host.steps(20);
        host
    }

    /// Runs `count` converter cycles and decodes what came out.
    pub fn steps(&mut self, count: usize) -> Vec<DeviceFrame> {
        let mut frames = Vec::new();
        for _ in 0..count {
            self.device.step(&mut self.link);
            let bytes = self.link.take_for_host(usize::MAX);
            for frame in self.decoder.feed(&bytes).flatten() {
                if let DeviceFrame::Sample(sample) = &frame {
                    self.samples.push(*sample);
                }
                frames.push(frame);
            }
        }
        frames
    }

    pub fn send_bytes(&mut self, bytes: &[u8]) {
        self.link.to_device.extend(bytes);
    }

    /// Sends a command and waits up to 200 cycles for its reply.
    pub fn request(&mut self, command: Command) -> Result<ReplyPayload, ErrorCode> {
        let request_id = self.next_request_id;
        self.next_request_id += 1;
        let mut encoded = [0u8; 256];
        let length = wire::encode_frame(
            &Request {
                request_id,
                command,
            },
            &mut encoded,
        )
        .unwrap();
        self.send_bytes(&encoded[..length]);
        self.reply_to(request_id)
    }

    /// Steps up to 200 cycles until the reply to `request_id` arrives.
    pub fn reply_to(&mut self, request_id: u16) -> Result<ReplyPayload, ErrorCode> {
        for _ in 0..200 {
            for frame in self.steps(1) {
                if let DeviceFrame::Reply(reply) = frame {
                    if reply.request_id == request_id {
                        return reply.result;
                    }
                }
            }
        }
        panic!("no reply to request {request_id}");
    }

    /// Sends command `command` with one varint argument, as a client of another implementation
    /// could (any value, not only the ones the typed commands can hold), and waits for the reply.
    pub fn request_with_varint(
        &mut self,
        command: u8,
        argument: u16,
    ) -> Result<ReplyPayload, ErrorCode> {
        let request_id = self.next_request_id;
        self.next_request_id += 1;
        let mut payload = vec![
            wire::PROTOCOL_VERSION,
            wire::kind::REQUEST,
            request_id as u8,
        ];
        assert!(request_id < 0x80);
        payload.push(command);
        let mut value = argument;
        while value >= 0x80 {
            payload.push((value as u8) | 0x80);
            value >>= 7;
        }
        payload.push(value as u8);
        payload.extend(wire::crc16(&payload).to_le_bytes());
        // COBS, as PROTOCOL.md section 2.1 describes it.
        let mut frame = Vec::new();
        for run in payload.split(|&byte| byte == 0) {
            frame.push(run.len() as u8 + 1);
            frame.extend(run);
        }
        frame.push(0);
        self.send_bytes(&frame);
        self.reply_to(request_id)
    }

    pub fn info(&mut self) -> InfoFrame {
        match self.request(Command::Info) {
            Ok(ReplyPayload::Info(info)) => info,
            other => panic!("{other:?}"),
        }
    }
}
