//! The conversion engine's block path (`ConversionEngine::convert_rows`, which runs each pad's
//! rows through its pipeline's batch path) against converting the same rows one at a time:
//! the same outputs bit for bit and the same tare warnings, over several devices and pads,
//! missing frames, recorded baselines that change mid-block, temperature-sensor changes, a
//! recording that starts in contact, and blocks of any size.
#![allow(clippy::panic)]

use model_core::{BaselineRecord, SplitCapacitance, TaxelFlags, TAXEL_COUNT};
use proptest::prelude::*;
use taxel_host::convert::{ConversionEngine, ConvertSettings, RecordedStates};
use taxel_host::device_state::{BaselineChange, RecordedDeviceState, RecordedPadState};
use taxel_host::schema::{PadReading, PadRow};
use wire::testing::{info_frame, pad_info_frame};
use wire::TemperatureSource;

const PADS: u8 = 2;

/// Sets at the start whose readings do not move.
const STILL_SETS: usize = 6;

/// Device 0's recorded state: both pads with baselines that change at sequence numbers
/// (`changes`), so a block can straddle a change.
fn recorded_states(changes: &[u32], directory: &std::path::Path) -> RecordedStates {
    let mut state = RecordedDeviceState::new(&info_frame(PADS));
    for pad in 0..PADS {
        let mut pad_state = match RecordedPadState::new(
            &pad_info_frame(pad),
            &model_core::Calibration::default(),
        ) {
            Ok(pad_state) => pad_state,
            Err(error) => panic!("pad state: {error}"),
        };
        pad_state.baselines = changes
            .iter()
            .enumerate()
            .map(|(index, from_sequence)| BaselineChange {
                from_sequence: *from_sequence,
                taxels: [Some(BaselineRecord {
                    capacitance: SplitCapacitance {
                        offset_pf: 4.0,
                        fine_pf: 0.5 + 0.01 * index as f32,
                    },
                    temperature_c: 25.0,
                    tracked_drift_pf: 0.0,
                }); TAXEL_COUNT],
            })
            .collect();
        state.add_pad(pad_state);
    }
    let path = directory.join("recording.dev0.device.json");
    if let Err(error) = state.write(&path) {
        panic!("writing the state: {error}");
    }
    match RecordedStates::of_one_device(0, &path) {
        Ok(states) => states,
        Err(error) => panic!("reading the state: {error}"),
    }
}

/// One generated pad reading: capacitances (some empty), a temperature and its sensor, the
/// recorded contact bit, acquisition flags; `None`: the pad's frame is missing from the set.
type Reading = Option<([Option<f32>; TAXEL_COUNT], Option<f32>, u8, bool, u16)>;

fn reading() -> impl Strategy<Value = Reading> {
    let capacitance = prop_oneof![
        8 => (4.45f32..5.3).prop_map(Some),
        1 => Just(None),
    ];
    prop::option::weighted(
        0.95,
        (
            prop::array::uniform4(capacitance),
            prop::option::weighted(0.9, 24.9f32..25.1),
            0u8..3,
            any::<bool>(),
            prop_oneof![30 => Just(0u16), 1 => any::<u16>()],
        ),
    )
}

/// Rows of two devices (device 1 has no recorded state: a tare on its first rows) and two pads,
/// set by set.
fn rows(readings: &[Reading]) -> Vec<PadRow> {
    let sources = [
        TemperatureSource::Tmp117,
        TemperatureSource::McuInternal,
        TemperatureSource::None,
    ];
    let keys = [(0u32, 0u8), (0, 1), (1, 0), (1, 1)];
    readings
        .chunks(keys.len())
        .enumerate()
        .flat_map(|(set, readings)| {
            readings
                .iter()
                .zip(keys)
                .map(move |(reading, (device, pad))| {
                    let reading =
                        reading.map(|(capacitances, temperature, source, contact, flags)| {
                            // The first sets are still and clean, so tares on rows succeed and the
                            // pressures that follow are numbers.
                            let (capacitances, temperature, flags) = if set < STILL_SETS {
                                ([Some(4.5); TAXEL_COUNT], Some(25.0), 0)
                            } else {
                                (capacitances, temperature, flags)
                            };
                            PadReading {
                                device_time_us: set as u64 * 10_000,
                                temperature_c: temperature,
                                temperature_source: sources[usize::from(source) % sources.len()],
                                capacitance_pf: capacitances,
                                pressure_kpa: [None; TAXEL_COUNT],
                                flags: [TaxelFlags::from_bits_truncate(flags); TAXEL_COUNT],
                                force_n: None,
                                centre_of_pressure_mm: None,
                                partial: false,
                                contact,
                            }
                        });
                    PadRow {
                        host_time_us: set as u64 * 10_000,
                        device,
                        pad,
                        sequence: set as u32,
                        sync_error_us: None,
                        reading,
                        marker: String::new(),
                    }
                })
        })
        .collect()
}

