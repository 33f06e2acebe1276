"""Reads an MCAP file `taxel-bridge --sim N --mcap FILE` wrote (or, with --file, one
`taxel record --mcap` wrote of one device playing the same scene) with the Python `mcap` and
`mcap-ros2-support` packages (the readers Foxglove's and ROS 2's tools are built on) and checks
every message: each decodes with the schema stored in the file, the schemas are the standard
ROS 2 types whose hashes rosbags computes, the pad topics' sequence numbers have no gap, the
stamps agree, and the values equal the simulated scene (bridge/tests/python/plateau.toml).

Run by bridge/tests/python_mcap.rs; prints one line per check and a closing
"N passed, M failed" line, and exits non-zero on any failure.
"""

import argparse
import os
import struct
import subprocess
import sys
import tempfile
import tomllib

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_typestore

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
TAXEL_AREA_M2 = 25e-6
PRESSURE_TOLERANCE_KPA = 0.5
FORCE_TOLERANCE_N = 0.05
STEADY_FROM_SEQUENCE = 300  # 3 s of scene time at 100 sample sets per second


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bridge", help="the taxel-bridge program to run (or --file)")
    parser.add_argument("--file", help="an MCAP file `taxel record --mcap` wrote (no diagnostics)")
    parser.add_argument("--scene", required=True)
    parser.add_argument("--devices", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=6.0)
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
                 "--listen", "tcp/127.0.0.1:0", "--no-connect", "--duration", str(args.seconds)],
                capture_output=True, text=True, timeout=args.seconds + 60)
            print(bridge.stderr, end="")
            check(bridge.returncode == 0, f"the bridge exited 0 ({bridge.returncode})")
        with open(path, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            header = reader.get_header()
            summary = reader.get_summary()
            check(header.profile == "ros2", f"profile {header.profile!r}")
            decoded = list(reader.iter_decoded_messages(log_time_order=False))

    total = sum(summary.statistics.channel_message_counts.values())
    check(len(decoded) == total and total > 0, f"every one of the {total} messages decodes with the file's schema ({len(decoded)})")
    schemas = {schema.name for schema in summary.schemas.values()}
    expected_schemas = {"sensor_msgs/msg/PointCloud2", "geometry_msgs/msg/WrenchStamped", "std_msgs/msg/Header"}
    if not args.file:
        expected_schemas.add("diagnostic_msgs/msg/DiagnosticArray")
    check(schemas == expected_schemas, f"the schemas are the standard types ({sorted(schemas)})")
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        expected = TYPESTORE.hash_rihs01(schema.name)
        check(channel.message_encoding == "cdr" and channel.metadata.get("type_hash") == expected and schema.encoding == "ros2msg",
              f"{channel.topic}: cdr with a ros2msg schema, type hash {expected}")

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
            check(len(sequences) > 100 and not gaps, f"{base}/pressure: {len(sequences)} messages without a sequence gap ({gaps[:3]})")
            check([message.sequence for message, _ in wrenches] == sequences, f"{base}/wrench: the same sequences")
            bad = []
            steady = 0
            for message, cloud in clouds:
                if message.sequence < STEADY_FROM_SEQUENCE:
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
                   if message.sequence >= STEADY_FROM_SEQUENCE and abs(-wrench.wrench.force.z - expected_force) > FORCE_TOLERANCE_N]
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
