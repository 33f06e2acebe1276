//! `taxel record --format mcap` of a simulated two-pad device: the file opens with the MCAP
//! library's reader, has the ROS 2 profile, one channel per pad topic with the standard type's
//! schema, consecutive sample-set sequence numbers, stamps no later than arrival, and pressures
//! (read from the CDR bytes by their layout, not with this workspace's encoder) equal to the
//! scene's plateau.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

mod support;

use std::collections::BTreeMap;
use std::process::Command;

use support::SimulatorProcess;

const PLATEAU_KPA: [[f32; 4]; 2] = [[10.0, 20.0, 30.0, 40.0], [5.0, 15.0, 25.0, 35.0]];

fn scene() -> String {
    let mut text = String::from("name = \"plateau\"\nrepeat = false\n");
    for plateau in PLATEAU_KPA {
        text.push_str("\n[[pad]]\n");
        for (time_s, pressures) in [
            (0.0, [0.0; 4]),
            (1.5, [0.0; 4]),
            (2.5, plateau),
            (1000.0, plateau),
        ] {
            text.push_str(&format!(
                "[[pad.keyframe]]\ntime_s = {time_s:?}\npressure_kpa = {pressures:?}\ntemperature_c = 25.0\n"
            ));
        }
    }
    text
}

/// The pressures (kPa) of a PointCloud2 of four points of x, y, z, pressure (Pa), flags: the
/// point data is the CDR message's last 81 bytes but one (`is_dense` ends it).
fn pressures_kpa(cdr: &[u8]) -> [f32; 4] {
    let data = &cdr[cdr.len() - 81..cdr.len() - 1];
    std::array::from_fn(|point| {
        let at = 20 * point + 12;
        f32::from_le_bytes(data[at..at + 4].try_into().unwrap()) / 1000.0
    })
}

#[test]
fn an_mcap_recording_holds_every_pads_messages_as_ros_2_types() {
    let directory = tempfile::tempdir().unwrap();
    let scene_path = directory.path().join("plateau.toml");
    std::fs::write(&scene_path, scene()).unwrap();
    let mut simulator = SimulatorProcess::start(
        directory.path(),
        "port",
        &["--speed", "4", "--scene", scene_path.to_str().unwrap()],
    );
    let recording = directory.path().join("rec.mcap");
    let output = Command::new(support::taxel_binary())
        .args([
            "record",
            &simulator.port,
            "--format",
            "mcap",
            "--samples",
            "500",
            "-o",
        ])
        .arg(&recording)
        .output()
        .unwrap();
    simulator.stop();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{messages}");
    let bytes = std::fs::read(&recording).unwrap();
    let mut topics: BTreeMap<String, Vec<mcap::Message>> = BTreeMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let schema = message.channel.schema.as_ref().unwrap();
        let expected = match message.channel.topic.rsplit('/').next().unwrap() {
            "pressure" => "sensor_msgs/msg/PointCloud2",
            "wrench" => "geometry_msgs/msg/WrenchStamped",
            _ => "std_msgs/msg/Header",
        };
        assert_eq!(schema.name, expected, "{}", message.channel.topic);
        assert_eq!(schema.encoding, "ros2msg");
        assert_eq!(message.channel.message_encoding, "cdr");
        assert!(message.channel.metadata["type_hash"].starts_with("RIHS01_"));
        assert!(
            message.publish_time <= message.log_time,
            "stamped after its arrival"
        );
        topics
            .entry(message.channel.topic.clone())
            .or_default()
            .push(message);
    }
    for (pad, plateau) in PLATEAU_KPA.iter().enumerate() {
        let base = format!("/taxel/device0/pad{pad}");
        let clouds = &topics[&format!("{base}/pressure")];
        let wrenches = &topics[&format!("{base}/wrench")];
        assert!(clouds.len().abs_diff(500) <= 1, "{base}: {}", clouds.len());
        let sequences: Vec<u32> = clouds.iter().map(|message| message.sequence).collect();
        assert!(
            sequences.windows(2).all(|pair| pair[1] == pair[0] + 1),
            "{base}: a sequence gap"
        );
        assert_eq!(
            wrenches
                .iter()
                .map(|message| message.sequence)
                .collect::<Vec<_>>(),
            sequences
        );
        let first = sequences[0];
        let steady: Vec<_> = clouds
            .iter()
            .filter(|message| message.sequence >= first.max(300))
            .collect();
        assert!(steady.len() >= 100, "{base}: {} steady", steady.len());
        for message in steady {
            let pressures = pressures_kpa(&message.data);
            for (taxel, (read, expected)) in pressures.iter().zip(plateau).enumerate() {
                assert!(
                    (read - expected).abs() < 0.5,
                    "{base} taxel {taxel}, set {}: {read} kPa, not {expected}",
                    message.sequence
                );
            }
        }
        assert_eq!(
            topics[&format!("{base}/contact_started")].len(),
            1,
            "{base}"
        );
    }
}
