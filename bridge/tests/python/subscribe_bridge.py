"""An independent subscriber to `taxel-bridge --sim N`: Python's eclipse-zenoh receives what the
bridge publishes, rosbags decodes the CDR payloads of the standard ROS 2 types, and every message
is checked against the simulated scene (bridge/tests/python/plateau.toml), the sequence numbers,
the stamps and the type hashes rosbags computes. Nothing of the bridge's own code is used.

Each message's attachment carries its publisher's GID, which rmw_zenoh computes as XXH3-128 of
the publisher's liveliness token, the low 64 bits then the high 64 bits, little-endian
(rmw_zenoh_cpp/src/detail/liveliness_utils.cpp, `Entity::Entity`: `simplified_XXH3_128bits` of
`liveliness_keyexpr_`, then `memcpy` of `low64` and `high64`): checked with Python's `xxhash`
(a binding of the reference C library) on the tokens received. Each publisher numbers its
messages from 1, as rmw_zenoh's `PublisherData` does (`sequence_number_(1)`). Without
--allow-commands the bridge serves nothing: no service server token (`SS`), and its start-up
line says so.

With --default-network the bridge is given no network option: this subscriber plays the
rmw_zenoh router on this machine (tcp/127.0.0.1:7447, where the bridge connects by default), and
while the bridge runs its sockets are read from /proc (Linux): it must listen on loopback only and
have no UDP socket on Zenoh's multicast scouting port 7446. The same check, run on a bridge given
`--listen tcp/0.0.0.0:0 --multicast-scouting`, must see both (so the check can fail).

Run by bridge-cli/tests/python_clients.rs; prints one line per check and a closing
"N passed, M failed" line, and exits non-zero on any failure. With --report FILE it also writes
the latency of every pad message (bridge arrival of the frame to reception here), for
PERFORMANCE.md.
"""

import argparse
import ipaddress
import json
import os
import socket
import struct
import subprocess
import sys
import threading
import time
import tomllib

import xxhash
import zenoh
from rosbags.typesys import Stores, get_typestore

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
# Per pad of the article: 25 mm² per taxel, centres at (±2.75, ±2.75) mm in C11, C12, C21, C22
# order (model-core's PadGeometry::ARTICLE, restated here).
TAXEL_AREA_M2 = 25e-6
TAXEL_CENTRES_M = [(-2.75e-3, 2.75e-3), (2.75e-3, 2.75e-3), (-2.75e-3, -2.75e-3), (2.75e-3, -2.75e-3)]
PRESSURE_TOLERANCE_KPA = 0.5
FORCE_TOLERANCE_N = 0.05
CENTRE_TOLERANCE_M = 0.2e-3
STEADY_FROM_S = 3.0


ROUTER_PORT = 7447
MULTICAST_SCOUTING_PORT = 7446


def socket_inodes(pid):
    """The inodes of the sockets process `pid` holds."""
    inodes = set()
    fd_dir = f"/proc/{pid}/fd"
    for fd in os.listdir(fd_dir):
        try:
            target = os.readlink(os.path.join(fd_dir, fd))
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(int(target[len("socket:["):-1]))
    return inodes


def decode_address(hex_address):
    """`0100007F:1D17` (or its IPv6 form) -> ("127.0.0.1", 7447)."""
    address, port = hex_address.split(":")
    raw = bytes.fromhex(address)
    # /proc prints each 32-bit word in host (little-endian) order.
    words = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    family = socket.AF_INET if len(words) == 4 else socket.AF_INET6
    return socket.inet_ntop(family, words), int(port, 16)


def exposure(pid):
    """(addresses process `pid` listens on by TCP, local ports of its UDP sockets)."""
    inodes = socket_inodes(pid)
    listening, udp_ports = [], []
    for table in ("tcp", "tcp6", "udp", "udp6"):
        with open(f"/proc/net/{table}") as lines:
            next(lines)
            for line in lines:
                fields = line.split()
                if int(fields[9]) not in inodes:
                    continue
                address, port = decode_address(fields[1])
                if table.startswith("tcp") and fields[3] == "0A":
                    listening.append((address, port))
                elif table.startswith("udp"):
                    udp_ports.append(port)
    return listening, udp_ports


def is_loopback(address):
    return ipaddress.ip_address(address).is_loopback


def run_bridge(command, seconds, inspect):
    """Runs the bridge; with `inspect`, reads its sockets 2.5 s in. -> (completed, exposure)."""
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = None
    if inspect:
        time.sleep(2.5)
        seen = exposure(process.pid)
    stdout, stderr = process.communicate(timeout=seconds + 60)
    return subprocess.CompletedProcess(command, process.returncode, stdout, stderr), seen


