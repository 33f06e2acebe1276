"""The bridge under faults: what it does when a subscriber stalls, when the Zenoh router it goes
through restarts, and when a device is unplugged and plugged back. Each scenario runs two
simulated devices (separate `taxel sim --pads N` processes playing
bridge/tests/python/plateau_one_pad.toml, 100 sample sets per second), `taxel-bridge` with
--timing-log (one line per frame published: device, pad, the device's sequence, host arrival,
publication) and a Python eclipse-zenoh subscriber of every pressure topic and of /diagnostics
(bridge_performance.py's helpers). Every scenario also checks every stamp received: not after
its frame's host arrival (timing log), not after its reception, increasing per pad.

- stalled subscriber: the subscriber (listening on loopback; the bridge connects to it) blocks in
  its callback once, for 5 s. Measured: the devices' own counters of frames not sent and the
  longest gap between a device's sample-set arrivals at the bridge (the device readers never
  block), how long publishing paused, the sample sets the bridge dropped (its health, read from
  /diagnostics) against the sets missing from the timing log, the frames published but never
  received, and the time from the end of the stall until the subscriber receives live again
  (a message within 5 ms of its arrival at the host) with the rate in the second after.
- router restart: a Zenoh router (an eclipse-zenoh session in mode "router", a process of this
  script, `--serve-router ENDPOINT`) on loopback; the bridge connects to it only (`--connect
  ENDPOINT --no-listen`), the subscriber too (mode "client"). The router is killed (SIGKILL) and
  started again 3 s later. Measured: the time from its restart until messages flow again, the
  frames lost (published but not received, and the sequence gaps the subscriber sees), the
  bridge still running.
- unplug and replug: device 0 is given to the bridge as a symbolic link to its `taxel sim`
  terminal, as a udev name would be. That process is killed (unplug), a new one started 2 s
  later and the link repointed to its terminal (replug). Measured: the time from the replug until
  the bridge reads the device and until the subscriber receives it again, device 0's status
  during the outage (ERROR, "looking for it again") and after (`reconnections` 1), no stamp of
  the new connection earlier than the new process's start, the publishers' sequence numbers
  going on, device 1 published throughout without a loss.

All of them, with the latency table, into bridge/PERFORMANCE.md (the one command):

    cargo build --release -p taxel -p taxel-bridge-cli
    python bridge/tests/python/bridge_performance.py --bin target/release

Alone, printing one line per expectation and "N passed, M failed" (exit 1 on a failure):

    python bridge/tests/python/bridge_faults.py --bin target/release [--scenario stall|router|replug]

`--quick` is the short form (two pads per device, a few seconds of streaming; the shorter stall
and outages are then 2 s): bridge-cli/tests/python_clients.rs runs `--scenario replug --quick`
against the debug build.
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from dataclasses import dataclass

import zenoh

# The helpers are imported from beside this script; no __pycache__ is left in the source tree.
sys.dont_write_bytecode = True
from bridge_performance import (DEVICES, DROPPED_BY_BRIDGE_KEY, LATENCY_GOAL_MS, SETS_PER_SECOND, Bridge,
                                Reception, Tools, publication_keys, stamp_faults, start_simulator,
                                stop_processes, zenoh_config)

# A device reader that never waits for the publishing loop takes a set every 10 ms; a gap this
# long between two of a device's arrivals would be a reader held up (the stall lasts seconds).
READER_GAP_LIMIT_S = 0.5
# A stall past Zenoh's wait_before_close (5 s) once the socket buffers are full.
LONG_STALL_S = 20.0
# How long the replugged device may take to be published again before the scenario gives up.
RESUME_LIMIT_S = 15.0


@dataclass
class Settings:
    """How long each phase lasts, and how many pads each device has."""
    pads: int
    before_s: float
    stall_s: float
    router_down_s: float
    unplugged_s: float
    after_s: float


FULL = Settings(pads=8, before_s=8.0, stall_s=5.0, router_down_s=3.0, unplugged_s=2.0, after_s=8.0)
QUICK = Settings(pads=2, before_s=4.0, stall_s=2.0, router_down_s=2.0, unplugged_s=2.0, after_s=2.0)


class Findings:
    """One scenario's measures, and whether each expectation held (said on stdout as it goes)."""

    def __init__(self, title, description):
        self.title = title
        self.description = description
        self.rows = []

    def measure(self, what, value):
        self.rows.append((what, value, "", None))
        print(f"   {self.title}: {what}: {value}")

    def expect(self, what, value, expected, held):
        self.rows.append((what, value, expected, bool(held)))
        print(f"{'ok' if held else 'FAILED'}: {self.title}: {what}: {value} (expected {expected})")

    def failures(self):
        return sum(1 for row in self.rows if row[3] is False)

    def passes(self):
        return sum(1 for row in self.rows if row[3] is True)