/// Converts `rows` in blocks of `block_sizes` (in turn) and one at a time, and checks both give
/// the same rows and warnings.
fn blocks_match_one_at_a_time(
    rows: &[PadRow],
    changes: &[u32],
    block_sizes: &[usize],
    timed: bool,
    tare_rows: u16,
) -> Result<(), TestCaseError> {
    let directory = tempfile::tempdir().map_err(|error| TestCaseError::fail(error.to_string()))?;
    let states = recorded_states(changes, directory.path());
    // Device 0 follows its recorded baselines and device 1, without a state, tares on its
    // first row; or every pad tares on its first `tare_rows` rows.
    let settings = ConvertSettings {
        tare_rows: (tare_rows > 1).then_some(tare_rows),
        ..ConvertSettings::default()
    };
    let mut one_by_one = ConversionEngine::new(settings.clone(), states.clone());
    let mut want = rows.to_vec();
    for row in &mut want {
        if timed {
            one_by_one
                .convert(row)
                .map_err(|error| TestCaseError::fail(error.to_string()))?;
        } else {
            one_by_one
                .convert_untimed(row)
                .map_err(|error| TestCaseError::fail(error.to_string()))?;
        }
    }
    let mut blocks = ConversionEngine::new(settings, states);
    let mut got = rows.to_vec();
    let mut start = 0;
    for size in block_sizes.iter().cycle() {
        if start >= got.len() {
            break;
        }
        let end = (start + size).min(got.len());
        blocks
            .convert_rows(&mut got[start..end], timed)
            .map_err(|error| TestCaseError::fail(error.to_string()))?;
        start = end;
    }
    for (index, (got, want)) in got.iter().zip(&want).enumerate() {
        // Debug prints every float exactly, so equal text is equal bits.
        prop_assert_eq!(format!("{got:?}"), format!("{want:?}"), "row {}", index);
    }
    prop_assert_eq!(blocks.finish(), one_by_one.finish());
    Ok(())
}

/// With `pressures_only`, the rows get the pressures and flags of the whole pipeline and no
/// force, centre of pressure, partial or contact.
fn pressures_only_matches_the_pipeline(
    rows: &[PadRow],
    changes: &[u32],
    timed: bool,
) -> Result<(), TestCaseError> {
    let directory = tempfile::tempdir().map_err(|error| TestCaseError::fail(error.to_string()))?;
    let states = recorded_states(changes, directory.path());
    let mut converted = Vec::new();
    for pressures_only in [false, true] {
        let settings = ConvertSettings {
            pressures_only,
            ..ConvertSettings::default()
        };
        let mut engine = ConversionEngine::new(settings, states.clone());
        let mut got = rows.to_vec();
        engine
            .convert_rows(&mut got, timed)
            .map_err(|error| TestCaseError::fail(error.to_string()))?;
        converted.push((got, engine.finish()));
    }
    let [(whole, whole_warnings), (pressures, pressures_warnings)] = &converted[..] else {
        return Err(TestCaseError::fail("two conversions"));
    };
    prop_assert_eq!(whole_warnings, pressures_warnings);
    let mut forces = 0;
    for (index, (whole, pressures)) in whole.iter().zip(pressures).enumerate() {
        let (Some(whole), Some(pressures)) = (&whole.reading, &pressures.reading) else {
            prop_assert_eq!(whole.reading.is_some(), pressures.reading.is_some());
            continue;
        };
        forces += usize::from(whole.force_n.is_some());
        prop_assert_eq!(
            format!("{:?}", (whole.pressure_kpa, whole.flags)),
            format!("{:?}", (pressures.pressure_kpa, pressures.flags)),
            "row {}",
            index
        );
        prop_assert_eq!(
            (
                pressures.force_n,
                pressures.centre_of_pressure_mm,
                pressures.partial,
                pressures.contact
            ),
            (None, None, false, false),
            "row {}",
            index
        );
    }
    prop_assert!(
        forces > 0,
        "the whole pipeline gave no force to compare with"
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn pressures_only_gives_the_pipelines_pressures_and_nothing_else(
        readings in prop::collection::vec(reading(), 4..600),
        changes in prop::collection::btree_set(0u32..300, 1..4),
        timed in any::<bool>(),
    ) {
        let changes: Vec<u32> = changes.into_iter().collect();
        pressures_only_matches_the_pipeline(&rows(&readings), &changes, timed)?;
    }

    #[test]
    fn blocks_convert_as_rows_one_at_a_time(
        readings in prop::collection::vec(reading(), 4..1200),
        changes in prop::collection::btree_set(0u32..300, 1..4),
        block_sizes in prop::collection::vec(1usize..600, 1..8),
        timed in any::<bool>(),
        tare_rows in 1u16..=STILL_SETS as u16,
    ) {
        let changes: Vec<u32> = changes.into_iter().collect();
        blocks_match_one_at_a_time(&rows(&readings), &changes, &block_sizes, timed, tare_rows)?;
    }

    /// One pad's rows alone (as Python converts one pad), blocks with and without a missing
    /// frame: the same rows as one at a time.
    #[test]
    fn one_pad_blocks_convert_as_rows_one_at_a_time(
        readings in prop::collection::vec(reading(), 4..1200),
        changes in prop::collection::btree_set(0u32..300, 1..4),
        block_sizes in prop::collection::vec(1usize..150, 1..8),
        timed in any::<bool>(),
        tare_rows in 1u16..=STILL_SETS as u16,
        device in 0u32..2,
    ) {
        let changes: Vec<u32> = changes.into_iter().collect();
        let rows: Vec<PadRow> = rows(&readings)
            .into_iter()
            .filter(|row| (row.device, row.pad) == (device, 0))
            .collect();
        blocks_match_one_at_a_time(&rows, &changes, &block_sizes, timed, tare_rows)?;
    }
}
