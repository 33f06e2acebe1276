//! Shared test helpers: frame builders, an in-memory device, a seeded noise source and
//! `taxel sim` processes.
#![allow(dead_code, clippy::unwrap_used, clippy::panic)]

use std::collections::VecDeque;
use std::io::{self, Read, Write};

use wire::{
    encode_frame_to_vec, DeviceFrame, ReplyFrame, ReplyPayload, Request, RequestDecoder,
    SampleFrame, TaxelSample,
};

/// The path of the built `taxel` binary.
pub fn taxel_binary() -> &'static str {
    env!("CARGO_BIN_EXE_taxel")
}

/// A `taxel sim` process serving a simulated device on a pseudo-terminal; killed when dropped.
pub struct SimulatorProcess {
    child: std::process::Child,
    /// The terminal to open.
    pub port: String,
}

impl SimulatorProcess {
    /// Starts `taxel sim --duration 60 <arguments>` with its port written to `name` in
    /// `directory`; returns once the port is ready (panics after 30 s).
    // The child is waited for when the returned value is stopped or dropped.
    #[allow(clippy::zombie_processes)]
    pub fn start(directory: &std::path::Path, name: &str, arguments: &[&str]) -> Self {
        use std::time::{Duration, Instant};
        let path_file = directory.join(name);
        let mut child = std::process::Command::new(taxel_binary())
            .args(["sim", "--duration", "60"])
            .args(arguments)
            .arg("--path-file")
            .arg(&path_file)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            if let Ok(path) = std::fs::read_to_string(&path_file) {
                if !path.trim().is_empty() {
                    return Self {
                        child,
                        port: path.trim().to_owned(),
                    };
                }
            }
            if Instant::now() >= deadline {
                let _ = child.kill();
                let _ = child.wait();
                panic!("the simulator did not start");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Stops it now.
    pub fn stop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for SimulatorProcess {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A sample frame with four taxels.
pub fn sample(
    sequence: u32,
    timestamp_us: u64,
    taxels: [(Option<f32>, f32, u16); 4],
) -> SampleFrame {
    SampleFrame {
        sequence,
        timestamp_us,
        temperature_c: Some(23.5),
        taxels: taxels.map(|(pressure_kpa, capacitance_pf, flags)| TaxelSample {
            pressure_kpa,
            capacitance_pf,
            flags,
        }),
        summary: wire::PadSummary::default(),
        ..wire::testing::sample_frame(0)
    }
}

/// The encoded bytes of a device frame, delimiter included.
pub fn encoded(frame: &DeviceFrame) -> Vec<u8> {
    encode_frame_to_vec(frame).unwrap()
}

/// A reader that hands out its bytes in chunks of the given sizes (cycled), then ends.
pub struct ChunkedReader {
    bytes: VecDeque<u8>,
    chunk_sizes: Vec<usize>,
    next_chunk: usize,
}

impl ChunkedReader {
    pub fn new(bytes: Vec<u8>, chunk_sizes: Vec<usize>) -> Self {
        Self {
            bytes: bytes.into(),
            chunk_sizes,
            next_chunk: 0,
        }
    }
}

impl Read for ChunkedReader {
    fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
        let size = self.chunk_sizes[self.next_chunk % self.chunk_sizes.len()]
            .min(buffer.len())
            .min(self.bytes.len());
        self.next_chunk += 1;
        for slot in buffer.iter_mut().take(size) {
            *slot = self.bytes.pop_front().unwrap();
        }
        Ok(size)
    }
}

impl Write for ChunkedReader {
    fn write(&mut self, buffer: &[u8]) -> io::Result<usize> {
        Ok(buffer.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// What the fake device does with a request: frames to send back (in order).
pub type Responder = Box<dyn FnMut(&Request) -> Vec<DeviceFrame>>;

/// An in-memory device: requests written to it are decoded and answered by a responder; reads
/// return its output and time out (like a serial port) when there is none.
pub struct FakeDevice {
    pub to_host: VecDeque<u8>,
    pub requests: Vec<Request>,
    decoder: RequestDecoder,
    responder: Responder,
}

impl FakeDevice {
    pub fn new(responder: Responder) -> Self {
        Self {
            to_host: VecDeque::new(),
            requests: Vec::new(),
            decoder: RequestDecoder::new(),
            responder,
        }
    }

    /// Queues a frame for the host.
    pub fn send(&mut self, frame: &DeviceFrame) {
        self.to_host.extend(encoded(frame));
    }
}

impl Read for FakeDevice {
    fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
        if self.to_host.is_empty() {
            return Err(io::Error::new(io::ErrorKind::TimedOut, "nothing to read"));
        }
        let size = buffer.len().min(self.to_host.len());
        for slot in buffer.iter_mut().take(size) {
            *slot = self.to_host.pop_front().unwrap();
        }
        Ok(size)
    }
}

impl Write for FakeDevice {
    fn write(&mut self, buffer: &[u8]) -> io::Result<usize> {
        for &byte in buffer {
            if let Some(Ok(request)) = self.decoder.push(byte) {
                let frames = (self.responder)(&request);
                for frame in &frames {
                    self.send(frame);
                }
                self.requests.push(request);
            }
        }
        Ok(buffer.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// An Ack reply to a request.
pub fn ack(request: &Request) -> DeviceFrame {
    DeviceFrame::Reply(ReplyFrame {
        request_id: request.request_id,
        result: Ok(ReplyPayload::Ack),
    })
}

/// SplitMix64: a small seeded generator, so synthetic data is the same on every run.
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [-1, 1).
    pub fn symmetric(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// An Info frame of a device with `pad_count` pads (firmware 3.0.0, default calibration).
pub fn info(pad_count: u8) -> wire::InfoFrame {
    wire::InfoFrame {
        firmware_version: wire::FirmwareVersion {
            major: 3,
            minor: 0,
            patch: 0,
        },
        ..wire::testing::info_frame(pad_count)
    }
}