def seconds(ns):
    return f"{ns / 1e9:.2f} s"


def longest_gap_s(times_ns, start_ns, end_ns):
    """The longest time without any of `times_ns` in [start_ns, end_ns], s."""
    inside = sorted(t for t in times_ns if start_ns <= t <= end_ns)
    edges = [start_ns, *inside, end_ns]
    return max(b - a for a, b in zip(edges, edges[1:])) / 1e9


def final_statuses(reception, before_ns=None):
    """Each device's last status (received before `before_ns`, if given): {device: (level,
    message, values)}."""
    last = {}
    for now, device, level, message, values in reception.statuses():
        if before_ns is None or now < before_ns:
            last[device] = (level, message, values)
    return last


def first_statuses(reception):
    """Each device's first status: {device: (level, message, values)}."""
    first = {}
    for _, device, level, message, values in reception.statuses():
        first.setdefault(device, (level, message, values))
    return first


def check_stamps(findings, received, keyed):
    late_arrival, late_reception, not_increasing, unknown = stamp_faults(received, keyed)
    findings.expect("stamps after their frame's host arrival / after reception / not increasing per pad",
                    f"{late_arrival} / {late_reception} / {not_increasing} of {len(received)}", "0 / 0 / 0",
                    late_arrival == late_reception == not_increasing == 0)
    findings.expect("messages received that the timing log does not have", unknown, "0", unknown == 0)


def check_bridge(findings, running, code):
    findings.expect("bridge still running at the end, then stopped by Ctrl-C", f"{'yes' if running else 'no'}, exit {code}",
                    "yes, exit 0", running and code == 0)


def start_devices(tools, directory, settings, link=None):
    """Both devices' simulators -> (processes, ports); with `link`, device 0's port is a
    symbolic link at that path to its terminal."""
    simulators, ports = [], []
    try:
        for device in range(DEVICES):
            process, path = start_simulator(tools, directory, f"device{device}", pads=settings.pads, seed=device + 1)
            simulators.append(process)
            if device == 0 and link is not None:
                os.symlink(path, link)
                path = link
            ports.append(path)
    except BaseException:
        stop_processes(simulators)
        raise
    return simulators, ports


