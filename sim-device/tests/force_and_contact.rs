//! Force, centre of pressure and contact end to end: scripted scenes on the simulated pad, the
//! device code converting them, the frames decoded by the host's decoder, checked against the
//! scene (its pressures times the electrode areas and centres of the article's pad, computed here
//! and not by model-core).

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sensor_sim::{Keyframe, ScriptedScene};
use sim_device::testing::Host;
use sim_device::{SceneFile, SimulatedDeviceConfig};
use wire::{DeviceEvent, DeviceFrame, SampleFrame};

/// Electrode area (5 mm x 5 mm) and centres of C11, C12, C21, C22 (x along a row, y towards
/// row 1, origin at the pad centre), as the sensor notes give them.
const AREA_MM2: f64 = 25.0;
const CENTRES_MM: [[f64; 2]; 4] = [[-2.75, 2.75], [2.75, 2.75], [-2.75, -2.75], [2.75, -2.75]];

/// The device reports each pressure within 0.5 kPa of the scene (docs/RELIABILITY.md), so the
/// force of four taxels is within 4 x 0.5 kPa x 25 mm² = 0.05 N.
const FORCE_TOLERANCE_N: f64 = 0.05;
/// At 0.25 N or more (10 kPa on one taxel), 0.5 kPa per taxel moves the centre by at most
/// about 0.35 mm; 0.5 mm leaves room.
const CENTRE_TOLERANCE_MM: f64 = 0.5;
const CENTRE_CHECKED_ABOVE_N: f64 = 0.25;

fn keyframe(time_s: f64, pressure_kpa: [f32; 4]) -> Keyframe {
    Keyframe {
        time_s,
        pressure_kpa,
        temperature_c: 26.0,
    }
}

/// Unloaded for the tare at boot, a centred press, a press on C12 alone, then a press sliding
/// from C11 to C12 along the top row.
fn scene() -> ScriptedScene {
    ScriptedScene::new(vec![
        keyframe(0.0, [0.0; 4]),
        keyframe(1.0, [0.0; 4]),
        keyframe(1.2, [20.0; 4]),
        keyframe(2.2, [20.0; 4]),
        keyframe(2.4, [0.0; 4]),
        keyframe(3.0, [0.0; 4]),
        keyframe(3.2, [0.0, 30.0, 0.0, 0.0]),
        keyframe(4.2, [0.0, 30.0, 0.0, 0.0]),
        keyframe(4.4, [0.0; 4]),
        keyframe(5.0, [0.0; 4]),
        keyframe(5.2, [30.0, 0.0, 0.0, 0.0]),
        keyframe(7.2, [0.0, 30.0, 0.0, 0.0]),
        keyframe(7.4, [0.0; 4]),
        keyframe(8.0, [0.0; 4]),
    ])
    .unwrap()
}

/// The scene's force and centre of pressure at a time.
fn truth(scene: &ScriptedScene, time_s: f64) -> (f64, Option<[f64; 2]>) {
    let pressures = scene.point_at_s(time_s).pressure_kpa.map(f64::from);
    let forces: Vec<f64> = pressures.iter().map(|kpa| kpa * AREA_MM2 * 1e-3).collect();
    let force_n: f64 = forces.iter().sum();
    let centre = (force_n > 0.0).then(|| {
        let mut centre = [0.0; 2];
        for (force, taxel_centre) in forces.iter().zip(CENTRES_MM) {
            centre[0] += force * taxel_centre[0] / force_n;
            centre[1] += force * taxel_centre[1] / force_n;
        }
        centre
    });
    (force_n, centre)
}

