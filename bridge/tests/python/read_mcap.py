"""Reads an MCAP file `taxel-bridge --sim N --mcap FILE` wrote (or, with --file, one
`taxel record --mcap` wrote of one device playing the same scene) with the Python `mcap` and
`mcap-ros2-support` packages (the readers Foxglove's and ROS 2's tools are built on) and checks
every message: each decodes with the schema stored in the file, the schemas are the standard
ROS 2 types whose hashes rosbags computes, the pad topics' sequence numbers have no gap, the
stamps agree, and the values equal the simulated scene (bridge/tests/python/plateau.toml).

It also checks what rosbag2 itself writes besides the messages, so that `ros2 bag info` and
`ros2 bag play` take the file for one of theirs (ros2/rosbag2, rosbag2_storage_mcap/src/
mcap_storage.cpp: `MCAPStorage::update_topic` and `update_metadata` write, `read_metadata`
reads; rosbag2_storage/include/rosbag2_storage/yaml.hpp and src/rosbag2_storage/qos.cpp say
the YAML): each channel's `offered_qos_profiles` (YAML) and, from Jazzy on, `topic_type_hash`;
the `rosbag2` metadata record, whose `serialized_metadata` (Jazzy) is the bag's metadata in
rosbag2's YAML, version 9, every key its decoder reads present, or whose only key is
`ROS_DISTRO` (Humble, --ros-distro humble).

Run by bridge/tests/python_mcap.rs; prints one line per check and a closing
"N passed, M failed" line, and exits non-zero on any failure.
"""

import argparse
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import tomllib

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader as Rosbag2Reader
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
TAXEL_AREA_M2 = 25e-6
PRESSURE_TOLERANCE_KPA = 0.5
FORCE_TOLERANCE_N = 0.05
STEADY_FROM_SEQUENCE = 300  # 3 s of scene time at 100 sample sets per second

# rmw's RMW_DURATION_INFINITE, which rmw_zenoh reports for a publisher without deadline,
# lifespan or lease (rmw_zenoh_cpp qos.cpp) and rosbag2 writes as {sec, nsec} (qos.cpp).
INFINITE = {"sec": 9223372036, "nsec": 854775807}
# rosbag2's YAML of one QoS profile (convert<rclcpp::QoS>::encode, version 9: the policies as
# rmw_qos_*_policy_to_str words) for the bridge's reliable, volatile, keep-last-10 publishers.
JAZZY_QOS = {"history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile",
             "deadline": INFINITE, "lifespan": INFINITE, "liveliness": "automatic",
             "liveliness_lease_duration": INFINITE, "avoid_ros_namespace_conventions": False}
# Humble's rosbag2 (rosbag2_transport/src/rosbag2_transport/qos.cpp on branch humble) writes the
# rmw enumerations as numbers: KEEP_LAST 1, RELIABLE 1, VOLATILE 2, AUTOMATIC 1 (rmw/types.h).
HUMBLE_QOS = dict(JAZZY_QOS, history=1, reliability=1, durability=2, liveliness=1)


