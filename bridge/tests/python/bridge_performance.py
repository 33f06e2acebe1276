"""Measures the bridge under load and faults and writes bridge/PERFORMANCE.md, in one command:

    cargo build --release -p taxel -p taxel-bridge-cli
    python bridge/tests/python/bridge_performance.py --bin target/release

1. Latency: two simulated devices of eight pads each (separate `taxel sim --pads 8` processes
   playing bridge/tests/python/plateau_one_pad.toml, 16 pads x 100 sample sets per second)
   bridged on loopback to a Python eclipse-zenoh subscriber of every pressure topic. Reports
   frames lost (every frame the bridge took from the devices must reach the subscriber), the
   latency from a frame's arrival at the host (the bridge's --timing-log) to its reception by
   the subscriber (p50, p99, max; both on the host's wall clock), and the bridge process's CPU
   time per pad. The first seconds are left out of the latency: frames wait there for the clock
   mapping's first estimate (docs/BRIDGE.md, Timestamps).
2. Faults: the scenarios of bridge_faults.py (a subscriber that stalls, a Zenoh router that
   restarts, a device unplugged and plugged back), each on the same two devices.

The helpers here (simulators, the subscriber, the timing log) are bridge_faults.py's too.
"""

import argparse
import importlib.metadata
import json
import os
import platform
import signal
import struct
import subprocess
import sys
import tempfile
import textwrap
import threading
import time

import zenoh

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "plateau_one_pad.toml")
PADS_PER_DEVICE = 8
DEVICES = 2
SETS_PER_SECOND = 100.0
WARM_UP_S = 5.0
LATENCY_GOAL_MS = 5.0
PRESSURE_KEYS = "0/taxel/*/*/pressure/**"
DIAGNOSTICS_KEYS = "0/diagnostics/**"
DROPPED_BY_BRIDGE_KEY = "sample sets dropped by the bridge (queue full, all devices)"


def percentile(values, fraction):
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, round(fraction * (len(ordered) - 1))))
    return ordered[index]


class Tools:
    """The programs measured: `taxel` (for `taxel sim`) and `taxel-bridge`."""

    def __init__(self, taxel, bridge):
        self.taxel = taxel
        self.bridge = bridge

    @classmethod
    def in_directory(cls, directory):
        return cls(os.path.join(directory, "taxel"), os.path.join(directory, "taxel-bridge"))


def zenoh_config(listen=(), connect=(), mode=None):
    """A Zenoh configuration on the given endpoints, without multicast scouting."""
    config = zenoh.Config()
    if mode is not None:
        config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    config.insert_json5("scouting/multicast/enabled", "false")
    return config


