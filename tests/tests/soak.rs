//! A short soak (the CI version of `cargo run --release -p taxel-tests --bin soak`): two
//! simulated devices of 8 pads recorded to CSV and MCAP at once through the host library; no
//! set lost unflagged, every pad's sets in the file.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use taxel_tests::soak::{run_soak, SoakConfig};

#[test]
fn two_devices_of_eight_pads_lose_nothing_unflagged() {
    let directory = tempfile::tempdir().unwrap();
    let config = SoakConfig {
        devices: 2,
        pads: 8,
        device_seconds: 10.0,
        speed: 10.0,
    };
    let outcome = run_soak(config, directory.path()).unwrap();
    assert_eq!(outcome.sets_per_device, [1000, 1000]);
    assert_eq!(outcome.rows, 2 * 1000 * 8);
    assert_eq!(outcome.unflagged_losses(), 0, "{outcome:?}");
    assert!(outcome.file_bytes.0 > 0 && outcome.file_bytes.1 > 0);
}