/// Runs the scene and returns the sample frames and the contact events (start?, time).
fn run() -> (Vec<SampleFrame>, Vec<(bool, u64)>) {
    let mut host = Host::with_config(
        SimulatedDeviceConfig::new(
            SceneFile::single_pad("presses", false, scene(), Vec::new()),
            1,
        )
        .with_seed(11),
    );
    let (mut samples, mut contacts) = (Vec::new(), Vec::new());
    for frame in host.run_until_s(8.0) {
        match frame {
            DeviceFrame::Sample(sample) => samples.push(sample),
            DeviceFrame::Event(event) => match event.event {
                DeviceEvent::ContactStarted { pad } => {
                    assert_eq!(pad.get(), 0);
                    contacts.push((true, event.timestamp_us));
                }
                DeviceEvent::ContactEnded { pad } => {
                    assert_eq!(pad.get(), 0);
                    contacts.push((false, event.timestamp_us));
                }
                _ => {}
            },
            _ => {}
        }
    }
    (samples, contacts)
}

#[test]
fn force_and_centre_of_pressure_follow_the_scene() {
    let scene = scene();
    let (samples, _) = run();
    let mut checked = (0, 0);
    let mut worst = (0.0f64, 0.0f64);
    for sample in samples
        .iter()
        .filter(|sample| sample.timestamp_us > 600_000)
    {
        // The set's four conversions span the 10 ms before its timestamp.
        let time_s = (sample.timestamp_us as f64 - 5_000.0) / 1e6;
        let (force_n, centre_mm) = truth(&scene, time_s);
        let reported_n = f64::from(sample.summary.force_n.unwrap());
        assert!(!sample.summary.partial, "{sample:?}");
        assert!(
            (reported_n - force_n).abs() <= FORCE_TOLERANCE_N,
            "{time_s:.3} s: {reported_n} N, scene {force_n} N"
        );
        worst.0 = worst.0.max((reported_n - force_n).abs());
        checked.0 += 1;
        if let (Some(centre_mm), true) = (centre_mm, force_n >= CENTRE_CHECKED_ABOVE_N) {
            let [x_mm, y_mm] = sample.summary.centre_of_pressure_mm.unwrap().map(f64::from);
            let error_mm = (x_mm - centre_mm[0]).hypot(y_mm - centre_mm[1]);
            assert!(
                error_mm <= CENTRE_TOLERANCE_MM,
                "{time_s:.3} s: ({x_mm}, {y_mm}) mm, scene {centre_mm:?}"
            );
            worst.1 = worst.1.max(error_mm);
            checked.1 += 1;
        }
    }
    // Centred, one taxel and the slide all took part.
    assert!(checked.0 > 600 && checked.1 > 350, "{checked:?}");
    eprintln!(
        "force: worst {:.4} N over {} sets; centre: worst {:.3} mm over {} sets",
        worst.0, checked.0, worst.1, checked.1
    );
}

#[test]
fn the_slide_moves_the_centre_along_the_top_row() {
    let (samples, _) = run();
    let at = |time_s: f64| {
        samples
            .iter()
            .find(|sample| sample.timestamp_us as f64 >= time_s * 1e6)
            .and_then(|sample| sample.summary.centre_of_pressure_mm)
            .unwrap()
    };
    // A quarter, half and three quarters of the way from C11 to C12.
    for (time_s, x_mm) in [(5.7, -1.375), (6.2, 0.0), (6.7, 1.375)] {
        let [x, y] = at(time_s);
        assert!((f64::from(x) - x_mm).abs() < 0.3, "{time_s} s: x {x}");
        assert!((f64::from(y) - 2.75).abs() < 0.3, "{time_s} s: y {y}");
    }
}

#[test]
fn each_press_is_one_contact_with_its_start_and_end_time() {
    let (_, contacts) = run();
    let kinds: Vec<bool> = contacts.iter().map(|(start, _)| *start).collect();
    assert_eq!(
        kinds,
        [true, false, true, false, true, false],
        "{contacts:?}"
    );
    // The force crosses 0.05 N (on) a little after each press starts and 0.03 N (off) just
    // before it ends; the debounce adds three sets (30 ms at 400 conversions/s).
    let expected_s = [1.2, 2.4, 3.2, 4.4, 5.2, 7.4];
    for ((_, time_us), near_s) in contacts.iter().zip(expected_s) {
        let time_s = *time_us as f64 / 1e6;
        assert!(
            (near_s - 0.2..near_s + 0.1).contains(&time_s),
            "event at {time_s} s, expected near {near_s} s"
        );
    }
}
