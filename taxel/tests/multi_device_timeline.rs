//! Two simulated boards on one host timeline: the same device code on each, their crystals off
//! by +100 and -100 ppm and their clocks started at different times, frames decoded by the host's
//! decoder and arriving after a jittery USB latency; each board's clock is mapped to the host
//! clock by `clock_sync`, and the merged times are compared with the true instants (the
//! simulations' own time, which the mapping never sees).

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sim_device::{ClockError, MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use taxel_host::clock_sync::{merge_by_host_time, ClockMapper};
use wire::{DeviceFrame, DeviceFrameDecoder};

/// One board: its device, link, decoder, mapper, and where it started on the host clock.
struct Board {
    device: SimulatedDevice,
    link: MemoryPort,
    decoder: DeviceFrameDecoder,
    mapper: ClockMapper,
    host_start_us: u64,
}

/// A small xorshift for the latency (the test's own, seeded).
struct Latency(u64);

impl Latency {
    fn next_us(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        // 0.1 to 1 ms, and 2 % of the frames 5 to 30 ms late (a busy host).
        let jitter_us = 100 + self.0 % 900;
        if self.0.is_multiple_of(50) {
            jitter_us + 5_000 + (self.0 >> 8) % 25_000
        } else {
            jitter_us
        }
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
        link: MemoryPort::new(usize::MAX),
        decoder: DeviceFrameDecoder::new(),
        mapper: ClockMapper::new(),
        host_start_us,
    }
}

#[test]
fn two_boards_at_plus_and_minus_100_ppm_merge_within_a_millisecond_after_10_s() {
    let mut boards = [
        board(
            1,
            ClockError {
                rate_ppm: 100.0,
                offset_us: 3_200_000,
            },
            0,
        ),
        board(
            2,
            ClockError {
                rate_ppm: -100.0,
                offset_us: 0,
            },
            1_700_000,
        ),
    ];
    let mut latency = Latency(0x9E37_79B9_7F4A_7C15);
    // Per board: (device time, true host instant) of every sample frame, and its arrival.
    let mut frames: [Vec<(u64, u64)>; 2] = [Vec::new(), Vec::new()];
    let mut last_arrival_us = [0u64; 2];
    for (index, board) in boards.iter_mut().enumerate() {
        while board.device.simulation().now_us() < 20_000_000 {
            board.device.step(&mut board.link);
            // The frame was stamped at the end of the cycle: the simulation's time now.
            let true_us = board.host_start_us + board.device.simulation().now_us();
            for frame in board.decoder.feed(&board.link.take_for_host(usize::MAX)) {
                if let Ok(DeviceFrame::Sample(sample)) = frame {
                    // Frames keep their order on the link.
                    let arrival_us = (true_us + latency.next_us()).max(last_arrival_us[index]);
                    last_arrival_us[index] = arrival_us;
                    board.mapper.observe(sample.timestamp_us, arrival_us);
                    frames[index].push((sample.timestamp_us, true_us));
                }
            }
        }
    }
    // Each board's frames from its 10th second on, mapped with the estimate at the end.
    let mut worst_us = 0i64;
    let mut mapped: Vec<Vec<(u64, u64)>> = Vec::new();
    for (board, frames) in boards.iter().zip(&frames) {
        let estimate = board.mapper.estimate().unwrap();
        assert!(
            estimate.uncertainty_us < 1_000,
            "uncertainty {} us",
            estimate.uncertainty_us
        );
        let mut board_mapped = Vec::new();
        for &(device_us, true_us) in frames {
            if true_us < board.host_start_us + 10_000_000 {
                continue;
            }
            let host_us = estimate.to_host_us(device_us);
            let error_us = host_us as i64 - true_us as i64;
            assert!(
                error_us.abs() <= 1_000,
                "mapped {host_us} us, true {true_us} us"
            );
            // Never fresher than it is.
            assert!(error_us <= 0, "mapped {error_us} us after the truth");
            worst_us = worst_us.max(error_us.abs());
            board_mapped.push((host_us, true_us));
        }
        assert!(board_mapped.len() > 900, "{}", board_mapped.len());
        mapped.push(board_mapped);
    }
    eprintln!("worst merged-time error: {worst_us} us");
    // On the merged timeline, samples more than 2 ms apart in truth keep their true order.
    let merged = merge_by_host_time(mapped);
    for pair in merged.windows(2) {
        // `sample` is the true instant.
        let (earlier, later) = (pair[0].sample, pair[1].sample);
        assert!(earlier <= later + 2_000, "{earlier} then {later}");
    }
}