def stalled_subscriber(tools, directory, port, settings, stall_s=None, title="stalled subscriber"):
    stall_s = settings.stall_s if stall_s is None else stall_s
    findings = Findings(
        title,
        f"The subscriber listens on loopback and the bridge connects to it; {settings.before_s:.0f} s after the "
        f"bridge started, the subscriber's callback blocks for {stall_s:.0f} s, once (Zenoh then reads nothing "
        f"more from the bridge's link); the bridge runs {settings.after_s:.0f} s more. A simulated device streams "
        "from its start and counts the frames it could not send before the bridge opened its port: what is "
        "checked is that its counters do not grow after." + (
            " Zenoh's wait_before_close is 5 s: a publisher blocked that long closes the link, and what its "
            "queues held is lost, as is what is published until the link is back; Zenoh does not tell the "
            "publisher, so the bridge's health cannot count it."
            if stall_s > 5.0 else ""))
    endpoint = f"tcp/127.0.0.1:{port}"
    stall = {}
    stall_lock = threading.Lock()
    stall_from = []

    def on_pressure(now_ns):
        with stall_lock:
            if stall or not stall_from or now_ns < stall_from[0]:
                return
            stall["start_ns"] = now_ns
        time.sleep(stall_s)
        stall["end_ns"] = time.time_ns()

    simulators, ports = start_devices(tools, directory, settings)
    session = None
    try:
        session = zenoh.open(zenoh_config(listen=[endpoint]))
        reception = Reception(session, on_pressure)
        bridge = Bridge(tools, directory, ports, ["--connect", endpoint, "--listen", "tcp/127.0.0.1:0"])
        stall_from.append(bridge.started_ns + int(settings.before_s * 1e9))
        time.sleep(settings.before_s + stall_s + settings.after_s)
        running = bridge.running()
        code = bridge.stop()
    finally:
        stop_processes(simulators)
    time.sleep(0.5)
    reception.close()
    session.close()
    check_bridge(findings, running, code)
    if code != 0 or "end_ns" not in stall:
        findings.expect("the subscriber stalled", "no", "yes", False)
        return findings
    rows = bridge.timing_log()
    keyed = publication_keys(rows)
    received = reception.received()
    statuses = final_statuses(reception, bridge.stopping_ns)
    firsts = first_statuses(reception)

    # A simulated device streams from its start, so it counts the frames it could not send
    # before the bridge opened its port: what matters is that they do not grow after.
    counter_keys = ("device: frames not sent", "device: sample frames not sent (one per pad per set)",
                    "sample sets dropped by the device", "frames lost on the link")
    for device in range(DEVICES):
        first = firsts.get(device, (None, "", {}))[2]
        last = statuses.get(device, (None, "", {}))[2]
        pairs = [(first.get(key, "not reported"), last.get(key, "not reported")) for key in counter_keys]
        findings.expect(f"device {device}: frames not sent / sample frames not sent / sets dropped by the device / "
                        "lost on the link, at the bridge's first status → its last",
                        " / ".join(f"{a} → {b}" for a, b in pairs), "no change (the device never waited)",
                        all(a == b and a != "not reported" for a, b in pairs))
    first_arrival_ns = min(row[3] for row in rows)
    for device in range(DEVICES):
        arrivals = {row[3] for row in rows if row[0] == device}
        gap_s = longest_gap_s(arrivals, first_arrival_ns, max(arrivals))
        findings.expect(f"device {device}: longest gap between its sample sets' arrivals at the bridge",
                        f"{gap_s * 1e3:.0f} ms", f"< {READER_GAP_LIMIT_S * 1e3:.0f} ms (readers never blocked)",
                        gap_s < READER_GAP_LIMIT_S)
    publications = [row[4] for row in rows]
    findings.measure("longest pause of the bridge's publishing (timing log)",
                     seconds(max(b - a for a, b in zip(publications, publications[1:]))))
    # The count of the whole run: the health the bridge publishes as it ends.
    ending = final_statuses(reception)
    dropped = {values.get(DROPPED_BY_BRIDGE_KEY) for _, _, values in ending.values()}
    missing_sets = 0
    for device in range(DEVICES):
        sequences = sorted({row[2] for row in rows if row[0] == device})
        missing_sets += sum(b - a - 1 for a, b in zip(sequences, sequences[1:]))
    counted = dropped == {str(missing_sets)}
    findings.expect("sample sets dropped by the bridge (/diagnostics) against the sets missing from the timing log",
                    f"{', '.join(sorted(str(value) for value in {values.get(DROPPED_BY_BRIDGE_KEY) for _, _, values in ending.values()}))} "
                    f"against {missing_sets}", "equal (every drop counted)", counted)
    levels = {(status[0], status[1]) for status in statuses.values()}
    findings.measure("last status of each device", "; ".join(f"level {level}: {message}" for level, message in sorted(levels)))
    lost = [key for key in keyed if key not in received]
    findings.expect("frames published but not received", len(lost), "0", not lost)
    end_ns = stall["end_ns"]
    live = sorted(now for key, (_, now) in received.items()
                  if now >= end_ns and key in keyed and now - keyed[key][3] <= LATENCY_GOAL_MS * 1e6)
    latencies_ms = [(now - keyed[key][3]) / 1e6 for key, (_, now) in received.items() if key in keyed]
    findings.measure("latency max (the backlog)", f"{max(latencies_ms):.0f} ms")
    if live:
        in_second = sum(1 for _, now in received.values() if live[0] <= now < live[0] + 1e9)
        full_rate = DEVICES * settings.pads * SETS_PER_SECOND
        findings.expect("from the end of the stall until the subscriber receives live again (within "
                        f"{LATENCY_GOAL_MS:.0f} ms of arrival); messages in the second after",
                        f"{seconds(live[0] - end_ns)}; {in_second} (full rate {full_rate:.0f})",
                        "live again, ≥ 90 % of the full rate", in_second >= 0.9 * full_rate)
    else:
        findings.expect("the subscriber receives live again after the stall", "never", "yes", False)
    check_stamps(findings, received, keyed)
    return findings


