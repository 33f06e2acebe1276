//! Shared test helpers: a deterministic proptest configuration, calibration specs (distinct,
//! worst-case, and a strategy over valid ones), the test flash geometries and store shortcuts,
//! the reference of what every pad must load after a list of saves, and the on-flash format
//! re-declared from its documentation (to check the store's bytes and to place records the
//! store would not write).
// Every test file uses a different subset of these helpers.
#![allow(dead_code)]
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers: a failure is a test failure"
)]

use core::future::Future;
use core::ops::Range;

use calibration_store::{
    CalibrationStore, LoadOutcome, PadRecord, RamFlash, RamFlashError, RecordScope, MAX_PADS,
};
use embedded_storage_async::nor_flash::NorFlash;
use heapless::Vec;
use model_core::calibration::{
    CalibrationSpec, CurvePoint, FaultThresholds, PermittivityPoint, TaxelCalibrationSpec,
    MAX_CURVE_POINTS, MAX_TEMPERATURE_POINTS,
};
use model_core::reading::MAX_MEASURABLE_PF;
use model_core::{PadGeometry, PadRole, TaxelGeometry};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};

/// A fixed seed and no regression files, so every run draws the same cases.
pub fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0xCA1B_2026),
        failure_persistence: None,
        ..Config::default()
    }
}

/// Small pages: three 2 KiB pages, the store on the last two so that page 0 checks that nothing
/// is written outside the range.
pub const SMALL_PAGE: usize = 2048;
/// The flash of the small-page tests.
pub type SmallFlash = RamFlash<{ 3 * SMALL_PAGE }, SMALL_PAGE>;
/// The store's range in [`SmallFlash`].
pub const SMALL_RANGE: Range<u32> = SMALL_PAGE as u32..3 * SMALL_PAGE as u32;
/// The untouched first page of [`SmallFlash`].
pub const OUTSIDE_RANGE: Range<usize> = 0..SMALL_PAGE;

/// The STM32F411CE's flash as far as the store sees it: 512 KiB in 128 KiB pages (the 16 and
/// 64 KiB sectors at the start are never touched, so uniform pages model it).
pub type F411Flash = RamFlash<{ 512 * 1024 }, { 128 * 1024 }>;

/// Runs a future to completion.
pub fn block_on<T>(future: impl Future<Output = T>) -> T {
    embassy_futures::block_on(future)
}

/// A fresh blank small flash, boxed (tests move it around a lot).
pub fn small_flash() -> Box<SmallFlash> {
    Box::new(SmallFlash::new())
}

/// A store over the small range of `flash`.
pub fn small_store(flash: &mut SmallFlash) -> CalibrationStore<&mut SmallFlash> {
    CalibrationStore::new(flash, SMALL_RANGE).unwrap()
}

/// "Reboot": power on, a new store on the same bytes, load.
pub fn reboot_and_load(flash: &mut SmallFlash) -> LoadOutcome<RamFlashError> {
    flash.power_cycle();
    block_on(small_store(flash).load(0))
}

/// Saves through a fresh store and panics on failure.
pub fn save<F: NorFlash>(flash: F, range: Range<u32>, spec: &PadRecord)
where
    F::Error: core::fmt::Debug,
{
    let mut store = CalibrationStore::new(flash, range).unwrap();
    block_on(store.save(spec)).unwrap();
}

/// A pad's role and geometry that differ with `id`: the role, and the electrodes' area (the
/// article's centres).
pub fn layout(id: u32) -> (PadRole, PadGeometry) {
    let role = PadRole::ALL[(id % PadRole::ALL.len() as u32) as usize];
    let area_mm2 = 1.0 + (id % 997) as f32;
    let taxels = PadGeometry::ARTICLE
        .taxels()
        .map(|taxel| TaxelGeometry::new(taxel.x_mm, taxel.y_mm, area_mm2));
    (role, PadGeometry::new(taxels).unwrap())
}