class Checks:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def check(self, condition, message):
        if condition:
            self.passed += 1
            print(f"ok: {message}")
        else:
            self.failed += 1
            print(f"FAILED: {message}")


def ros_type_of(dds_name):
    """`sensor_msgs::msg::dds_::PointCloud2_` -> `sensor_msgs/msg/PointCloud2`."""
    package, kind, _, name = dds_name.split("::")
    return f"{package}/{kind}/{name[:-1]}"


def parse_key(key):
    """`<domain>/<topic…>/<dds type>/<hash>` -> (domain, topic, ros type, hash)."""
    chunks = key.split("/")
    return chunks[0], "/" + "/".join(chunks[1:-2]), ros_type_of(chunks[-2]), chunks[-1]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bridge", required=True, help="the taxel-bridge binary")
    parser.add_argument("--scene", required=True)
    parser.add_argument("--devices", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--port", type=int, default=17447)
    parser.add_argument("--report", help="write latencies and counts here (JSON)")
    parser.add_argument("--timing-log", help="passed to the bridge (for --report)")
    parser.add_argument("--default-network", action="store_true",
                        help="give the bridge no network option; play the router on 7447")
    args = parser.parse_args()
    if args.default_network:
        args.port = ROUTER_PORT

    with open(args.scene, "rb") as scene_file:
        scene = tomllib.load(scene_file)
    plateaus = [pad["keyframe"][-1]["pressure_kpa"] for pad in scene["pad"]]

    received = []
    tokens = []
    lock = threading.Lock()

    def on_data(sample):
        now_ns = time.time_ns()
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
        with lock:
            received.append((str(sample.key_expr), sample.payload.to_bytes(), attachment, now_ns))

    def on_token(sample):
        with lock:
            tokens.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

    config = zenoh.Config()
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{args.port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(config)
    data_subscriber = session.declare_subscriber("0/**", on_data)
    token_subscriber = session.liveliness().declare_subscriber("@ros2_lv/0/**", on_token, history=True)

    command = [args.bridge, "--sim", str(args.devices), "--sim-scene", args.scene, "--duration", str(args.seconds)]
    if not args.default_network:
        command += ["--connect", f"tcp/127.0.0.1:{args.port}", "--listen", "tcp/127.0.0.1:0"]
    if args.timing_log:
        command += ["--timing-log", args.timing_log]
    started = time.monotonic()
    bridge, seen = run_bridge(command, args.seconds, inspect=args.default_network)
    elapsed = time.monotonic() - started
    time.sleep(0.5)
    data_subscriber.undeclare()
    token_subscriber.undeclare()
    session.close()
    print(bridge.stderr, end="")

    checks = Checks()
    checks.check(bridge.returncode == 0, f"the bridge ran {elapsed:.1f} s and exited 0 ({bridge.returncode})")
    checks.check("; no commands accepted;" in bridge.stderr, "the start-up line says no commands are accepted")
    if args.default_network:
        listening, udp_ports = seen
        checks.check(listening and all(is_loopback(address) for address, _ in listening),
                     f"with no network option the bridge listens on loopback only ({listening})")
        checks.check(MULTICAST_SCOUTING_PORT not in udp_ports,
                     f"with no network option the bridge has no multicast scouting socket (UDP ports {udp_ports})")
        # The same check sees an exposed bridge.
        exposed_command = [args.bridge, "--sim", "1", "--sim-scene", args.scene, "--duration", "4",
                           "--listen", "tcp/0.0.0.0:0", "--multicast-scouting", "--no-connect"]
        exposed, (listening, udp_ports) = run_bridge(exposed_command, 4, inspect=True)
        checks.check(any(not is_loopback(address) for address, _ in listening) and MULTICAST_SCOUTING_PORT in udp_ports,
                     f"the check sees a bridge opened with --listen tcp/0.0.0.0:0 --multicast-scouting ({listening}, UDP {udp_ports}; exit {exposed.returncode})")

    by_topic = {}
    for key, payload, attachment, now_ns in received:
        by_topic.setdefault(key, []).append((payload, attachment, now_ns))

    # Type hashes in the key expressions equal rosbags' RIHS01 of the named types.
    types_seen = {}
    for key in by_topic:
        _, topic, ros_type, type_hash = parse_key(key)
        types_seen[ros_type] = type_hash
    for ros_type, type_hash in sorted(types_seen.items()):
        checks.check(type_hash == TYPESTORE.hash_rihs01(ros_type), f"{ros_type}: key hash {type_hash} equals rosbags'")
    expected_types = {"sensor_msgs/msg/PointCloud2", "geometry_msgs/msg/WrenchStamped",
                      "std_msgs/msg/Header", "diagnostic_msgs/msg/DiagnosticArray"}
    checks.check(set(types_seen) == expected_types, f"the four message types are published ({sorted(types_seen)})")

    # Liveliness: the node and a publisher token per topic, in rmw_zenoh's format.
    put_tokens = [key for key, alive in tokens if alive]
    node_tokens = [key for key in put_tokens if "/NN/%/%/taxel_bridge" in key]
    checks.check(len(node_tokens) == 1, f"one node token ({node_tokens})")
    service_tokens = [key for key in put_tokens if key.split("/")[5:6] == ["SS"]]
    checks.check(not service_tokens, f"no service server without --allow-commands ({service_tokens[:2]})")
    token_of_key = {}
    for key in by_topic:
        _, topic, ros_type, type_hash = parse_key(key)
        mangled = topic.replace("/", "%")
        dds_type = key.split("/")[-2]
        wanted = f"/MP/%/%/taxel_bridge/{mangled}/{dds_type}/{type_hash}/"
        matching = [token for token in put_tokens if wanted in token]
        checks.check(len(matching) == 1, f"publisher token for {topic}")
        if matching:
            token_of_key[key] = matching[0]
    # rmw_zenoh's GID: XXH3-128 of the token, low 64 bits then high, each little-endian.
    gid_bad = []
    for key, messages in by_topic.items():
        token = token_of_key.get(key)
        expected_gid = xxhash.xxh3_128_intdigest(token.encode()).to_bytes(16, "little") if token else None
        gids = {attachment[17:33] for _, attachment, _ in messages}
        if gids != {expected_gid}:
            gid_bad.append(key)
    checks.check(by_topic and not gid_bad, f"every attachment's GID is XXH3-128 of its publisher's token ({gid_bad[:2]})")

    latencies_ms = []
    for device in range(args.devices):
        for pad, plateau in enumerate(plateaus):
            base = f"0/taxel/device{device}/pad{pad}"
            pressure_key = next((key for key in by_topic if key.startswith(base + "/pressure/")), None)
            wrench_key = next((key for key in by_topic if key.startswith(base + "/wrench/")), None)
            checks.check(pressure_key is not None and wrench_key is not None, f"{base}: pressure and wrench published")
            if pressure_key is None or wrench_key is None:
                continue
            sequences = []
            stamps_ok = True
            steady = 0
            steady_bad = []
            sequence_times = []
            press_times = []
            for payload, attachment, now_ns in by_topic[pressure_key]:
                sequence, stamp_ns, gid_length = struct.unpack_from("<qqB", attachment)
                cloud = TYPESTORE.deserialize_cdr(payload, "sensor_msgs/msg/PointCloud2")
                header_ns = cloud.header.stamp.sec * 1_000_000_000 + cloud.header.stamp.nanosec
                stamps_ok &= header_ns == stamp_ns and stamp_ns <= now_ns and gid_length == 16
                stamps_ok &= cloud.header.frame_id == f"taxel_device{device}_pad{pad}"
                sequences.append(sequence)
                sequence_times.append((sequence, stamp_ns))
                latencies_ms.append((device, pad, sequence, now_ns))
                points = [struct.unpack_from("<ffffI", bytes(cloud.data), 20 * index) for index in range(cloud.width)]
                names = [field.name for field in cloud.fields]
                press_times.append((header_ns, sum(point[3] for point in points) / 1000.0))
                if names != ["x", "y", "z", "pressure", "flags"] or cloud.width != 4:
                    steady_bad.append(f"layout {names} width {cloud.width}")
                    continue
                for index, (x, y, _, _, _) in enumerate(points):
                    if abs(x - TAXEL_CENTRES_M[index][0]) > 1e-7 or abs(y - TAXEL_CENTRES_M[index][1]) > 1e-7:
                        steady_bad.append(f"taxel {index} at ({x}, {y})")
                sequences_per_second = 100.0
                if sequence / sequences_per_second >= STEADY_FROM_S:
                    steady += 1
                    for index, (_, _, _, pressure_pa, flags) in enumerate(points):
                        if abs(pressure_pa / 1000.0 - plateau[index]) > PRESSURE_TOLERANCE_KPA or flags != 0:
                            steady_bad.append(f"seq {sequence} taxel {index}: {pressure_pa / 1000.0:.2f} kPa flags {flags}")
            checks.check(stamps_ok, f"{base}/pressure: header stamp = attachment timestamp <= reception, 16-byte gid, frame id")
            gaps = [b - a for a, b in zip(sequences, sequences[1:]) if b - a != 1]
            checks.check(not gaps and len(sequences) > 100 and sequences[0] == 1,
                         f"{base}/pressure: {len(sequences)} messages, sequences from {sequences[0] if sequences else None} (1, as rmw_zenoh) with no gap {gaps[:5]}")
            checks.check(steady >= 100 and not steady_bad, f"{base}/pressure: {steady} steady messages equal the plateau {plateau} kPa within {PRESSURE_TOLERANCE_KPA} ({steady_bad[:3]})")
            # The sets come at 100 per second of device time: sequence over stamp.
            (first_sequence, first_ns), (last_sequence, last_ns) = sequence_times[0], sequence_times[-1]
            rate = (last_sequence - first_sequence) / ((last_ns - first_ns) / 1e9)
            checks.check(abs(rate - 100.0) < 2.0, f"{base}/pressure: {rate:.2f} sets per second of stamp time")

            expected_force = sum(plateau) * 1000.0 * TAXEL_AREA_M2
            expected_x = sum(p * c[0] for p, c in zip(plateau, TAXEL_CENTRES_M)) / sum(plateau)
            expected_y = sum(p * c[1] for p, c in zip(plateau, TAXEL_CENTRES_M)) / sum(plateau)
            wrench_sequences = []
            wrench_bad = []
            for payload, attachment, _ in by_topic[wrench_key]:
                sequence, _, _ = struct.unpack_from("<qqB", attachment)
                wrench_sequences.append(sequence)
                if sequence / 100.0 < STEADY_FROM_S:
                    continue
                message = TYPESTORE.deserialize_cdr(payload, "geometry_msgs/msg/WrenchStamped")
                force = -message.wrench.force.z
                x = message.wrench.torque.y / force
                y = -message.wrench.torque.x / force
                if abs(force - expected_force) > FORCE_TOLERANCE_N or abs(x - expected_x) > CENTRE_TOLERANCE_M or abs(y - expected_y) > CENTRE_TOLERANCE_M:
                    wrench_bad.append(f"seq {sequence}: {force:.3f} N at ({x * 1e3:.2f}, {y * 1e3:.2f}) mm")
            checks.check(wrench_sequences == sequences, f"{base}/wrench: the same sequence numbers as the pressures")
            checks.check(not wrench_bad, f"{base}/wrench: {expected_force:.3f} N within {FORCE_TOLERANCE_N} N at ({expected_x * 1e3:.2f}, {expected_y * 1e3:.2f}) mm within {CENTRE_TOLERANCE_M * 1e3} mm ({wrench_bad[:3]})")

            started_key = next((key for key in by_topic if key.startswith(base + "/contact_started/")), None)
            events = by_topic.get(started_key, [])
            if events:
                header = TYPESTORE.deserialize_cdr(events[0][0], "std_msgs/msg/Header")
                event_ns = header.stamp.sec * 1_000_000_000 + header.stamp.nanosec
                # The press ramps from 1.5 s to 2.5 s of scene time: contact comes after the first
                # cloud with any pressure and by 0.2 s after the first at the plateau.
                press_ns = next((ns for ns, total in press_times if total > 0.5), None)
                plateau_ns = next((ns for ns, total in press_times if total > 0.95 * sum(plateau)), None)
                checks.check(len(events) == 1 and press_ns is not None and plateau_ns is not None
                             and press_ns - 50_000_000 <= event_ns <= plateau_ns + 200_000_000,
                             f"{base}: one contact_started, {(event_ns - (press_ns or 0)) / 1e9:.2f} s after the press began and {(event_ns - (plateau_ns or 0)) / 1e9:.2f} s from the plateau")
            else:
                checks.check(False, f"{base}: a contact_started event")

    diagnostics_key = next((key for key in by_topic if key.startswith("0/diagnostics/")), None)
    checks.check(diagnostics_key is not None, "diagnostics published")
    if diagnostics_key is not None:
        arrays = [TYPESTORE.deserialize_cdr(payload, "diagnostic_msgs/msg/DiagnosticArray") for payload, _, _ in by_topic[diagnostics_key]]
        last = arrays[-2] if len(arrays) > 1 else arrays[-1]
        names = [status.name for status in last.status]
        checks.check(names == [f"taxel_bridge: device{device}" for device in range(args.devices)], f"one status per device ({names})")
        for status in last.status:
            values = {pair.key: pair.value for pair in status.values}
            checks.check(values.get("sample sets dropped by the bridge (queue full, all devices)") == "0", f"{status.name}: nothing dropped by the bridge ({status.message})")
            checks.check("calibration source" in values and "pad0 temperature source" in values, f"{status.name}: calibration and temperature source reported")

    if args.report:
        with open(args.report, "w") as report:
            json.dump({"received": [[d, p, s, n] for d, p, s, n in latencies_ms], "seconds": args.seconds}, report)

    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