def start_router(endpoint):
    """A Zenoh router on `endpoint` (a process running this script with --serve-router), ready."""
    process = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--serve-router", endpoint],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = process.stdout.readline()
    if line.strip() != "ready":
        process.kill()
        process.wait()
        raise RuntimeError(f"the router on {endpoint} did not start ({line!r})")
    return process


def serve_router(endpoint):
    session = zenoh.open(zenoh_config(listen=[endpoint], mode="router"))
    print("ready", flush=True)
    try:
        while True:
            time.sleep(1.0)
    finally:
        session.close()


def router_restart(tools, directory, port, settings):
    findings = Findings(
        "router restart",
        f"A Zenoh router on loopback; the bridge connects to it only (`--connect tcp/127.0.0.1:PORT --no-listen`), "
        f"the subscriber too (mode client). {settings.before_s:.0f} s after the bridge started the router is "
        f"killed (SIGKILL), and started again {settings.router_down_s:.0f} s later; the bridge runs "
        f"{settings.after_s:.0f} s more.")
    endpoint = f"tcp/127.0.0.1:{port}"
    routers = [start_router(endpoint)]
    simulators, ports = [], []
    session = None
    try:
        simulators, ports = start_devices(tools, directory, settings)
        session = zenoh.open(zenoh_config(connect=[endpoint], mode="client"))
        reception = Reception(session)
        bridge = Bridge(tools, directory, ports, ["--connect", endpoint, "--no-listen"])
        time.sleep(settings.before_s)
        routers[0].kill()
        killed_ns = time.time_ns()
        routers[0].wait()
        time.sleep(settings.router_down_s)
        routers.append(start_router(endpoint))
        restarted_ns = time.time_ns()
        time.sleep(settings.after_s)
        running = bridge.running()
        code = bridge.stop()
    finally:
        stop_processes(simulators)
        stop_processes(routers)
    time.sleep(0.5)
    reception.close()
    session.close()
    check_bridge(findings, running, code)
    if code != 0:
        return findings
    rows = bridge.timing_log()
    keyed = publication_keys(rows)
    received = reception.received()
    after = sorted(now for _, now in received.values() if now >= restarted_ns)
    if after:
        resumed_ns = after[0]
        findings.expect("from the router's restart until messages flow again", seconds(resumed_ns - restarted_ns),
                        "they flow again", True)
        in_second = sum(1 for now in after if resumed_ns + 1e9 <= now < resumed_ns + 2e9)
        full_rate = DEVICES * settings.pads * SETS_PER_SECOND
        findings.expect("messages in the second after the first second of flowing again", f"{in_second} (full rate {full_rate:.0f})",
                        "≥ 90 % of the full rate", in_second >= 0.9 * full_rate)
    else:
        resumed_ns = None
        findings.expect("messages flow again after the router's restart", "never", "yes", False)
    lost = [key for key in keyed if key not in received]
    # The window opens after the last frame received before the kill: the frames published after
    # it were in flight through the router when it died, or published while it was away.
    window_start = max(keyed[key][4] for key, (_, now) in received.items() if now < killed_ns and key in keyed)
    window_end = resumed_ns if resumed_ns is not None else float("inf")
    inside = {key for key in lost if window_start < keyed[key][4] <= window_end}
    outside = [key for key in lost if key not in inside]
    in_flight = sum(1 for key in inside if keyed[key][4] < killed_ns)
    findings.measure("frames lost with the router (published after the last one received before its kill, up to "
                     "the first received after its restart)",
                     f"{len(inside)} ({len(inside) / (DEVICES * settings.pads):.0f} per pad; {in_flight} of them "
                     "published before the kill)")
    findings.expect("frames lost outside that window", len(outside), "0", not outside)
    sequence_gaps = 0
    for pad in {key[:2] for key in received}:
        sequences = sorted(key[2] for key in received if key[:2] == pad)
        sequence_gaps += sum(b - a - 1 for a, b in zip(sequences, sequences[1:]))
    findings.expect("sequence gaps the subscriber sees, all pads", sequence_gaps, "= the frames lost",
                    sequence_gaps == len(lost))
    statuses = final_statuses(reception, bridge.stopping_ns)
    dropped = sorted({values.get(DROPPED_BY_BRIDGE_KEY, "not reported") for _, _, values in statuses.values()})
    findings.expect("sample sets dropped by the bridge (/diagnostics)", ", ".join(dropped), "0", dropped == ["0"])
    check_stamps(findings, received, keyed)
    return findings