def start_simulator(tools, directory, name, scene=SCENE, pads=PADS_PER_DEVICE, seed=1):
    """A `taxel sim` process (its own process, so that killing it unplugs the device) -> (process,
    the path of its terminal)."""
    path_file = os.path.join(directory, f"{name}.path")
    process = subprocess.Popen(
        [tools.taxel, "sim", "--scene", scene, "--pads", str(pads), "--seed", str(seed), "--path-file", path_file],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and process.poll() is None:
        if os.path.exists(path_file):
            with open(path_file) as port:
                return process, port.read().strip()
        time.sleep(0.02)
    process.kill()
    process.wait()
    raise RuntimeError(f"taxel sim ({name}) wrote no terminal path")


def stop_processes(processes):
    for process in processes:
        if process.poll() is None:
            process.terminate()
    for process in processes:
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


class Bridge:
    """`taxel-bridge` on `ports` with a --timing-log, until stop(); its stderr goes to a file."""

    def __init__(self, tools, directory, ports, network, extra=()):
        self.timing_path = os.path.join(directory, "timing.csv")
        self.stderr_path = os.path.join(directory, "bridge.stderr")
        self.stderr_file = open(self.stderr_path, "w")
        self.started_ns = time.time_ns()
        self.process = subprocess.Popen(
            [tools.bridge, *ports, *network, "--timing-log", self.timing_path, *extra],
            stdout=subprocess.DEVNULL, stderr=self.stderr_file)
        self.usage = None
        self.stopping_ns = None

    def running(self):
        return self.process.poll() is None

    def stop(self, timeout_s=30.0):
        """Ctrl-C, as a user stops it; -> its exit code. Its CPU time is then in `usage`."""
        self.stopping_ns = time.time_ns()
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            pid, status, usage = os.wait4(self.process.pid, os.WNOHANG)
            if pid:
                self.process.returncode = os.waitstatus_to_exitcode(status)
                self.usage = usage
                break
            time.sleep(0.05)
        else:
            self.process.kill()
            _, status, self.usage = os.wait4(self.process.pid, 0)
            self.process.returncode = os.waitstatus_to_exitcode(status)
        self.stderr_file.close()
        return self.process.returncode

    def stderr(self):
        with open(self.stderr_path) as stderr:
            return stderr.read()

    def cpu_s(self):
        return self.usage.ru_utime + self.usage.ru_stime

    def timing_log(self):
        """One row per sample frame published: (device, pad, device's sequence, arrival ns,
        publication ns), in publication order."""
        rows = []
        with open(self.timing_path) as timing:
            for line in timing:
                rows.append(tuple(int(value) for value in line.split(",")))
        return rows


def publication_keys(rows):
    """Each timing-log row under the key a subscriber sees: (device, pad, the publisher's
    sequence number), numbered as the bridge numbers them (docs/BRIDGE.md, Sequence numbers):
    1 for a pad's first frame, then the device's step modulo 2^32 added, a step of 0 or
    backwards (2^31 or more) counting 1. -> {key: row}."""
    last = {}
    keyed = {}
    for row in rows:
        device, pad, sequence = row[:3]
        previous = last.get((device, pad))
        if previous is None:
            published = 1
        else:
            step = (sequence - previous[0]) % (1 << 32)
            published = previous[1] + (1 if step == 0 or step >= (1 << 31) else step)
        last[(device, pad)] = (sequence, published)
        keyed[(device, pad, published)] = row
    return keyed


class Reception:
    """A Python eclipse-zenoh subscriber of every pad's pressure topic and of /diagnostics:
    each pressure message as (device, pad, publisher's sequence, stamp ns, reception ns), from
    its key expression and its attachment (whose timestamp is the header's stamp), and each
    diagnostic array's payload with its reception. `on_pressure(now_ns)`, if given, is called
    in the callback after each pressure message."""

    def __init__(self, session, on_pressure=None):
        self.lock = threading.Lock()
        self.pressure = []
        self.diagnostics = []
        self.on_pressure = on_pressure
        self.subscribers = [
            session.declare_subscriber(PRESSURE_KEYS, self._pressure),
            session.declare_subscriber(DIAGNOSTICS_KEYS, self._diagnostics),
        ]

    def _pressure(self, sample):
        now_ns = time.time_ns()
        sequence, stamp_ns = struct.unpack_from("<qq", sample.attachment.to_bytes())
        chunks = str(sample.key_expr).split("/")
        device, pad = int(chunks[2][len("device"):]), int(chunks[3][len("pad"):])
        with self.lock:
            self.pressure.append((device, pad, sequence, stamp_ns, now_ns))
        if self.on_pressure is not None:
            self.on_pressure(now_ns)

    def _diagnostics(self, sample):
        now_ns = time.time_ns()
        with self.lock:
            self.diagnostics.append((now_ns, sample.payload.to_bytes()))

    def close(self):
        for subscriber in self.subscribers:
            subscriber.undeclare()

    def received(self):
        """{(device, pad, sequence): (stamp ns, reception ns)} of the pressure messages."""
        with self.lock:
            return {(d, p, s): (stamp, now) for d, p, s, stamp, now in self.pressure}

    def statuses(self):
        """Every status of the diagnostic arrays, in order: (reception ns, device, level,
        message, {key: value}); decoded by rosbags."""
        from rosbags.typesys import Stores, get_typestore
        typestore = get_typestore(Stores.ROS2_JAZZY)
        with self.lock:
            arrays = list(self.diagnostics)
        statuses = []
        for now_ns, payload in arrays:
            array = typestore.deserialize_cdr(payload, "diagnostic_msgs/msg/DiagnosticArray")
            for status in array.status:
                device = int(status.name.rsplit("device", 1)[1])
                values = {pair.key: pair.value for pair in status.values}
                statuses.append((now_ns, device, status.level, status.message, values))
        return statuses


def stamp_faults(received, keyed):
    """What is wrong with the stamps received: (how many stamps are after their frame's host
    arrival (timing log), after their reception, or not after the pad's previous stamp; how
    many received messages are not in the timing log)."""
    late_arrival = late_reception = not_increasing = unknown = 0
    previous = {}
    for key in sorted(received):
        stamp_ns, now_ns = received[key]
        row = keyed.get(key)
        if row is None:
            unknown += 1
        elif stamp_ns > row[3]:
            late_arrival += 1
        if stamp_ns > now_ns:
            late_reception += 1
        pad = key[:2]
        if pad in previous and stamp_ns <= previous[pad]:
            not_increasing += 1
        previous[pad] = stamp_ns
    return late_arrival, late_reception, not_increasing, unknown


def host_words(load_before):
    return (f"Host: {platform.machine()}, {os.cpu_count()} cores shared with the simulators and the "
            f"subscriber, Python {platform.python_version()}, eclipse-zenoh "
            f"{importlib.metadata.version('eclipse-zenoh')}; load average {load_before:.1f} when it started")


def measure_latency(tools, seconds, port):
    """The latency table's figures: 16 pads streamed for `seconds` to a subscriber."""
    with tempfile.TemporaryDirectory() as directory:
        simulators, ports = [], []
        try:
            for device in range(DEVICES):
                process, path = start_simulator(tools, directory, f"device{device}", seed=device + 1)
                simulators.append(process)
                ports.append(path)
            session = zenoh.open(zenoh_config(listen=[f"tcp/127.0.0.1:{port}"]))
            reception = Reception(session)
            bridge = Bridge(tools, directory, ports,
                            ["--connect", f"tcp/127.0.0.1:{port}", "--listen", "tcp/127.0.0.1:0"])
            time.sleep(seconds)
            bridge.stop()
        finally:
            stop_processes(simulators)
        time.sleep(0.5)
        reception.close()
        session.close()
        if bridge.process.returncode != 0:
            raise RuntimeError(f"the bridge failed: {bridge.stderr()}")
        rows = bridge.timing_log()
    keyed = publication_keys(rows)
    received = reception.received()
    first_arrival_ns = min(row[3] for row in rows)
    lost = [key for key in keyed if key not in received]
    latencies_ms = [(received[key][1] - row[3]) / 1e6 for key, row in keyed.items()
                    if key in received and row[3] - first_arrival_ns >= WARM_UP_S * 1e9]
    pads = len({row[:2] for row in rows})
    duration_s = (max(row[3] for row in rows) - first_arrival_ns) / 1e9
    gaps = 0
    for pad in {row[:2] for row in rows}:
        sequences = sorted(row[2] for row in rows if row[:2] == pad)
        gaps += sum(b - a - 1 for a, b in zip(sequences, sequences[1:]))
    late_arrival, late_reception, not_increasing, _ = stamp_faults(received, keyed)
    cpu_s = bridge.cpu_s()
    return {
        "pads": pads,
        "rate": len(rows) / duration_s / pads,
        "frames": len(rows),
        "gaps": gaps,
        "lost": len(lost),
        "p50": percentile(latencies_ms, 0.5),
        "p99": percentile(latencies_ms, 0.99),
        "max": max(latencies_ms),
        "measured": len(latencies_ms),
        "stamps_wrong": late_arrival + late_reception + not_increasing,
        "cpu_s": cpu_s,
        "seconds": seconds,
        "cpu_percent_per_pad": 100.0 * cpu_s / seconds / pads,
    }


def latency_table(figures):
    met = lambda condition: "met" if condition else "**missed**"
    return f"""| measure | value | goal |
|---|---|---|
| pads | {figures['pads']} | 16 |
| sample sets per second per pad (host arrivals) | {figures['rate']:.1f} | 100 |
| frames taken from the devices | {figures['frames']} | |
| sequence gaps in what the devices sent | {figures['gaps']} | |
| frames lost between the bridge and the subscriber | {figures['lost']} | 0: {met(figures['lost'] == 0)} |
| latency, frame arrival at the host to reception by the subscriber, p50 | {figures['p50']:.2f} ms | |
| latency p99 | {figures['p99']:.2f} ms | ≤ {LATENCY_GOAL_MS:.0f} ms: {met(figures['p99'] <= LATENCY_GOAL_MS)} |
| latency max | {figures['max']:.2f} ms | |
| latency frames measured (after the first {WARM_UP_S:.0f} s) | {figures['measured']} | |
| stamps after their frame's arrival or reception, or not increasing | {figures['stamps_wrong']} | 0: {met(figures['stamps_wrong'] == 0)} |
| bridge CPU time (user + system) | {figures['cpu_s']:.2f} s in {figures['seconds']:.0f} s | |
| bridge CPU per pad | {figures['cpu_percent_per_pad']:.2f} % of one core | |
"""


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bin", required=True, help="directory with taxel and taxel-bridge")
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--port", type=int, default=17449)
    parser.add_argument("--output", default=os.path.join(HERE, "..", "..", "PERFORMANCE.md"))
    args = parser.parse_args()
    # Imported here (it imports this module's helpers); no __pycache__ left in the source tree.
    sys.dont_write_bytecode = True
    import bridge_faults

    tools = Tools.in_directory(args.bin)
    load_before = os.getloadavg()[0]
    latency = measure_latency(tools, args.seconds, args.port)
    print(latency_table(latency))
    faults = bridge_faults.run_scenarios(tools, args.port + 1, bridge_faults.FULL)

    setup = textwrap.fill(
        "Two simulated devices of eight pads each (`taxel sim --pads 8 --scene "
        "bridge/tests/python/plateau_one_pad.toml`, separate processes, 100 sample sets per second), "
        "bridged by `taxel-bridge` (release build) to a Python eclipse-zenoh subscriber of every pressure "
        f"topic and of `/diagnostics`, on loopback TCP. {host_words(load_before)}.", 100, break_on_hyphens=False)
    text = f"""# taxel-bridge performance

Generated by `python bridge/tests/python/bridge_performance.py --bin target/release` (after
`cargo build --release -p taxel -p taxel-bridge-cli`); do not edit by hand. The scenarios are
bridge/tests/python/bridge_performance.py (latency) and bridge/tests/python/bridge_faults.py
(faults); each docstring says what is measured and how.

{setup}

## Latency: 16 pads for {args.seconds:.0f} s

{latency_table(latency)}
Each frame is published twice (pressure cloud and wrench); the subscriber counts the pressure
messages. The latency includes the bridge's stamping, CDR encoding and Zenoh, the loopback
network and the Python subscriber's callback. CPU per pad is the bridge process's CPU time over
the run divided by its length and the pads.

## Faults

{bridge_faults.faults_markdown(faults)}"""
    # Written under a temporary name and renamed, so a failed run never leaves half a file.
    temporary = args.output + ".tmp"
    with open(temporary, "w") as output:
        output.write(text)
    os.replace(temporary, args.output)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