def check_rosbag2_metadata(check, path, summary, metadata_records, distro, sequences_from_1):
    """What rosbag2_storage_mcap writes besides the messages, checked against its source."""
    yaml = YAML(typ="safe")
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        profiles = yaml.load(channel.metadata.get("offered_qos_profiles", ""))
        expected = [JAZZY_QOS if distro == "jazzy" else HUMBLE_QOS]
        check(profiles == expected, f"{channel.topic}: offered_qos_profiles {profiles}")
        if distro == "jazzy":
            expected_hash = TYPESTORE.hash_rihs01(schema.name)
            check(channel.metadata.get("topic_type_hash") == expected_hash and "type_hash" not in channel.metadata,
                  f"{channel.topic}: topic_type_hash {expected_hash}")
        else:
            check("topic_type_hash" not in channel.metadata, f"{channel.topic}: no topic_type_hash (Humble)")
    records = [record for record in metadata_records if record.name == "rosbag2"]
    check(len(records) == 1, f"one rosbag2 metadata record ({len(records)})")
    if not records:
        return
    record = records[0].metadata
    if distro == "humble":
        check(record == {"ROS_DISTRO": "humble"}, f"Humble's rosbag2 record holds ROS_DISTRO only ({record})")
        return
    check(set(record) == {"serialized_metadata"}, f"the rosbag2 record holds serialized_metadata ({sorted(record)})")
    bag = yaml.load(record.get("serialized_metadata", ""))
    # Every key YAML::convert<rosbag2_storage::BagMetadata>::decode reads for version 9.
    required = ["version", "storage_identifier", "duration", "starting_time", "message_count",
                "topics_with_message_count", "relative_file_paths", "compression_format",
                "compression_mode", "files", "custom_data", "ros_distro"]
    check(all(key in bag for key in required), f"serialized_metadata has every key rosbag2 decodes ({sorted(bag)})")
    check(bag.get("version") == 9 and bag.get("storage_identifier") == "mcap" and bag.get("ros_distro") == "jazzy",
          f"version 9, storage mcap, ros_distro jazzy ({bag.get('version')}, {bag.get('storage_identifier')}, {bag.get('ros_distro')})")
    statistics = summary.statistics
    total = sum(statistics.channel_message_counts.values())
    check(bag.get("message_count") == total, f"message_count {bag.get('message_count')} = {total}")
    check(bag.get("starting_time") == {"nanoseconds_since_epoch": statistics.message_start_time}
          and bag.get("duration") == {"nanoseconds": statistics.message_end_time - statistics.message_start_time},
          f"starting_time and duration as the statistics ({bag.get('starting_time')}, {bag.get('duration')})")
    name = os.path.basename(path)
    files = bag.get("files") or [{}]
    check(bag.get("relative_file_paths") == [name] and files[0].get("path") == name
          and files[0].get("message_count") == total, f"the file is {name} ({bag.get('relative_file_paths')})")
    by_name = {channel.topic: channel for channel in summary.channels.values()}
    topics = bag.get("topics_with_message_count") or []
    bad = []
    for topic in topics:
        metadata = topic["topic_metadata"]
        channel = by_name.get(metadata["name"])
        if channel is None:
            bad.append(metadata["name"])
            continue
        schema = summary.schemas[channel.schema_id]
        if (metadata["type"] != schema.name or metadata["serialization_format"] != "cdr"
                or metadata["type_description_hash"] != TYPESTORE.hash_rihs01(schema.name)
                or metadata["offered_qos_profiles"] != [JAZZY_QOS]
                or topic["message_count"] != statistics.channel_message_counts.get(channel.id, 0)):
            bad.append(metadata["name"])
    check(len(topics) == len(by_name) and not bad, f"a topic_metadata per channel with its type, hash, QoS and count ({bad[:3]})")

    # rosbags' own rosbag2 reader, given the record as the bag's metadata.yaml (what rosbag2
    # writes beside a bag: the same BagMetadata under rosbag2_bagfile_information), opens the bag.
    with tempfile.TemporaryDirectory() as directory:
        shutil.copy(path, os.path.join(directory, name))
        with open(os.path.join(directory, "metadata.yaml"), "w") as metadata_file:
            metadata_file.write("rosbag2_bagfile_information:\n")
            metadata_file.writelines(f"  {line}\n" for line in record["serialized_metadata"].splitlines())
        try:
            with Rosbag2Reader(directory) as bag_reader:
                qos = {str(profile.history) for connection in bag_reader.connections
                       for profile in connection.ext.offered_qos_profiles}
                read = sum(1 for _ in bag_reader.messages())
                check(bag_reader.message_count == total and read == total and qos == {"QosHistory.KEEP_LAST"},
                      f"rosbags' rosbag2 reader takes the record for the bag's metadata ({bag_reader.message_count} messages, {read} read, history {qos})")
        except Exception as error:  # noqa: BLE001 - any refusal is the failure reported
            check(False, f"rosbags' rosbag2 reader takes the record for the bag's metadata ({error!r})")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bridge", help="the taxel-bridge program to run (or --file)")
    parser.add_argument("--file", help="an MCAP file `taxel record --mcap` wrote (no diagnostics)")
    parser.add_argument("--scene", required=True)
    parser.add_argument("--devices", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--ros-distro", default="jazzy", choices=["jazzy", "humble"])
    args = parser.parse_args()
    with open(args.scene, "rb") as scene_file:
        plateaus = [pad["keyframe"][-1]["pressure_kpa"] for pad in tomllib.load(scene_file)["pad"]]

    passed = failed = 0

    def check(condition, message):
        nonlocal passed, failed
        if condition:
            passed += 1
            print(f"ok: {message}")
        else:
            failed += 1
            print(f"FAILED: {message}")

    with tempfile.TemporaryDirectory() as directory:
        if args.file:
            path = args.file
        else:
            path = os.path.join(directory, "bridge.mcap")
            bridge = subprocess.run(
                [args.bridge, "--sim", str(args.devices), "--sim-scene", args.scene, "--mcap", path,
                 "--listen", "tcp/127.0.0.1:0", "--no-connect", "--duration", str(args.seconds),
                 "--ros-distro", args.ros_distro],
                capture_output=True, text=True, timeout=args.seconds + 60)
            print(bridge.stderr, end="")
            check(bridge.returncode == 0, f"the bridge exited 0 ({bridge.returncode})")
        with open(path, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            header = reader.get_header()
            summary = reader.get_summary()
            check(header.profile == "ros2", f"profile {header.profile!r}")
            decoded = list(reader.iter_decoded_messages(log_time_order=False))
            metadata_records = list(reader.iter_metadata())
        check_rosbag2_metadata(check, path, summary, metadata_records, args.ros_distro, not args.file)

    total = sum(summary.statistics.channel_message_counts.values())
    check(len(decoded) == total and total > 0, f"every one of the {total} messages decodes with the file's schema ({len(decoded)})")
    schemas = {schema.name for schema in summary.schemas.values()}
    expected_schemas = {"sensor_msgs/msg/PointCloud2", "geometry_msgs/msg/WrenchStamped", "std_msgs/msg/Header"}
    if not args.file:
        expected_schemas.add("diagnostic_msgs/msg/DiagnosticArray")
    check(schemas == expected_schemas, f"the schemas are the standard types ({sorted(schemas)})")
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        check(channel.message_encoding == "cdr" and schema.encoding == "ros2msg",
              f"{channel.topic}: cdr with a ros2msg schema")

    by_topic = {}
    for schema, channel, message, ros_message in decoded:
        by_topic.setdefault(channel.topic, []).append((message, ros_message))
        stamp = getattr(ros_message, "header", None)
    stamps_bad = []
    for topic, messages in by_topic.items():
        for message, ros_message in messages:
            header = ros_message.header if hasattr(ros_message, "header") else ros_message
            stamp_ns = header.stamp.sec * 1_000_000_000 + header.stamp.nanosec
            if stamp_ns != message.publish_time or message.log_time < message.publish_time:
                stamps_bad.append((topic, message.sequence))
    check(not stamps_bad, f"publish time = header stamp <= log time on every message ({stamps_bad[:3]})")

    for device in range(args.devices):
        for pad, plateau in enumerate(plateaus):
            base = f"/taxel/device{device}/pad{pad}"
            clouds = by_topic.get(base + "/pressure", [])
            wrenches = by_topic.get(base + "/wrench", [])
            sequences = [message.sequence for message, _ in clouds]
            gaps = [b - a for a, b in zip(sequences, sequences[1:]) if b - a != 1]
            # The steady part starts 3 s after the first set recorded (or later in scene time).
            first_sequence = sequences[0] if sequences else 0
            check(len(sequences) > 100 and not gaps, f"{base}/pressure: {len(sequences)} messages without a sequence gap ({gaps[:3]})")
            if not args.file:
                # The bridge numbers each publisher's messages from 1, as rmw_zenoh does.
                check(sequences[:1] == [1], f"{base}/pressure: the bridge's sequence starts at 1 ({sequences[:1]})")
            check([message.sequence for message, _ in wrenches] == sequences, f"{base}/wrench: the same sequences")
            bad = []
            steady = 0
            for message, cloud in clouds:
                if message.sequence - first_sequence < STEADY_FROM_SEQUENCE:
                    continue
                steady += 1
                data = bytes(cloud.data)
                for index in range(4):
                    pressure_pa = struct.unpack_from("<f", data, 20 * index + 12)[0]
                    if abs(pressure_pa / 1000.0 - plateau[index]) > PRESSURE_TOLERANCE_KPA:
                        bad.append((message.sequence, index, pressure_pa))
            check(steady >= 100 and not bad, f"{base}/pressure: {steady} steady messages at {plateau} kPa ({bad[:3]})")
            expected_force = sum(plateau) * 1000.0 * TAXEL_AREA_M2
            bad = [message.sequence for message, wrench in wrenches
                   if message.sequence - first_sequence >= STEADY_FROM_SEQUENCE and abs(-wrench.wrench.force.z - expected_force) > FORCE_TOLERANCE_N]
            check(not bad, f"{base}/wrench: {expected_force:.3f} N within {FORCE_TOLERANCE_N} N ({bad[:3]})")
            started = by_topic.get(base + "/contact_started", [])
            check(len(started) == 1 and started[0][1].frame_id == f"taxel_device{device}_pad{pad}", f"{base}: one contact_started in the pad's frame")

    diagnostics = by_topic.get("/diagnostics", [])
    if not args.file:
        check(len(diagnostics) >= 3, f"{len(diagnostics)} diagnostic arrays")
    if diagnostics:
        names = [status.name for status in diagnostics[0][1].status]
        check(names == [f"taxel_bridge: device{device}" for device in range(args.devices)], f"a status per device ({names})")

    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
