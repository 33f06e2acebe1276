"""An independent client of `taxel-bridge --foxglove`: a Foxglove WebSocket client written from
the protocol's published specification (foxglove/ws-protocol, docs/spec.md, "Foxglove WebSocket
protocol v1"), with the `websockets` package for the WebSocket and the `protobuf` package for
the protobuf-encoded channels. Nothing of the bridge's code, nor of the Foxglove SDK's, is used.
What it receives is checked against the simulated scene (bridge/tests/python/foxglove_plateau.toml)
and against what docs/BRIDGE.md ("A live view in Foxglove") says.

From the specification:
- the client offers its subprotocols in the WebSocket handshake and the server selects one;
- the server's first message is a JSON `serverInfo`; channels come in JSON `advertise` messages
  (`id`, `topic`, `encoding`, `schemaName`, `schema`, `schemaEncoding`), a protobuf schema being
  a base64 FileDescriptorSet;
- the client sends JSON `subscribe` with `subscriptions: [{id, channelId}]`;
- the server sends binary `messageData`: opcode 0x01, the subscription id (u32 LE), the log time
  (u64 LE, ns), then the payload in the channel's encoding.

One thing is not in the specification: its subprotocol is `foxglove.websocket.v1`, and servers of
the Foxglove SDK negotiate the same v1 messages under the name `foxglove.sdk.v1` (they answer a
handshake offering only `foxglove.websocket.v1` with HTTP 400). This client offers both, as the
specification lets a client offer every subprotocol it supports, and checks that the server chose
one of them. (The specification was removed from the repository's main branch in July 2025 as
outdated; it is read at the commit before.)

Run by bridge-cli/tests/python_clients.rs; prints one line per check and a closing
"N passed, M failed" line, and exits non-zero on any failure.
"""

import argparse
import asyncio
import base64
import json
import math
import socket
import struct
import subprocess
import sys
import tempfile
import time
import tomllib

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

OFFERED_SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
MESSAGE_DATA = 0x01
# The article's pad, the default geometry (README: 25 mm² electrodes centred at ±2.75 mm, C11
# top-left; C11, C12, C21, C22 order), restated here: (x mm, y mm, area mm²).
ARTICLE_TAXELS = [(-2.75, 2.75, 25.0), (2.75, 2.75, 25.0), (-2.75, -2.75, 25.0), (2.75, -2.75, 25.0)]
PRESSURE_TOLERANCE_KPA = 0.5
FORCE_TOLERANCE_N = 0.05
CENTRE_TOLERANCE_MM = 0.2
# The scene's plateau holds from 2.5 s; the device numbers its sample sets from 0 at boot, 100
# per second.
STEADY_FROM_SEQUENCE = 300
# docs/BRIDGE.md: blue at 0 kPa to red at 50 kPa.
FULL_SCALE_KPA = 50.0
COLOUR_TOLERANCE = 0.02
NAMESPACE = "/taxel"


def load_scene(path):
    """Per pad of the scene: its plateau (kPa) and its taxels (x mm, y mm, area mm²)."""
    with open(path, "rb") as scene_file:
        pads = tomllib.load(scene_file)["pad"]
    scene = []
    for pad in pads:
        taxels = [(t["x_mm"], t["y_mm"], t["area_mm2"]) for t in pad.get("taxel", [])] or ARTICLE_TAXELS
        scene.append((pad["keyframe"][-1]["pressure_kpa"], taxels))
    return scene


def protobuf_class(channel):
    """The message class of a protobuf channel, from the FileDescriptorSet it advertises."""
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"])).file
    pool = descriptor_pool.DescriptorPool()
    pending = list(files)
    added = set()
    while pending:
        ready = [f for f in pending if all(dependency in added for dependency in f.dependency)]
        if not ready:
            raise ValueError(f"unresolvable dependencies in the schema of {channel['topic']}")
        for file in ready:
            pool.Add(file)
            added.add(file.name)
            pending.remove(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))


async def connect_retrying(uri, bridge, **options):
    """A connection to the server, retried while the bridge starts."""
    deadline = time.monotonic() + 30
    while True:
        try:
            return await connect(uri, subprotocols=OFFERED_SUBPROTOCOLS, compression=None,
                                 open_timeout=5, **options)
        except (OSError, asyncio.TimeoutError):
            if time.monotonic() > deadline or bridge.poll() is not None:
                raise
            await asyncio.sleep(0.2)


