//! An MCU-only reset while the pads are loaded (a watchdog reset in a gripper holding an
//! object): every pad's baselines come back from the retained RAM, so each held load still reads
//! as itself (the policy without an intact record, "not tared" rather than a zero, is tested in
//! `device`).

// Test helpers may unwrap: a failure is the test failing.
#![allow(clippy::unwrap_used)]

use device::{HostInputEvent, HostPort, Outgoing, QueueFull};
use sensor_sim::{Keyframe, ScriptedScene};
use sim_device::{PadScene, SceneFile, SimulatedDevice, SimulatedDeviceConfig};

/// A host that is connected and throws everything away.
struct Sink;

impl HostPort for Sink {
    fn host_connected(&mut self) -> bool {
        true
    }
    fn try_receive(&mut self) -> Option<HostInputEvent> {
        None
    }
    fn try_send(&mut self, _outgoing: Outgoing) -> Result<(), QueueFull> {
        Ok(())
    }
}

fn loaded_device() -> SimulatedDevice {
    let keyframe = |time_s, pressure_kpa, temperature_c| Keyframe {
        time_s,
        pressure_kpa,
        temperature_c,
    };
    let scene = ScriptedScene::new(vec![
        keyframe(0.0, [0.0; 4], 26.0),
        keyframe(1.0, [0.0; 4], 26.0),
        keyframe(1.5, [30.0, 12.0, 0.0, 45.0], 26.0),
    ])
    .unwrap();
    SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::single_pad("held", false, scene, Vec::new()), 1)
            .with_seed(5),
    )
    .unwrap()
}

fn run_until(device: &mut SimulatedDevice, until_s: f64) -> model_core::PadOutput {
    let mut last = None;
    while device.simulation().now_us() < (until_s * 1e6) as u64 {
        last = device.step(&mut Sink).map(|sample| sample.output);
    }
    last.unwrap()
}

#[test]
fn a_held_load_survives_an_mcu_only_reset() {
    let mut device = loaded_device();
    let before = run_until(&mut device, 3.0);
    device.restart_mcu().unwrap();
    let after = run_until(&mut device, 4.0);
    for (taxel, expected) in [30.0f32, 12.0, 0.0, 45.0].into_iter().enumerate() {
        let before = before.taxels[taxel].pressure_kpa().unwrap();
        let after = after.taxels[taxel].pressure_kpa().unwrap();
        assert!(
            (before - expected).abs() < 0.5 && (after - expected).abs() < 0.5,
            "taxel {taxel}: {before} -> {after}"
        );
    }
}

/// Three pads holding three different loads, on multiplexer channels 0 to 2.
#[test]
fn every_pads_held_load_survives_an_mcu_only_reset() {
    let held: [[f32; 4]; 3] = [
        [30.0, 12.0, 0.0, 45.0],
        [5.0, 40.0, 22.0, 0.0],
        [0.0, 0.0, 18.0, 36.0],
    ];
    let pad_scene = |pressures: [f32; 4]| PadScene {
        name: String::new(),
        role: model_core::PadRole::Unspecified,
        geometry: model_core::PadGeometry::ARTICLE,
        scene: ScriptedScene::new(vec![
            Keyframe {
                time_s: 0.0,
                pressure_kpa: [0.0; 4],
                temperature_c: 26.0,
            },
            Keyframe {
                time_s: 1.0,
                pressure_kpa: [0.0; 4],
                temperature_c: 26.0,
            },
            Keyframe {
                time_s: 1.5,
                pressure_kpa: pressures,
                temperature_c: 26.0,
            },
        ])
        .unwrap(),
        faults: Vec::new(),
    };
    let mut device = SimulatedDevice::new(SimulatedDeviceConfig {
        scene: SceneFile {
            name: "held by three pads".into(),
            repeat: false,
            pads: held.iter().map(|pressures| pad_scene(*pressures)).collect(),
        },
        seed: 5,
        speed: None,
        topology: sim_device::pads_topology(3),
        bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
    })
    .unwrap();
    let run_until = |device: &mut SimulatedDevice, until_s: f64| {
        let mut last = [None; 3];
        while device.simulation().now_us() < (until_s * 1e6) as u64 {
            device.step_observed(&mut Sink, |sample| {
                last[usize::from(sample.pad)] = Some(sample.output);
            });
        }
        last.map(Option::unwrap)
    };
    let before = run_until(&mut device, 3.0);
    device.restart_mcu().unwrap();
    let after = run_until(&mut device, 4.0);
    for (pad, pressures) in held.iter().enumerate() {
        for (taxel, expected) in pressures.iter().enumerate() {
            let before = before[pad].taxels[taxel].pressure_kpa().unwrap();
            let after = after[pad].taxels[taxel].pressure_kpa();
            assert!(
                (before - expected).abs() < 0.5,
                "pad {pad} taxel {taxel} before: {before}"
            );
            assert!(
                after.is_some_and(|after| (after - expected).abs() < 0.5),
                "pad {pad} taxel {taxel}: {before} -> {after:?}"
            );
        }
    }
}