def unplug_and_replug(tools, directory, port, settings):
    findings = Findings(
        "unplug and replug",
        f"Device 0 is given to the bridge as a symbolic link to its `taxel sim` terminal. {settings.before_s:.0f} s "
        f"after the bridge started, that process is killed (SIGKILL: unplugged); {settings.unplugged_s:.0f} s later a "
        f"new one is started and the link repointed to its terminal (plugged back); the bridge runs "
        f"{settings.after_s:.0f} s after device 0 is received again. Device 1 streams throughout.")
    endpoint = f"tcp/127.0.0.1:{port}"
    link = os.path.join(directory, "device0")
    simulators, ports = start_devices(tools, directory, settings, link=link)
    session = None
    resumed_ns = None
    try:
        session = zenoh.open(zenoh_config(listen=[endpoint]))
        reception = Reception(session)
        bridge = Bridge(tools, directory, ports, ["--connect", endpoint, "--listen", "tcp/127.0.0.1:0"])
        time.sleep(settings.before_s)
        simulators[0].kill()
        unplugged_ns = time.time_ns()
        simulators[0].wait()
        time.sleep(settings.unplugged_s)
        spawned_ns = time.time_ns()
        process, path = start_simulator(tools, directory, "device0-again", pads=settings.pads, seed=1)
        simulators.append(process)
        os.symlink(path, link + ".new")
        os.replace(link + ".new", link)
        replugged_ns = time.time_ns()
        deadline = time.monotonic() + RESUME_LIMIT_S
        while resumed_ns is None and time.monotonic() < deadline:
            with reception.lock:
                resumed_ns = next((now for device, _, _, _, now in reception.pressure
                                   if device == 0 and now > replugged_ns), None)
            time.sleep(0.05)
        time.sleep(settings.after_s)
        running = bridge.running()
        code = bridge.stop()
    finally:
        stop_processes(simulators)
    time.sleep(0.5)
    reception.close()
    session.close()
    check_bridge(findings, running, code)
    if code != 0:
        return findings
    rows = bridge.timing_log()
    keyed = publication_keys(rows)
    received = reception.received()
    # The new connection's frames: the old one's last frames may still be read from the terminal
    # after the kill; the new device cannot send before its process starts.
    new_rows = [row for row in rows if row[0] == 0 and row[3] >= spawned_ns]
    if resumed_ns is not None and new_rows:
        findings.measure("from the replug until the bridge reads device 0 again (its first sample set's arrival)",
                         seconds(min(row[3] for row in new_rows) - replugged_ns))
        findings.expect("from the replug until the subscriber receives device 0 again", seconds(resumed_ns - replugged_ns),
                        f"publishing resumes by itself (within {RESUME_LIMIT_S:.0f} s)", True)
    else:
        findings.expect("publishing of device 0 resumes after the replug", "never", "yes", False)
    statuses = reception.statuses()
    outage = [(level, message) for now, device, level, message, _ in statuses
              if device == 0 and unplugged_ns < now <= (resumed_ns or now)]
    looking = [message for level, message in outage if level == 2 and "looking for it again" in message]
    findings.expect("device 0's status while unplugged", f"ERROR: {looking[0]}" if looking else f"{sorted(set(outage))[:2]}",
                    "ERROR, looking for it again", bool(looking))
    last = final_statuses(reception, bridge.stopping_ns)
    level, message, values = last.get(0, (None, "", {}))
    findings.expect("device 0's last status: reconnections", f"{values.get('reconnections', 'not reported')} (level {level}: {message})",
                    "1", values.get("reconnections") == "1")
    if new_rows:
        new_keys = [key for key, row in keyed.items() if row[0] == 0 and row[3] >= spawned_ns]
        new_stamps = [received[key][0] for key in new_keys if key in received]
        earliest = min(new_stamps) if new_stamps else None
        findings.expect("new connection: earliest stamp after the new device's process started",
                        seconds(earliest - spawned_ns) if earliest is not None else "none received",
                        "≥ 0 (no stamp from the old clock mapping)", earliest is not None and earliest >= spawned_ns)
        # From the raw reception, not the timing log's numbering: each pad's numbers go on
        # from the last before the unplug, not from 1 again.
        with reception.lock:
            raw = [(pad, sequence, now) for device, pad, sequence, _, now in reception.pressure if device == 0]
        continued = bool(raw)
        for pad in {pad for pad, _, _ in raw}:
            before = [sequence for p, sequence, now in raw if p == pad and now <= unplugged_ns + 1e9]
            later = [sequence for p, sequence, now in raw if p == pad and now > replugged_ns]
            continued &= bool(before and later) and later[0] == max(before) + 1 and later == sorted(set(later))
        findings.expect("device 0's publishers' sequence numbers go on where they were", "yes" if continued else "no",
                        "yes", continued)
    device1 = [now for key, (_, now) in received.items() if key[0] == 1]
    window_end = resumed_ns if resumed_ns is not None else replugged_ns
    findings.expect("device 1: longest time without a message from the unplug until device 0 is back",
                    f"{longest_gap_s(device1, unplugged_ns, window_end) * 1e3:.0f} ms", f"< {READER_GAP_LIMIT_S * 1e3:.0f} ms",
                    longest_gap_s(device1, unplugged_ns, window_end) < READER_GAP_LIMIT_S)
    device1_lost = sum(1 for key in keyed if key[0] == 1 and key not in received)
    device1_gaps = 0
    for pad in {row[1] for row in rows if row[0] == 1}:
        sequences = [row[2] for row in rows if row[:2] == (1, pad)]
        device1_gaps += sum(b - a - 1 for a, b in zip(sequences, sequences[1:]))
    findings.expect("device 1: frames lost / sequence gaps", f"{device1_lost} / {device1_gaps}", "0 / 0",
                    device1_lost == 0 and device1_gaps == 0)
    check_stamps(findings, received, keyed)
    return findings


