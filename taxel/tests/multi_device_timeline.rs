//! Two simulated boards on one host timeline through the one stamping policy
//! (`stamping::Stamper`, what the recorder, the live view and the bridge stamp with): the same
//! device code on each board, their crystals off by +100 and -100 ppm and their clocks started
//! at different times, frames decoded by the host's decoder and arriving after a jittery USB
//! latency. Each board's frames go through a stamper of its own exactly as the recorder feeds
//! it (every frame observed, pushed and released at its arrival), and every stamp is compared
//! with the true sampling instant (the simulations' own time, which the stamper never sees).

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sim_device::{ClockError, MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use taxel_host::stamping::{Stamped, Stamper};
use wire::{DeviceFrame, DeviceFrameDecoder};

/// What the test knows of a frame and the stamper does not: its true sampling instant.
#[derive(Debug, Clone, Copy)]
struct Truth {
    sequence: u32,
    true_us: u64,
}

/// One board: its device, link, decoder, stamper, and where it started on the host clock.
struct Board {
    device: SimulatedDevice,
    link: MemoryPort,
    decoder: DeviceFrameDecoder,
    stamper: Stamper<Truth>,
    host_start_us: u64,
    clock_error: ClockError,
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
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1).with_seed(seed),
        clock_error,
    )
    .unwrap();
    Board {
        device,
        link: MemoryPort::new(usize::MAX),
        decoder: DeviceFrameDecoder::new(),
        stamper: Stamper::default(),
        host_start_us,
        clock_error,
    }
}

#[test]
fn two_boards_at_plus_and_minus_100_ppm_are_stamped_within_a_millisecond_of_the_truth() {
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
    let mut stamped: [Vec<Stamped<Truth>>; 2] = [Vec::new(), Vec::new()];
    let mut frames = [0usize; 2];
    for (index, board) in boards.iter_mut().enumerate() {
        let mut last_arrival_us = 0;
        while board.device.simulation().now_us() < 20_000_000 {
            board.device.step(&mut board.link);
            // The frame was stamped at the end of the cycle: the simulation's time now.
            let true_us = board.host_start_us + board.device.simulation().now_us();
            for frame in board.decoder.feed(&board.link.take_for_host(usize::MAX)) {
                if let Ok(DeviceFrame::Sample(sample)) = frame {
                    // Frames keep their order on the link.
                    let arrival_us = (true_us + latency.next_us()).max(last_arrival_us);
                    last_arrival_us = arrival_us;
                    // As the recorder does: observe, push, release at the arrival.
                    board.stamper.observe(sample.timestamp_us, arrival_us);
                    board.stamper.push(
                        Truth {
                            sequence: sample.sequence,
                            true_us,
                        },
                        sample.timestamp_us,
                        arrival_us,
                    );
                    stamped[index].extend(board.stamper.release(arrival_us));
                    frames[index] += 1;
                }
            }
        }
        stamped[index].extend(board.stamper.finish());
    }

    let mut worst_us = [0i64; 2];
    for (index, (board, stamped)) in boards.iter().zip(&stamped).enumerate() {
        // Nothing dropped, the order kept, every item stamped with the mapping.
        assert_eq!(stamped.len(), frames[index], "board {index}");
        assert!(stamped.len() > 1_800, "board {index}: {}", stamped.len());
        assert!(
            stamped
                .windows(2)
                .all(|pair| pair[1].item.sequence == pair[0].item.sequence + 1),
            "board {index}: order"
        );
        assert_eq!(board.stamper.stamped_at_arrival(), 0, "board {index}");
        let estimate = board.stamper.estimate().unwrap();
        let drift_error_ppm = estimate.drift_ppm - board.clock_error.rate_ppm;
        assert!(drift_error_ppm.abs() < 5.0, "drift {}", estimate.drift_ppm);
        assert!(
            estimate.uncertainty_us < 1_000,
            "uncertainty {} us",
            estimate.uncertainty_us
        );
        let mut covered = 0usize;
        for item in stamped {
            assert!(item.host_us <= item.arrival_us, "stamped after its arrival");
            let error_bound_us = item.error_us.unwrap();
            let error_us = item.host_us as i64 - item.item.true_us as i64;
            if error_us.unsigned_abs() <= error_bound_us {
                covered += 1;
            }
            worst_us[index] = worst_us[index].max(error_us.abs());
            // Every item, from the first: an item waits for its board's first estimate.
            assert!(
                error_us.abs() <= 1_000,
                "board {index}: stamped {} us, true {} us",
                item.host_us,
                item.item.true_us
            );
            // Never fresher than it is.
            assert!(error_us <= 0, "stamped {error_us} us after the truth");
        }
        eprintln!(
            "board {index}: {} items, worst |stamp - true| {} us, error bound covers {covered}; \
             drift {:+.2} ppm, uncertainty {} us",
            stamped.len(),
            worst_us[index],
            estimate.drift_ppm,
            estimate.uncertainty_us
        );
        // The error bound is a bound: it covers every item.
        assert_eq!(covered, stamped.len(), "board {index}");
    }

    // On one timeline (every item by its stamp, ties by board), samples more than 2 ms apart in
    // truth keep their true order.
    let mut merged: Vec<(u64, usize, u64)> = stamped
        .iter()
        .enumerate()
        .flat_map(|(index, items)| {
            items
                .iter()
                .map(move |item| (item.host_us, index, item.item.true_us))
        })
        .collect();
    merged.sort_by_key(|&(host_us, index, _)| (host_us, index));
    for pair in merged.windows(2) {
        let (earlier, later) = (pair[0].2, pair[1].2);
        assert!(earlier <= later + 2_000, "{earlier} then {later}");
    }
}