/// `calibration` with `layout(id)`.
pub fn with_layout(calibration: CalibrationSpec, id: u32) -> PadRecord {
    let (role, geometry) = layout(id);
    PadRecord {
        calibration,
        role,
        geometry,
    }
}

/// A valid record that differs from every other `spec(id)`: the id, a parasitic capacitance, the
/// role and the geometry.
pub fn spec(id: u32) -> PadRecord {
    let mut spec = CalibrationSpec {
        id,
        ..CalibrationSpec::default()
    };
    spec.taxels[(id % 4) as usize].parasitic_pf = (id % 1000) as f32 * 0.01;
    with_layout(spec, id)
}

/// The longest record: a 5-byte id, 16 points and a calibrated C0 on every taxel, 8
/// temperature points, a geometry.
pub fn worst_case_spec(id: u32) -> PadRecord {
    with_layout(worst_case_calibration(id), id)
}

/// The longest calibration: a 5-byte id, 16 points and a calibrated C0 on every taxel, 8
/// temperature points.
pub fn worst_case_calibration(id: u32) -> CalibrationSpec {
    let taxel = |taxel: usize| TaxelCalibrationSpec {
        points: (0..MAX_CURVE_POINTS)
            .map(|index| {
                let step = index as f32;
                CurvePoint::new(step * 3.5, step * (0.017 + 0.001 * taxel as f32))
            })
            .collect(),
        parasitic_pf: 1.5 + taxel as f32,
        unloaded_sensor_pf: Some(4.25 + 0.125 * taxel as f32),
    };
    CalibrationSpec {
        id,
        taxels: [taxel(0), taxel(1), taxel(2), taxel(3)],
        temperature_points: (0..MAX_TEMPERATURE_POINTS)
            .map(|index| PermittivityPoint {
                temperature_c: -20.0 + 10.0 * index as f32,
                permittivity_ratio: 1.0 - 0.004 * index as f32,
            })
            .collect(),
        characterised_min_c: -20.0,
        characterised_max_c: 60.0,
        thresholds: FaultThresholds::default(),
    }
}

/// `spec(id)` for even ids and `worst_case_spec(id)` for odd ones: records of both lengths.
pub fn mixed_spec(id: u32) -> PadRecord {
    if id.is_multiple_of(2) {
        spec(id)
    } else {
        worst_case_spec(id)
    }
}

fn curve() -> impl Strategy<Value = Vec<CurvePoint, MAX_CURVE_POINTS>> {
    proptest::collection::vec((0.01f32..10.0, 0.0001f32..0.1), 1..MAX_CURVE_POINTS).prop_map(
        |steps| {
            let mut points = Vec::new();
            let mut point = CurvePoint::new(0.0, 0.0);
            points.push(point).unwrap();
            for (pressure_step_kpa, change_step) in steps {
                point.pressure_kpa += pressure_step_kpa;
                point.relative_change += change_step;
                points.push(point).unwrap();
            }
            points
        },
    )
}

/// No calibrated C0 (the default), or one anywhere in the valid range (0, MAX_MEASURABLE_PF].
fn unloaded_sensor_pf() -> impl Strategy<Value = Option<f32>> {
    prop_oneof![
        Just(None),
        (f32::MIN_POSITIVE..=MAX_MEASURABLE_PF).prop_map(Some),
        Just(Some(MAX_MEASURABLE_PF)),
    ]
}

fn taxel() -> impl Strategy<Value = TaxelCalibrationSpec> {
    (curve(), 0.0f32..=100.0, unloaded_sensor_pf()).prop_map(
        |(points, parasitic_pf, unloaded_sensor_pf)| TaxelCalibrationSpec {
            points,
            parasitic_pf,
            unloaded_sensor_pf,
        },
    )
}

