"""Measures the bridge and writes bridge/PERFORMANCE.md: two simulated devices of four pads each
(separate `taxel sim` processes, 8 pads x 100 sample sets per second) bridged on loopback to a
Python eclipse-zenoh subscriber. Reports frames lost (every frame the bridge took from the
devices must reach the subscriber), the latency from a frame's arrival at the host (the bridge's
--timing-log) to its reception by the subscriber (p50, p99, max; both on the host's wall clock),
and the bridge process's CPU time per pad.

    cargo build --release -p taxel -p taxel-bridge-cli
    python bridge/tests/python/bridge_performance.py --bin target/release

The first seconds are left out of the latency: frames wait there for the clock mapping's first
estimate (docs/BRIDGE.md, Timestamps).
"""

import argparse
import importlib.metadata
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import zenoh

WARM_UP_S = 5.0


def percentile(values, fraction):
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, round(fraction * (len(ordered) - 1))))
    return ordered[index]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bin", required=True, help="directory with taxel and taxel-bridge")
    parser.add_argument("--scene", default=os.path.join(os.path.dirname(__file__), "plateau.toml"))
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--port", type=int, default=17449)
    parser.add_argument("--output", default=os.path.join(os.path.dirname(__file__), "..", "..", "PERFORMANCE.md"))
    args = parser.parse_args()

    load_before = os.getloadavg()[0]
    received = {}
    lock = threading.Lock()

    def on_pressure(sample):
        now_ns = time.time_ns()
        sequence = int.from_bytes(sample.attachment.to_bytes()[:8], "little", signed=True)
        chunks = str(sample.key_expr).split("/")
        device, pad = int(chunks[2][len("device"):]), int(chunks[3][len("pad"):])
        with lock:
            received[(device, pad, sequence)] = now_ns

    config = zenoh.Config()
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{args.port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(config)
    subscriber = session.declare_subscriber("0/taxel/*/*/pressure/**", on_pressure)

    with tempfile.TemporaryDirectory() as directory:
        simulators, ports = [], []
        for device in range(2):
            path_file = os.path.join(directory, f"port{device}")
            simulators.append(subprocess.Popen(
                [os.path.join(args.bin, "taxel"), "sim", "--scene", args.scene, "--seed", str(device + 1),
                 "--path-file", path_file], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
            for _ in range(200):
                if os.path.exists(path_file):
                    break
                time.sleep(0.05)
            with open(path_file) as port:
                ports.append(port.read().strip())
        timing_path = os.path.join(directory, "timing.csv")
        bridge = subprocess.Popen(
            [os.path.join(args.bin, "taxel-bridge"), *ports, "--connect", f"tcp/127.0.0.1:{args.port}", "--listen", "tcp/127.0.0.1:0",
             "--duration", str(args.seconds), "--timing-log", timing_path],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        _, status, usage = os.wait4(bridge.pid, 0)
        bridge.returncode = os.waitstatus_to_exitcode(status)
        stderr = bridge.stderr.read()
        for simulator in simulators:
            simulator.terminate()
            simulator.wait()
        time.sleep(0.5)
        subscriber.undeclare()
        session.close()
        if bridge.returncode != 0:
            print(stderr)
            return 1
        published = []
        with open(timing_path) as timing:
            for line in timing:
                device, pad, sequence, arrival_ns, published_ns = (int(value) for value in line.split(","))
                published.append((device, pad, sequence, arrival_ns, published_ns))

    # The timing log has the device's sequence numbers; the attachment the publisher's, which
    # count from 1 at the pad's first frame published and step as the device's do.
    first_sequence = {}
    for device, pad, sequence, _, _ in published:
        first_sequence.setdefault((device, pad), sequence)

    def received_key(device, pad, sequence):
        return (device, pad, sequence - first_sequence[(device, pad)] + 1)

    first_arrival_ns = min(row[3] for row in published)
    lost = [row for row in published if received_key(*row[:3]) not in received]
    latencies_ms = [
        (received[received_key(device, pad, sequence)] - arrival_ns) / 1e6
        for device, pad, sequence, arrival_ns, _ in published
        if received_key(device, pad, sequence) in received and arrival_ns - first_arrival_ns >= WARM_UP_S * 1e9
    ]
    pads = len({(row[0], row[1]) for row in published})
    duration_s = (max(row[3] for row in published) - first_arrival_ns) / 1e9
    rate = len(published) / duration_s / pads
    cpu_s = usage.ru_utime + usage.ru_stime
    cpu_percent_per_pad = 100.0 * cpu_s / args.seconds / pads
    gaps = 0
    for device, pad in {(row[0], row[1]) for row in published}:
        sequences = sorted(row[2] for row in published if (row[0], row[1]) == (device, pad))
        gaps += sum(b - a - 1 for a, b in zip(sequences, sequences[1:]))

    text = f"""# taxel-bridge performance

Generated by `python bridge/tests/python/bridge_performance.py --bin target/release` (after
`cargo build --release -p taxel -p taxel-bridge-cli`); do not edit by hand.

Two simulated devices of four pads each (`taxel sim --scene bridge/tests/python/plateau.toml`,
separate processes), bridged by `taxel-bridge` (release build) to a Python eclipse-zenoh
subscriber of every pressure topic, on loopback TCP, for {args.seconds:.0f} s. Host: {platform.machine()},
{os.cpu_count()} cores shared with the simulators and the subscriber, Python {platform.python_version()},
eclipse-zenoh {importlib.metadata.version("eclipse-zenoh")}; load average {load_before:.1f} when it started.

| measure | value |
|---|---|
| pads | {pads} |
| sample sets per second per pad (host arrivals) | {rate:.1f} |
| frames taken from the devices | {len(published)} |
| sequence gaps in what the devices sent | {gaps} |
| frames lost between the bridge and the subscriber | {len(lost)} |
| latency, frame arrival at the host to reception by the subscriber, p50 | {percentile(latencies_ms, 0.5):.2f} ms |
| latency p99 (goal 5 ms) | {percentile(latencies_ms, 0.99):.2f} ms |
| latency max | {max(latencies_ms):.2f} ms |
| latency frames measured (after the first {WARM_UP_S:.0f} s) | {len(latencies_ms)} |
| bridge CPU time (user + system) | {cpu_s:.2f} s in {args.seconds:.0f} s |
| bridge CPU per pad | {cpu_percent_per_pad:.2f} % of one core |

Each frame is published twice (pressure cloud and wrench); the subscriber counts the pressure
messages. The latency includes the bridge's stamping, CDR encoding and Zenoh, the loopback
network and the Python subscriber's callback.
"""
    # Written under a temporary name and renamed, so a failed run never leaves half a file.
    temporary = args.output + ".tmp"
    with open(temporary, "w") as output:
        output.write(text)
    os.replace(temporary, args.output)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