def long_stall(tools, directory, port, settings):
    """The stall, long enough for the back-pressure to reach the bridge (the socket buffers on
    loopback hold several seconds of every pad)."""
    return stalled_subscriber(tools, directory, port, settings, stall_s=LONG_STALL_S, title="long stall")


SCENARIOS = {"stall": stalled_subscriber, "long-stall": long_stall, "router": router_restart,
             "replug": unplug_and_replug}


def run_scenarios(tools, port, settings, names=tuple(SCENARIOS)):
    """Runs the scenarios `names`, each on its own port from `port`; -> their findings."""
    results = []
    for offset, name in enumerate(names):
        with tempfile.TemporaryDirectory() as directory:
            results.append(SCENARIOS[name](tools, directory, port + offset, settings))
    return results


def faults_markdown(results):
    sections = []
    for findings in results:
        lines = [f"### {findings.title[0].upper()}{findings.title[1:]}", "", textwrap.fill(findings.description, 100, break_on_hyphens=False), "",
                 "| measure | value | expected |", "|---|---|---|"]
        for what, value, expected, held in findings.rows:
            verdict = "" if held is None else (f"{expected}: met" if held else f"{expected}: **missed**")
            lines.append(f"| {what} | {value} | {verdict} |")
        sections.append("\n".join(lines) + "\n")
    return "\n".join(sections)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bin", help="directory with taxel and taxel-bridge")
    parser.add_argument("--taxel", help="the taxel program (instead of --bin)")
    parser.add_argument("--bridge", help="the taxel-bridge program (instead of --bin)")
    parser.add_argument("--scenario", choices=sorted(SCENARIOS), action="append")
    parser.add_argument("--quick", action="store_true", help="two pads per device, a few seconds")
    parser.add_argument("--port", type=int, default=17459)
    parser.add_argument("--serve-router", metavar="ENDPOINT", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve_router:
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
        serve_router(args.serve_router)
        return 0
    if args.bin:
        tools = Tools.in_directory(args.bin)
    elif args.taxel and args.bridge:
        tools = Tools(args.taxel, args.bridge)
    else:
        parser.error("give --bin, or --taxel and --bridge")
    results = run_scenarios(tools, args.port, QUICK if args.quick else FULL, args.scenario or tuple(SCENARIOS))
    passed = sum(findings.passes() for findings in results)
    failed = sum(findings.failures() for findings in results)
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
