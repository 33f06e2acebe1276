//! `taxel record --mcap` of a simulated two-pad device: the file opens with the MCAP library's
//! reader, has the ROS 2 profile, one channel per pad topic with the standard type's schema,
//! exactly `--samples` sets of every pad with consecutive sequence numbers, stamps (the header's
//! and the message's publish time alike) never later than arrival and equal to the CSV's
//! `host_time_s` of the same set (one stamping policy for both files), and pressures (read
//! from the CDR bytes by their layout, not with this workspace's encoder) equal to the scene's
//! plateau.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

mod support;

use std::collections::{BTreeMap, HashMap};
use std::process::Command;

use support::SimulatorProcess;
use taxel_host::schema::RowReader;

const PLATEAU_KPA: [[f32; 4]; 2] = [[10.0, 20.0, 30.0, 40.0], [5.0, 15.0, 25.0, 35.0]];

/// Sample sets recorded.
const SETS: usize = 500;

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

/// The header stamp of a message that starts with a `std_msgs/Header` (after the 4-byte CDR
/// encapsulation: `sec` as i32, `nanosec` as u32, little-endian), ns since the Unix epoch.
fn header_stamp_ns(cdr: &[u8]) -> u64 {
    let sec = i32::from_le_bytes(cdr[4..8].try_into().unwrap());
    let nanosec = u32::from_le_bytes(cdr[8..12].try_into().unwrap());
    u64::try_from(sec).unwrap() * 1_000_000_000 + u64::from(nanosec)
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
    let csv = directory.path().join("rec.csv");
    let output = Command::new(support::taxel_binary())
        .args(["record", &simulator.port, "--samples", &SETS.to_string()])
        .arg("--mcap")
        .arg(&recording)
        .arg("-o")
        .arg(&csv)
        .output()
        .unwrap();
    simulator.stop();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{messages}");

    // The CSV written with it: (pad, seq) -> host_time_s in µs.
    let mut csv_stamps_us: HashMap<(u8, u32), u64> = HashMap::new();
    let mut reader =
        RowReader::new(std::io::BufReader::new(std::fs::File::open(&csv).unwrap())).unwrap();
    while let Some(row) = reader.next_row() {
        let row = row.unwrap();
        assert_eq!(row.device, 0);
        csv_stamps_us.insert((row.pad, row.sequence), row.host_time_us);
    }
    assert_eq!(csv_stamps_us.len(), 2 * SETS);

    let bytes = std::fs::read(&recording).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert_eq!(summary.stats.unwrap().message_count, {
        // A cloud and a wrench per pad per set, and one contact start per pad.
        2 * 2 * SETS as u64 + 2
    });
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
        assert!(message.channel.metadata["topic_type_hash"].starts_with("RIHS01_"));
        assert!(
            message.publish_time <= message.log_time,
            "stamped after its arrival"
        );
        assert_eq!(
            header_stamp_ns(&message.data),
            message.publish_time,
            "{}: the header's stamp is the publish time",
            message.channel.topic
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
        // --samples N: N sets of every pad, in the MCAP file as in the CSV.
        assert_eq!(clouds.len(), SETS, "{base}");
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
        for message in clouds.iter().chain(wrenches) {
            let csv_us = csv_stamps_us[&(pad as u8, message.sequence)];
            assert_eq!(
                message.publish_time,
                csv_us * 1_000,
                "{base} set {}: the MCAP and CSV stamps differ",
                message.sequence
            );
        }
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
