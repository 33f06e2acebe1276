//! Arbitrary bytes through every reader of the host tool and the plot path: `convert` (CSV and
//! raw log), the reference-load reader of `calibrate`, and `plot` drawing what it read. Never a
//! panic, and never a hang: CI runs this with a per-input time limit (libFuzzer's -timeout).
#![no_main]

use libfuzzer_sys::fuzz_target;
use taxel_host::convert::{convert_csv, convert_raw, ConvertOptions};

fuzz_target!(|bytes: &[u8]| {
    let options = ConvertOptions::default();
    let _ = convert_csv(bytes, std::io::sink(), &options);
    let _ = convert_raw(bytes, std::io::sink(), &options);
    let _ = taxel_host::calibrate::read_loads(bytes);
    if let Ok(series) = taxel::plot::read_pressure_series(bytes) {
        assert!(series.time_s.iter().all(|time_s| time_s.is_finite()));
        let _ = taxel::plot::pressures_svg(&series, (320, 200));
    }
});