async def stalled_client(uri, port, bridge):
    """A client that subscribes to every channel and then never reads: its socket's receive
    buffer is made small and websockets stops reading once one frame waits, so the server's
    sends to it soon block. The other client must get everything all the same."""
    stalled = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    deadline = time.monotonic() + 30
    while True:
        try:
            stalled.connect(("127.0.0.1", port))
            break
        except OSError:
            if time.monotonic() > deadline or bridge.poll() is not None:
                raise
            await asyncio.sleep(0.2)
    websocket = await connect(uri, sock=stalled, subprotocols=OFFERED_SUBPROTOCOLS, compression=None,
                              open_timeout=5, max_queue=1, max_size=None)
    subscribed = 0
    while subscribed == 0:
        message = json.loads(await websocket.recv())
        if message.get("op") == "advertise":
            subscriptions = [{"id": index + 1, "channelId": channel["id"]}
                             for index, channel in enumerate(message["channels"])]
            await websocket.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
            subscribed = len(subscriptions)
    return websocket, subscribed


async def receive(uri, wanted_topics, seconds, bridge, port):
    """Connects (retrying while the bridge starts), subscribes to `wanted_topics` as they are
    advertised and receives until the server closes or `seconds` pass. Returns the subprotocol,
    the serverInfo, every channel advertised by id and the messages as (topic, log time, payload,
    reception time)."""
    websocket = await connect_retrying(uri, bridge, max_size=None)
    stalled, stalled_subscriptions = await stalled_client(uri, port, bridge)
    channels, subscriptions, messages, texts = {}, {}, [], []
    server_info = None
    end = time.monotonic() + seconds
    async with websocket:
        while time.monotonic() < end:
            try:
                frame = await asyncio.wait_for(websocket.recv(), timeout=max(0.1, end - time.monotonic()))
            except (ConnectionClosed, asyncio.TimeoutError):
                break
            if isinstance(frame, str):
                message = json.loads(frame)
                texts.append(message)
                if message.get("op") == "serverInfo" and server_info is None:
                    server_info = message
                elif message.get("op") == "advertise":
                    new = []
                    for channel in message["channels"]:
                        channels[channel["id"]] = channel
                        if channel["topic"] in wanted_topics and channel["id"] not in subscriptions.values():
                            subscription = len(subscriptions) + 1
                            subscriptions[subscription] = channel["id"]
                            new.append({"id": subscription, "channelId": channel["id"]})
                    if new:
                        await websocket.send(json.dumps({"op": "subscribe", "subscriptions": new}))
            elif frame and frame[0] == MESSAGE_DATA:
                subscription, log_ns = struct.unpack_from("<IQ", frame, 1)
                topic = channels[subscriptions[subscription]]["topic"] if subscription in subscriptions else None
                messages.append((topic, log_ns, bytes(frame[13:]), time.time_ns()))
    stalled.transport.abort()
    return websocket.subprotocol, server_info, texts, channels, messages, stalled_subscriptions


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bridge", required=True)
    parser.add_argument("--scene", required=True)
    parser.add_argument("--devices", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=7.0)
    parser.add_argument("--port", type=int, default=18765)
    args = parser.parse_args()
    scene = load_scene(args.scene)
    pads = [(device, pad) for device in range(args.devices) for pad in range(len(scene))]
    state_topics = {f"{NAMESPACE}/device{d}/pad{p}/state": (d, p) for d, p in pads}
    scene_topic, transforms_topic, health_topic = (f"{NAMESPACE}/{name}" for name in ("scene", "transforms", "health"))
    wanted = set(state_topics) | {scene_topic, transforms_topic, health_topic}

    with tempfile.TemporaryFile(mode="w+") as bridge_log:
        bridge = subprocess.Popen(
            [args.bridge, "--sim", str(args.devices), "--sim-scene", args.scene,
             "--no-connect", "--listen", "tcp/127.0.0.1:0", "--duration", str(args.seconds),
             "--foxglove", f"127.0.0.1:{args.port}"],
            stdout=subprocess.DEVNULL, stderr=bridge_log, text=True)
        try:
            subprotocol, server_info, texts, channels, messages, stalled_subscriptions = asyncio.run(
                receive(f"ws://127.0.0.1:{args.port}", wanted, args.seconds + 20, bridge, args.port))
            returncode = bridge.wait(timeout=60)
        finally:
            if bridge.poll() is None:
                bridge.kill()
        bridge_log.seek(0)
        bridge_words = bridge_log.read()
    print(bridge_words, end="")

    passed = failed = 0

    def check(condition, message):
        nonlocal passed, failed
        passed, failed = (passed + 1, failed) if condition else (passed, failed + 1)
        print(("ok: " if condition else "FAILED: ") + message)

    check(returncode == 0, f"the bridge exited 0 ({returncode})")
    check(f"Foxglove: ws://127.0.0.1:{args.port}" in bridge_words and "this machine only" in bridge_words,
          "the start-up line gives the address, reachable from this machine only")
    check(stalled_subscriptions >= len(wanted) and "0 sample sets dropped by the bridge" in bridge_words,
          f"a second client subscribed to {stalled_subscriptions} channels and never read: "
          "the bridge dropped nothing (and the checks below hold for this client)")
    check(subprotocol in OFFERED_SUBPROTOCOLS, f"the server chose an offered subprotocol ({subprotocol})")
    check(bool(texts) and texts[0].get("op") == "serverInfo", "the first message is serverInfo")
    check(server_info is not None and server_info.get("name") == "taxel-bridge"
          and isinstance(server_info.get("capabilities"), list),
          f"serverInfo names the server and lists capabilities ({server_info})")
    advertised = {channel["topic"]: channel for channel in channels.values()}
    check(wanted <= set(advertised), f"every topic advertised (missing: {sorted(wanted - set(advertised))})")
    by_topic = {}
    for topic, log_ns, payload, received_ns in messages:
        by_topic.setdefault(topic, []).append((log_ns, payload, received_ns))
    check(None not in by_topic, "every message is on a subscription the client made")

    # The pads' states: JSON with a JSON schema.
    steady_from_ns = 0
    for topic, (device, pad) in sorted(state_topics.items()):
        channel = advertised.get(topic, {})
        schema = json.loads(channel.get("schema", "{}") or "{}")
        check(channel.get("encoding") == "json" and channel.get("schemaEncoding") == "jsonschema"
              and channel.get("schemaName") == "taxel.PadState" and "pressure_kpa" in schema.get("properties", {}),
              f"{topic}: json, schema taxel.PadState in jsonschema")
        states = [(log_ns, json.loads(payload)) for log_ns, payload, _ in by_topic.get(topic, [])]
        required = schema.get("required", [])
        check(len(states) > 200 and required and all(all(field in state for field in required) for _, state in states),
              f"{topic}: {len(states)} states, each with the schema's required fields")
        check(all(state["stamp_ns"] <= log_ns and state["timestamp"]["sec"] * 1_000_000_000 + state["timestamp"]["nsec"] == state["stamp_ns"]
                  and (state["device"], state["pad"]) == (device, pad) for log_ns, state in states),
              f"{topic}: timestamp = stamp_ns, not after the log time (arrival); device {device}, pad {pad}")
        sequences = [state["sequence"] for _, state in states]
        missing = sum(b - a - 1 for a, b in zip(sequences, sequences[1:]))
        check(sequences == sorted(sequences) and missing <= len(sequences) // 10,
              f"{topic}: sequences in order, {missing} missing of {len(sequences) + missing}")
        plateau, taxels = scene[pad]
        forces = [p * area / 1000 for p, (_, _, area) in zip(plateau, taxels)]
        expected_force_n = sum(forces)
        expected_centre_mm = [sum(f * t[axis] for f, t in zip(forces, taxels)) / expected_force_n for axis in (0, 1)]
        steady = [(log_ns, state) for log_ns, state in states if state["sequence"] >= STEADY_FROM_SEQUENCE]
        bad = [state for _, state in steady
               if any(p is None or abs(p - q) > PRESSURE_TOLERANCE_KPA for p, q in zip(state["pressure_kpa"], plateau))
               or abs(state["force_n"] - expected_force_n) > FORCE_TOLERANCE_N
               or state["centre_of_pressure_mm"] is None
               or any(abs(state["centre_of_pressure_mm"][axis] - expected) > CENTRE_TOLERANCE_MM
                      for axis, expected in zip("xy", expected_centre_mm))
               or not state["contact"] or state["partial"] or any(state["flags"])]
        check(len(steady) > 100 and not bad,
              f"{topic}: {len(steady)} steady states at {plateau} kPa, {expected_force_n:.3f} N at "
              f"({expected_centre_mm[0]:.2f}, {expected_centre_mm[1]:.2f}) mm, in contact, no flag ({bad[:1]})")
        if steady:
            steady_from_ns = max(steady_from_ns, steady[0][0])

    # The 3D scene: protobuf foxglove.SceneUpdate and foxglove.FrameTransforms.
    decoded = {}
    for topic, schema_name in ((scene_topic, "foxglove.SceneUpdate"), (transforms_topic, "foxglove.FrameTransforms")):
        channel = advertised.get(topic, {})
        check(channel.get("encoding") == "protobuf" and channel.get("schemaEncoding") == "protobuf"
              and channel.get("schemaName") == schema_name,
              f"{topic}: protobuf {schema_name}, schema a base64 FileDescriptorSet")
        try:
            message_class = protobuf_class(channel)
            decoded[topic] = [(log_ns, message_class.FromString(payload)) for log_ns, payload, _ in by_topic.get(topic, [])]
        except Exception as error:  # noqa: BLE001: any failure to decode is this check failing
            decoded[topic] = []
            check(False, f"{topic}: decoded with the advertised schema ({error!r})")
    scenes = decoded[scene_topic]
    duration_s = (scenes[-1][0] - scenes[0][0]) / 1e9 if len(scenes) > 1 else 0
    check(len(scenes) > 20 and len(scenes) <= duration_s * 20 + 2,
          f"{len(scenes)} scene updates in {duration_s:.1f} s (at most 20 per second)")
    steady_scenes = [update for log_ns, update in scenes if log_ns > steady_from_ns + 100_000_000]
    frames = {f"taxel_device{d}_pad{p}": (d, p) for d, p in pads}
    bad = []
    for update in steady_scenes:
        if sorted(entity.frame_id for entity in update.entities) != sorted(frames):
            bad.append(("entities", [entity.frame_id for entity in update.entities]))
            continue
        for entity in update.entities:
            _, pad = frames[entity.frame_id]
            plateau, taxels = scene[pad]
            if len(entity.cubes) != 4:
                bad.append((entity.frame_id, len(entity.cubes), "cubes"))
                continue
            for cube, pressure, (x_mm, y_mm, area) in zip(entity.cubes, plateau, taxels):
                position, size, colour = cube.pose.position, cube.size, cube.color
                side_m = math.sqrt(area) / 1000
                red = min(max(pressure / FULL_SCALE_KPA, 0), 1)
                if (abs(position.x - x_mm / 1000) > 1e-6 or abs(position.y - y_mm / 1000) > 1e-6
                        or abs(size.x - side_m) > 1e-6 or abs(size.y - side_m) > 1e-6
                        or abs(position.z - size.z / 2) > 1e-9 or size.z <= 0
                        or abs(colour.r - red) > COLOUR_TOLERANCE or abs(colour.b - (1 - red)) > COLOUR_TOLERANCE):
                    bad.append((entity.frame_id, x_mm, y_mm, pressure, str(cube).replace("\n", " ")))
    check(len(steady_scenes) > 20 and not bad,
          f"{len(steady_scenes)} steady scenes: every pad's entity in its frame, 4 cubes at its electrodes' "
          f"centres, of its electrodes' size, standing on the pad, blue to red by pressure ({bad[:1]})")
    transforms = decoded[transforms_topic]
    check(len(transforms) >= len(scenes) - 1 and len(transforms) > 20, f"{len(transforms)} transform messages")
    last = {transform.child_frame_id: transform for transform in transforms[-1][1].transforms} if transforms else {}
    check(set(last) == set(frames) and all(t.parent_frame_id == "taxel_pads" for t in last.values()),
          f"each pad's frame placed in taxel_pads ({sorted(last)})")
    footprints = []
    for frame, (_, pad) in frames.items():
        transform = last.get(frame)
        if transform is None:
            continue
        _, taxels = scene[pad]
        half_x = max(abs(x) + math.sqrt(a) / 2 for x, _, a in taxels) / 1000
        half_y = max(abs(y) + math.sqrt(a) / 2 for _, y, a in taxels) / 1000
        x, y = transform.translation.x, transform.translation.y
        footprints.append((frame, x - half_x, x + half_x, y - half_y, y + half_y))
    overlapping = [(a[0], b[0]) for i, a in enumerate(footprints) for b in footprints[i + 1:]
                   if a[1] < b[2] and b[1] < a[2] and a[3] < b[4] and b[3] < a[4]]
    check(len(footprints) == len(frames) and not overlapping, f"no two pads overlap in the scene ({overlapping})")

    # The devices' health: JSON.
    channel = advertised.get(health_topic, {})
    check(channel.get("encoding") == "json" and channel.get("schemaEncoding") == "jsonschema"
          and channel.get("schemaName") == "taxel.Health", f"{health_topic}: json, schema taxel.Health")
    healths = [json.loads(payload) for _, payload, _ in by_topic.get(health_topic, [])]
    check(len(healths) >= 3, f"{len(healths)} health messages (one a second)")
    # The bridge's last report comes as the devices stop (ERROR, "stopped") and the server
    # stops right after it, so it may or may not arrive: the last one while they streamed.
    running = [health["devices"] for health in healths
               if all(device.get("message") != "stopped" for device in health["devices"])]
    running = running[-1] if running else []
    check([device.get("name") for device in running] == [f"taxel_bridge: device{d}" for d in range(args.devices)]
          and all(device.get("level_name") == "OK" and device.get("level") == 0
                  and int(device["values"].get("frames published", "0")) > 0
                  and "calibration source" in device["values"] for device in running),
          f"while streaming: every device named, OK, frames published, calibration source "
          f"({[(d.get('name'), d.get('level_name'), d.get('message')) for d in running]})")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
