//! Arbitrary bytes through every reader of the host tool and the plot path: `convert` (a
//! recording of the schema and a raw log, with the wide export), the reference-load reader of
//! `calibrate`, and `plot` drawing what it read. Never a panic, and never a hang: CI runs this
//! with a per-input time limit (libFuzzer's -timeout).
#![no_main]

use libfuzzer_sys::fuzz_target;
use taxel_host::convert::{
    convert_raw, convert_recording, ConversionEngine, ConvertSettings, RecordedStates, WideWriter,
};
use taxel_host::schema::RowWriter;

fn engine() -> ConversionEngine {
    ConversionEngine::new(ConvertSettings::default(), RecordedStates::default())
}

fuzz_target!(|bytes: &[u8]| {
    if let Ok(mut rows) = RowWriter::new(std::io::sink()) {
        let _ = convert_recording(bytes, &mut rows, engine());
    }
    if let Ok(mut wide) = WideWriter::new(std::io::sink(), 2) {
        let _ = convert_recording(bytes, &mut wide, engine());
        let _ = convert_raw(bytes, 0, 2, &mut wide, engine());
    }
    let _ = taxel_host::calibrate::read_loads(bytes);
    if let Ok(series) = taxel::plot::read_pressure_series(bytes) {
        assert!(series
            .pads
            .iter()
            .all(|pad| pad.time_s.iter().all(|time_s| time_s.is_finite())));
        let _ = taxel::plot::pressures_svg(&series, (320, 200));
    }
});
