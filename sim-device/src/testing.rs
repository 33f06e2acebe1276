//! Test support (feature `testing`): a host on a simulated device's memory port, driven through
//! the real encoder and decoder, for the tests of this crate and of the crates above it.
//!
//! These helpers panic when the device does not do what a test needs (no reply, a device that
//! does not start): in a test, that is the test failing, with the reason.
#![allow(
    clippy::unwrap_used,
    clippy::panic,
    reason = "test support: a failure is the test failing"
)]

use crate::{MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{
    Command, DeviceEvent, DeviceFrame, DeviceFrameDecoder, ErrorCode, EventFrame, InfoFrame,
    ReplyPayload, Request, SampleFrame,
};

/// A host on the simulated device's port: requests through the real encoder, every frame
/// through the real decoder, the sample frames kept.
pub struct Host {
    /// The simulated device.
    pub device: SimulatedDevice,
    /// Its port.
    pub link: MemoryPort,
    /// The host's decoder of what the device sends.
    pub decoder: DeviceFrameDecoder,
    /// Request id of the next request.
    pub next_request_id: u16,
    /// Every sample frame decoded so far.
    pub samples: Vec<SampleFrame>,
}

impl Default for Host {
    fn default() -> Self {
        Self::new()
    }
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
    ///
    /// # Panics
    /// If the simulated device does not start.
    pub fn with_scene(scene: SceneFile, pads: usize) -> Self {
        let mut host = Self::with_config(SimulatedDeviceConfig::new(scene, pads).with_seed(9));
        host.steps(20);
        host
    }

    /// A device of `config`, not stepped yet.
    ///
    /// # Panics
    /// If the simulated device does not start.
    pub fn with_config(config: SimulatedDeviceConfig) -> Self {
        Self::on(SimulatedDevice::new(config).unwrap())
    }

    /// A host on `device`, not stepped yet.
    pub fn on(device: SimulatedDevice) -> Self {
        Self {
            device,
            link: MemoryPort::new(usize::MAX),
            decoder: DeviceFrameDecoder::new(),
            next_request_id: 1,
            samples: Vec::new(),
        }
    }

    /// Steps until the simulation's clock reaches `until_s` and returns every frame decoded.
    ///
    /// # Panics
    /// If a frame does not decode.
    pub fn run_until_s(&mut self, until_s: f64) -> Vec<DeviceFrame> {
        let mut frames = Vec::new();
        while self.device.simulation().now_us() < (until_s * 1e6) as u64 {
            frames.extend(self.steps(1));
        }
        frames
    }

    /// Runs `count` converter cycles and decodes what came out.
    ///
    /// # Panics
    /// If a frame does not decode.
    pub fn steps(&mut self, count: usize) -> Vec<DeviceFrame> {
        let mut frames = Vec::new();
        for _ in 0..count {
            self.device.step(&mut self.link);
            let bytes = self.link.take_for_host(usize::MAX);
            for frame in self.decoder.feed(&bytes) {
                let frame = frame.unwrap();
                if let DeviceFrame::Sample(sample) = &frame {
                    self.samples.push(*sample);
                }
                frames.push(frame);
            }
        }
        frames
    }

    /// Queues `bytes` for the device, as the host's serial port would.
    pub fn send_bytes(&mut self, bytes: &[u8]) {
        self.link.to_device.extend(bytes);
    }

    /// Sends a command and waits up to 400 cycles for its reply.
    ///
    /// # Panics
    /// If no reply comes.
    pub fn request(&mut self, command: Command) -> Result<ReplyPayload, ErrorCode> {
        self.request_with_events(command).0
    }

    /// Sends a command and steps up to 400 cycles (a tare of 64 sets and its wait) until its
    /// reply: the reply and every event the device sent meanwhile.
    ///
    /// # Panics
    /// If no reply comes.
    pub fn request_with_events(
        &mut self,
        command: Command,
    ) -> (Result<ReplyPayload, ErrorCode>, Vec<DeviceEvent>) {
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
        let mut events = Vec::new();
        for _ in 0..400 {
            for frame in self.steps(1) {
                match frame {
                    DeviceFrame::Event(EventFrame { event, .. }) => events.push(event),
                    DeviceFrame::Reply(reply) if reply.request_id == request_id => {
                        return (reply.result, events);
                    }
                    _ => {}
                }
            }
        }
        panic!("no reply to request {request_id}");
    }

    /// Steps up to 200 cycles until the reply to `request_id` arrives.
    ///
    /// # Panics
    /// If no reply comes.
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
    ///
    /// # Panics
    /// If no reply comes or the request id needs more than one byte.
    pub fn request_with_varint(
        &mut self,
        command: u8,
        argument: u16,
    ) -> Result<ReplyPayload, ErrorCode> {
        let request_id = self.next_request_id;
        self.next_request_id += 1;
        let mut payload = std::vec![
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

    /// The device's Info frame.
    ///
    /// # Panics
    /// If the device refuses or does not answer.
    pub fn info(&mut self) -> InfoFrame {
        match self.request(Command::Info) {
            Ok(ReplyPayload::Info(info)) => info,
            other => panic!("{other:?}"),
        }
    }
}