/// Any calibration that validates, up to the maximum sizes.
pub fn valid_spec() -> impl Strategy<Value = CalibrationSpec> {
    let law = (
        -60.0f32..0.0,
        proptest::collection::vec((0.1f32..20.0, 0.5f32..=2.0), 1..=MAX_TEMPERATURE_POINTS),
        0.1f32..100.0,
    );
    let thresholds = (0.0f32..=50.0, 0.0f32..0.1, 0.001f32..0.9);
    (
        any::<u32>(),
        proptest::array::uniform4(taxel()),
        law,
        thresholds,
    )
        .prop_map(|(id, taxels, law, thresholds)| {
            let (first_c, steps, span_c) = law;
            let mut temperature_c = first_c;
            let temperature_points = steps
                .into_iter()
                .map(|(step_c, permittivity_ratio)| {
                    temperature_c += step_c;
                    PermittivityPoint {
                        temperature_c,
                        permittivity_ratio,
                    }
                })
                .collect();
            let (open_below_pf, dead_band_relative, shorted_margin) = thresholds;
            CalibrationSpec {
                id,
                taxels,
                temperature_points,
                characterised_min_c: first_c,
                characterised_max_c: first_c + span_c,
                thresholds: FaultThresholds {
                    open_below_pf,
                    shorted_below_relative: dead_band_relative + shorted_margin,
                    dead_band_relative,
                },
            }
        })
}

/// The outcome as the spec it carries, or a label for the other outcomes.
pub fn describe(outcome: &LoadOutcome<RamFlashError>) -> String {
    match outcome {
        LoadOutcome::Stored(record) => format!("Stored(id {})", record.calibration.id),
        LoadOutcome::Absent => "Absent".into(),
        LoadOutcome::Corrupt(reason) => format!("Corrupt({reason:?})"),
    }
}

/// The saves that completed, in order: the reference of what every pad loads (the last save
/// that covers it).
#[derive(Debug, Clone, Default)]
pub struct History(pub std::vec::Vec<(RecordScope, PadRecord)>);

impl History {
    /// What `pad` must load (a pad index of `MAX_PADS` or more: only saves for every pad).
    pub fn expected(&self, pad: u8) -> Option<&PadRecord> {
        self.0
            .iter()
            .rev()
            .find_map(|(scope, spec)| scope.covers(pad).then_some(spec))
    }

    /// The outcomes pads 0 to `MAX_PADS` (the last standing for any index beyond) must load.
    pub fn outcomes(&self) -> std::vec::Vec<LoadOutcome<RamFlashError>> {
        (0..=MAX_PADS)
            .map(|pad| match self.expected(pad) {
                Some(spec) => LoadOutcome::Stored(spec.clone()),
                None => LoadOutcome::Absent,
            })
            .collect()
    }

    /// This history with one more save.
    pub fn with(&self, scope: RecordScope, spec: &PadRecord) -> Self {
        let mut saves = self.0.clone();
        saves.push((scope, spec.clone()));
        Self(saves)
    }
}

/// A store over the two pages after the first page of `flash` (the first page checks that
/// nothing is written outside the range).
pub fn store_of<const SIZE: usize, const PAGE: usize>(
    flash: &mut RamFlash<SIZE, PAGE>,
) -> CalibrationStore<&mut RamFlash<SIZE, PAGE>> {
    CalibrationStore::new(flash, PAGE as u32..SIZE as u32).unwrap()
}

/// "Reboot" (power on, a new store on the same bytes) and load every pad, then an index past
/// the last (which only records for every pad cover).
pub fn load_every_pad<const SIZE: usize, const PAGE: usize>(
    flash: &mut RamFlash<SIZE, PAGE>,
) -> std::vec::Vec<LoadOutcome<RamFlashError>> {
    flash.power_cycle();
    (0..=MAX_PADS)
        .map(|pad| block_on(store_of(flash).load(pad)))
        .collect()
}

/// The on-flash format as its documentation gives it, for a flash of 4-byte words.
pub mod layout {
    use calibration_store::PadRecord;
    use crc::{Crc, CRC_32_ISO_HDLC};
    use model_core::PadRole;

