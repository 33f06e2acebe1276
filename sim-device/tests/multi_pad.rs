//! Several pads on one simulated device, end to end: pads behind the simulated TCA9548A, found
//! by the device's discovery, read in turn by the device code, their frames decoded by the
//! host's decoder and checked against each pad's own scene (force = pressure x the article's
//! 5 mm x 5 mm electrodes, computed here, not by model-core); a pad that fails is flagged and
//! recovers on its own while the others keep their rate.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sensor_sim::{Device, Fault, Keyframe, ScriptedScene, Simulation, Window};
use sim_device::testing::Host;
use sim_device::{pads_topology, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{DeviceEvent, DeviceFrame, InfoFrame, SampleFrame};

/// Four 25 mm² electrodes.
const PAD_AREA_M2: f64 = 4.0 * 25e-6;
/// Each pressure within 0.5 kPa of the scene (docs/RELIABILITY.md): 4 x 0.5 kPa x 25 mm².
const FORCE_TOLERANCE_N: f64 = 0.05;

fn keyframe(time_s: f64, pressure_kpa: f32) -> Keyframe {
    Keyframe {
        time_s,
        pressure_kpa: [pressure_kpa; 4],
        temperature_c: 26.0,
    }
}

/// Unloaded for the tare at boot, then `pressure_kpa` on every taxel from 1.2 s to `release_s`.
fn press(pressure_kpa: f32, release_s: f64) -> ScriptedScene {
    ScriptedScene::new(vec![
        keyframe(0.0, 0.0),
        keyframe(1.0, 0.0),
        keyframe(1.2, pressure_kpa),
        keyframe(release_s, pressure_kpa),
        keyframe(release_s + 0.2, 0.0),
        keyframe(release_s + 1.0, 0.0),
    ])
    .unwrap()
}

/// What a run of the device sent.
struct Run {
    info: Option<InfoFrame>,
    samples: Vec<SampleFrame>,
    events: Vec<(u64, DeviceEvent)>,
}

impl Run {
    fn of_pad(&self, pad: u8) -> impl Iterator<Item = &SampleFrame> {
        self.samples
            .iter()
            .filter(move |sample| sample.pad.get() == pad)
    }
}

/// Boots a device with `pads` pads, gives pad k the scene `scene(k)` and `setup` a chance to
/// inject faults, runs it to `until_s` and decodes everything it sent.
fn run(
    pads: usize,
    scene: impl Fn(usize) -> ScriptedScene,
    setup: impl Fn(&Simulation),
    until_s: f64,
) -> Run {
    let device = SimulatedDevice::new(SimulatedDeviceConfig {
        scene: SceneFile::single_pad(
            "unloaded",
            false,
            ScriptedScene::new(vec![keyframe(0.0, 0.0)]).unwrap(),
            Vec::new(),
        ),
        seed: 21,
        speed: None,
        topology: pads_topology(pads),
        bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
    })
    .unwrap();
    for pad in 0..pads {
        let scene = scene(pad);
        device
            .simulation()
            .set_pad_scene(pad, move |time_us: u64| {
                scene.point_at_s(time_us as f64 / 1e6)
            })
            .unwrap();
    }
    setup(device.simulation());
    run_to(device, until_s)
}

/// Steps `device` to `until_s` and decodes everything it sent.
fn run_to(device: SimulatedDevice, until_s: f64) -> Run {
    let mut host = Host::on(device);
    let mut run = Run {
        info: None,
        samples: Vec::new(),
        events: Vec::new(),
    };
    for frame in host.run_until_s(until_s) {
        match frame {
            DeviceFrame::Info(info) => run.info = Some(info),
            DeviceFrame::Sample(sample) => run.samples.push(sample),
            DeviceFrame::Event(event) => run.events.push((event.timestamp_us, event.event)),
            _ => {}
        }
    }
    run
}

/// Pad k presses 6 + 4k kPa.
fn pad_pressure_kpa(pad: usize) -> f32 {
    6.0 + 4.0 * pad as f32
}

fn streams_every_pad(pads: usize) {
    let run = run(pads, |pad| press(pad_pressure_kpa(pad), 2.6), |_| {}, 3.5);
    assert_eq!(run.info.unwrap().pad_count as usize, pads);
    // Every set carries one frame per pad, in pad order, under one sequence number.
    let sets: Vec<&[SampleFrame]> = run.samples.chunks(pads).collect();
    assert!(sets.len() > 300, "{} sets", sets.len());
    for set in &sets {
        if set.len() < pads {
            continue;
        }
        for (pad, sample) in set.iter().enumerate() {
            assert_eq!(sample.pad.get() as usize, pad);
            assert_eq!(sample.sequence, set[0].sequence);
        }
    }
    for pad in 0..pads {
        let expected_n = f64::from(pad_pressure_kpa(pad)) * 1e3 * PAD_AREA_M2;
        let held: Vec<&SampleFrame> = run
            .of_pad(pad as u8)
            .filter(|sample| (1_400_000..2_500_000).contains(&sample.timestamp_us))
            .collect();
        assert!(held.len() > 100, "pad {pad}: {} sets held", held.len());
        for sample in &held {
            let force_n = f64::from(sample.summary.force_n.unwrap());
            assert!(
                (force_n - expected_n).abs() < FORCE_TOLERANCE_N,
                "pad {pad} at {} us: {force_n} N, scene {expected_n} N",
                sample.timestamp_us
            );
            let [x_mm, y_mm] = sample.summary.centre_of_pressure_mm.unwrap();
            assert!(
                x_mm.abs() < 0.5 && y_mm.abs() < 0.5,
                "pad {pad}: centre {x_mm}, {y_mm}"
            );
            assert!(sample.summary.contact && !sample.summary.partial);
        }
        let contacts: Vec<bool> = run
            .events
            .iter()
            .filter_map(|(_, event)| match event {
                DeviceEvent::ContactStarted { pad: p } if p.get() as usize == pad => Some(true),
                DeviceEvent::ContactEnded { pad: p } if p.get() as usize == pad => Some(false),
                _ => None,
            })
            .collect();
        assert_eq!(contacts, [true, false], "pad {pad}: contact events");
    }
}

#[test]
fn one_pad_streams_alone() {
    streams_every_pad(1);
}

#[test]
fn two_pads_stream_each_their_own_scene() {
    streams_every_pad(2);
}

#[test]
fn eight_pads_stream_each_their_own_scene() {
    streams_every_pad(8);
}

/// Sample sets of `pad` with timestamps in `from_s .. to_s`.
fn sets_between(run: &Run, pad: u8, from_s: f64, to_s: f64) -> Vec<&SampleFrame> {
    let range = (from_s * 1e6) as u64..(to_s * 1e6) as u64;
    run.of_pad(pad)
        .filter(|sample| range.contains(&sample.timestamp_us))
        .collect()
}

fn reads(sample: &SampleFrame) -> bool {
    sample.taxels.iter().all(|taxel| taxel.flags == 0) && sample.summary.force_n.is_some()
}

#[test]
fn a_failing_pad_is_flagged_and_recovers_while_the_others_keep_their_rate() {
    const UNPLUGGED: usize = 3;
    const CHANNEL_STUCK_OPEN: usize = 5;
    const NACKING: usize = 6;
    let fault = Window::Between {
        start_us: 2_000_000,
        end_us: 3_000_000,
    };
    let run = run(
        8,
        |_| press(10.0, 5.0),
        |simulation| {
            simulation
                .inject_on_pad(UNPLUGGED, Fault::Unplugged, fault)
                .unwrap();
            simulation.inject_upstream(
                Fault::MuxChannelStuck {
                    channel: CHANNEL_STUCK_OPEN as u8,
                    closed: false,
                },
                fault,
            );
            simulation
                .inject_on_pad(NACKING, Fault::Nack(Device::Fdc1004), fault)
                .unwrap();
        },
        4.5,
    );
    let expected_n = 10.0 * 1e3 * PAD_AREA_M2;
    for pad in 0..8u8 {
        let failing = [UNPLUGGED, CHANNEL_STUCK_OPEN, NACKING].contains(&(pad as usize));
        let before = sets_between(&run, pad, 1.0, 2.0);
        let during = sets_between(&run, pad, 2.0, 3.0);
        // Every pad keeps sending a frame per set, at 95 % of its rate or more while three
        // pads fail (a failing pad costs the others a register read per retry, and one timeout
        // or re-initialisation when it fails or comes back).
        assert!(
            during.len() * 100 >= before.len() * 95,
            "pad {pad}: {} sets in the second before the faults, {} during",
            before.len(),
            during.len()
        );
        if failing {
            let inside = sets_between(&run, pad, 2.05, 2.95);
            assert!(!inside.is_empty(), "pad {pad}: no frame during its fault");
            assert!(
                inside
                    .iter()
                    .all(|sample| !reads(sample) && sample.summary.force_n.is_none()),
                "pad {pad}: a frame during its fault looks good"
            );
            // Back within the longest back-off (0.32 s) and a few sets.
            let after = sets_between(&run, pad, 3.5, 4.5);
            assert!(
                !after.is_empty() && after.iter().all(|sample| reads(sample)),
                "pad {pad}"
            );
            let reinitialised = run.events.iter().any(|(_, event)| {
                matches!(event, DeviceEvent::ConverterReinitialised { pad: p, .. } if p.get() == pad)
            });
            assert!(reinitialised, "pad {pad}: no re-initialisation announced");
        } else {
            for sample in sets_between(&run, pad, 1.5, 4.5) {
                assert!(reads(sample), "pad {pad} at {} us", sample.timestamp_us);
                let force_n = f64::from(sample.summary.force_n.unwrap());
                assert!(
                    (force_n - expected_n).abs() < FORCE_TOLERANCE_N,
                    "pad {pad}: {force_n} N"
                );
            }
        }
    }
}

/// The scene's force on a pad at a time: its pressures times the electrode areas the scene
/// gives the pad (the palm of the glove has larger electrodes than its fingertips).
fn scene_force_n(scene: &SceneFile, pad: usize, time_s: f64) -> f64 {
    let pad = scene.pad(pad).unwrap();
    let point = pad.scene.point_at_s(time_s);
    point
        .pressure_kpa
        .iter()
        .zip(pad.geometry.taxels())
        .map(|(kpa, taxel)| f64::from(*kpa) * 1e3 * f64::from(taxel.area_mm2) * 1e-6)
        .sum()
}

/// A built-in scene of several pads on a board with as many, run to `until_s`.
fn run_built_in(name: &str, until_s: f64) -> (SceneFile, Run) {
    let scene = SceneFile::built_in(name).unwrap();
    let pads = scene.pads.len();
    let device =
        SimulatedDevice::new(SimulatedDeviceConfig::new(scene.clone(), pads).with_seed(4)).unwrap();
    let run = run_to(device, until_s);
    (scene, run)
}

/// Every frame of every pad whose taxels all read follows its pad's scene within the force
/// tolerance (evaluated at the frame's own time).
fn assert_forces_follow_the_scene(scene: &SceneFile, run: &Run, from_s: f64) {
    for sample in &run.samples {
        let time_s = sample.timestamp_us as f64 / 1e6;
        if time_s < from_s || !reads(sample) {
            continue;
        }
        let pad = usize::from(sample.pad.get());
        let expected_n = scene_force_n(scene, pad, time_s);
        // 0.5 kPa on each taxel, over the pad's own electrodes (0.2 N on the glove's palm).
        let area_mm2: f32 = scene
            .pad(pad)
            .unwrap()
            .geometry
            .taxels()
            .iter()
            .map(|taxel| taxel.area_mm2)
            .sum();
        let tolerance_n = 0.5 * f64::from(area_mm2) * 1e-3;
        let force_n = f64::from(sample.summary.force_n.unwrap());
        assert!(
            (force_n - expected_n).abs() < tolerance_n,
            "pad {pad} at {time_s:.3} s: {force_n} N, scene {expected_n} N"
        );
    }
}

#[test]
fn the_gripper_scene_grasps_with_two_pads_and_the_object_slips_down() {
    let (scene, run) = run_built_in("gripper", 8.0);
    assert_eq!(run.info.unwrap().pad_count, 2);
    assert_forces_follow_the_scene(&scene, &run, 1.0);
    for pad in 0..2u8 {
        // Held: centred. Slipping: the centre of pressure moves towards row 2 (negative y).
        let held = sets_between(&run, pad, 3.0, 4.5);
        assert!(!held.is_empty());
        assert!(held.iter().all(|sample| {
            let [x_mm, y_mm] = sample.summary.centre_of_pressure_mm.unwrap();
            x_mm.abs() < 0.3 && y_mm.abs() < 0.3 && sample.summary.contact
        }));
        let slipped = sets_between(&run, pad, 6.8, 7.0);
        assert!(!slipped.is_empty());
        assert!(slipped.iter().all(|sample| {
            let [_, y_mm] = sample.summary.centre_of_pressure_mm.unwrap();
            y_mm < -1.5
        }));
        let released = sets_between(&run, pad, 7.6, 8.0);
        assert!(!released.is_empty());
        assert!(released.iter().all(|sample| !sample.summary.contact));
    }
}

#[test]
fn the_glove_scene_loads_six_pads_and_flags_the_shorted_fingertip_only() {
    let (scene, run) = run_built_in("glove", 10.0);
    assert_eq!(run.info.unwrap().pad_count, 6);
    assert_eq!(scene.pads[1].name, "index fingertip");
    assert_forces_follow_the_scene(&scene, &run, 1.0);
    let shorted = wire::flags::SHORTED;
    for pad in 0..6u8 {
        let during_short = sets_between(&run, pad, 5.1, 6.4);
        assert!(!during_short.is_empty());
        for sample in during_short {
            if pad == 1 {
                assert!(sample.taxels[1].flags & shorted != 0, "pad 1 not flagged");
                assert!(sample.taxels[1].pressure_kpa.is_none());
                // Left out of the force, and said so.
                assert!(sample.summary.partial && sample.summary.contact);
            } else {
                assert!(reads(sample) && sample.summary.contact, "pad {pad}");
            }
        }
        let released = sets_between(&run, pad, 9.3, 10.0);
        assert!(!released.is_empty());
        assert!(released.iter().all(|sample| !sample.summary.contact));
    }
}
