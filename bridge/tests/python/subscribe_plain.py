"""`taxel-bridge --mode plain` read by Python's eclipse-zenoh with nothing but `struct` and `json`:
the documented key expressions and record layouts (docs/BRIDGE.md, Plain mode), checked against
the simulated scene (bridge/tests/python/plateau.toml). Prints "N passed, M failed"."""

import argparse
import json
import struct
import subprocess
import sys
import threading
import time
import tomllib

import zenoh

SAMPLE = struct.Struct("<QIBBHfff4f4HfB3x")
CONTACT = struct.Struct("<QBB6x")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bridge", required=True)
    parser.add_argument("--scene", required=True)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--port", type=int, default=17448)
    args = parser.parse_args()
    with open(args.scene, "rb") as scene_file:
        plateaus = [pad["keyframe"][-1]["pressure_kpa"] for pad in tomllib.load(scene_file)["pad"]]

    received = []
    lock = threading.Lock()

    def on_sample(sample):
        with lock:
            received.append((str(sample.key_expr), str(sample.encoding), sample.payload.to_bytes(), time.time_ns()))

    config = zenoh.Config()
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{args.port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(config)
    subscriber = session.declare_subscriber("taxel/**", on_sample)
    bridge = subprocess.run(
        [args.bridge, "--mode", "plain", "--sim", "1", "--sim-scene", args.scene,
         "--connect", f"tcp/127.0.0.1:{args.port}", "--listen", "tcp/127.0.0.1:0",
         "--duration", str(args.seconds)],
        capture_output=True, text=True, timeout=args.seconds + 60)
    time.sleep(0.5)
    subscriber.undeclare()
    session.close()
    print(bridge.stderr, end="")

    passed = failed = 0

    def check(condition, message):
        nonlocal passed, failed
        passed, failed = (passed + 1, failed) if condition else (passed, failed + 1)
        print(("ok: " if condition else "FAILED: ") + message)

    check(bridge.returncode == 0, f"the bridge exited 0 ({bridge.returncode})")
    for pad, plateau in enumerate(plateaus):
        key = f"taxel/device0/pad{pad}/sample"
        records = [(encoding, payload, now) for k, encoding, payload, now in received if k == key]
        check(records and all(len(payload) == SAMPLE.size and "taxel-sample-v1" in encoding for encoding, payload, _ in records),
              f"{key}: {len(records)} records of {SAMPLE.size} bytes, encoding {records[0][0] if records else None}")
        fields = [SAMPLE.unpack(payload) for _, payload, _ in records]
        sequences = [field[1] for field in fields]
        gaps = [b - a for a, b in zip(sequences, sequences[1:]) if b - a != 1]
        check(len(sequences) > 100 and not gaps, f"{key}: no sequence gap ({gaps[:3]})")
        check(all(field[0] <= now for field, (_, _, now) in zip(fields, records)) and all(field[2] == pad for field in fields),
              f"{key}: stamps not after reception, pad index {pad}")
        bad = []
        for field in fields:
            stamp, sequence, _, summary, _, force, _, _, *rest = field
            pressures = rest[:4]
            if sequence < 300:
                continue
            expected_force = sum(plateau) * 0.025
            if any(abs(p - q) > 0.5 for p, q in zip(pressures, plateau)) or abs(force - expected_force) > 0.05 or not summary & 1:
                bad.append((sequence, pressures, force, summary))
        check(not bad, f"{key}: steady records at {plateau} kPa, {sum(plateau) * 0.025:.3f} N, in contact ({bad[:2]})")
        contacts = [CONTACT.unpack(payload) for k, _, payload, _ in received if k == f"taxel/device0/pad{pad}/contact"]
        check(len(contacts) == 1 and contacts[0][1:] == (pad, 1), f"pad{pad}: one contact start record ({contacts})")
    health = [json.loads(payload) for k, _, payload, _ in received if k == "taxel/device0/health"]
    check(len(health) >= 3 and health[0]["name"] == "taxel_bridge: device0" and "calibration source" in health[0]["values"],
          f"{len(health)} health records in JSON")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