    /// The flash word of `RamFlash` (and of the F411).
    pub const WORD: usize = 4;
    /// The page header (16 bytes), then the commit word.
    pub const COMMIT_AT: usize = 16;
    /// Where the first record of a page starts.
    pub const RECORDS_AT: usize = COMMIT_AT + WORD;
    /// A record's header, before its body.
    pub const RECORD_HEADER_LEN: usize = 16;
    /// The pads byte of a record for every pad.
    pub const EVERY_PAD: u8 = 0xFF;

    const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

    /// A page header: "TXCS", the format version, three erased bytes, the generation and the
    /// CRC-32 of the 12 bytes before it.
    pub fn page_header(format_version: u8, generation: u32) -> Vec<u8> {
        let mut header = b"TXCS".to_vec();
        header.extend_from_slice(&[format_version, 0xFF, 0xFF, 0xFF]);
        header.extend_from_slice(&generation.to_le_bytes());
        let crc = CRC.checksum(&header);
        header.extend_from_slice(&crc.to_le_bytes());
        header
    }

    /// A record padded to the word: body length, its complement, save counter, pads byte, three
    /// erased bytes, the CRC-32 of those 12 bytes and the body, the body.
    pub fn record(body: &[u8], save_counter: u32, pads: u8) -> Vec<u8> {
        let length = body.len() as u16;
        let mut record = length.to_le_bytes().to_vec();
        record.extend_from_slice(&(!length).to_le_bytes());
        record.extend_from_slice(&save_counter.to_le_bytes());
        record.extend_from_slice(&[pads, 0xFF, 0xFF, 0xFF]);
        let mut digest = CRC.digest();
        digest.update(&record);
        digest.update(body);
        record.extend_from_slice(&digest.finalize().to_le_bytes());
        record.extend_from_slice(body);
        while !record.len().is_multiple_of(WORD) {
            record.push(0xFF);
        }
        record
    }

    /// A body, written out by hand: the body format version (2), the postcard calibration, the
    /// role's index and each taxel's x, y and area as f32 little-endian.
    pub fn body(record: &PadRecord) -> Vec<u8> {
        let mut buffer = [0u8; 1024];
        let mut body = vec![2];
        body.extend_from_slice(postcard::to_slice(&record.calibration, &mut buffer).unwrap());
        let role = PadRole::ALL
            .iter()
            .position(|role| *role == record.role)
            .unwrap();
        body.push(role as u8);
        for taxel in record.geometry.taxels() {
            for value in [taxel.x_mm, taxel.y_mm, taxel.area_mm2] {
                body.extend(value.to_le_bytes());
            }
        }
        body
    }

    /// Writes into `page` (erased, as bytes) a complete page (header, commit word) of
    /// `format_version` and `generation` holding `records`.
    pub fn write_page(page: &mut [u8], format_version: u8, generation: u32, records: &[Vec<u8>]) {
        page[..16].copy_from_slice(&page_header(format_version, generation));
        page[COMMIT_AT..RECORDS_AT].fill(0x00);
        let mut address = RECORDS_AT;
        for record in records {
            page[address..address + record.len()].copy_from_slice(record);
            address += record.len();
        }
    }

    /// Where the erased space after the records of `page` starts (the first slot whose 16
    /// header bytes read erased).
    pub fn free_start(page: &[u8]) -> usize {
        let mut address = RECORDS_AT;
        loop {
            let header = &page[address..address + RECORD_HEADER_LEN];
            if header.iter().all(|&byte| byte == 0xFF) {
                return address;
            }
            let length = u16::from_le_bytes([header[0], header[1]]);
            assert_eq!(!length, u16::from_le_bytes([header[2], header[3]]));
            address += (RECORD_HEADER_LEN + usize::from(length)).next_multiple_of(WORD);
        }
    }

    /// Appends `record` after the records of `page`.
    pub fn append(page: &mut [u8], record: &[u8]) {
        let start = free_start(page);
        page[start..start + record.len()].copy_from_slice(record);
    }
}
