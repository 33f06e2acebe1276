"""A ROS 2 service client written from rmw_zenoh's design document and source, calling the
services of `taxel-bridge --allow-commands`; nothing of the bridge's own code is used.

What an rmw_zenoh client does (rmw_zenoh_cpp/src/detail/rmw_client_data.cpp,
`ClientData::send_request`; the server side in rmw_service_data.cpp): a Zenoh query on the
service's key expression `<domain>/<service>/<srv type>/<type hash>` (liveliness_utils.cpp,
`TopicInfo`; the type is the response type's name without `Response_`) with target
`ALL_COMPLETE` (so only queryables declared complete answer), consolidation `NONE`, the CDR
request as payload and the attachment (attachment_helpers.cpp) of the client's sequence number
(from 1), the time and its GID; the server replies on the service's key expression with the CDR
response and an attachment carrying the request's sequence number and the client's GID. The
service appears in the graph by a liveliness token `.../SS/...`.

The service type hashes are computed here by rosbags' REP-2011 implementation from the
definitions (std_srvs/srv/Trigger's; taxel_msgs/srv/SetUseCase from ros2-messages/srv/
SetUseCase.srv), a service being hashed as a type of three fields request_message,
response_message and event_message (rosidl_generator_type_description), with
service_msgs/msg/ServiceEventInfo's `char[16]` as rosidl sees it (`uint8[16]`: rosbags 0.11's
Jazzy store has it as char, which gives another hash). Trigger's hash is also checked against
the literal of ROS 2 Jazzy's generated std_srvs (share/std_srvs/srv/Trigger.json).

The run: two simulated devices of two pads playing bridge/tests/python/held.toml (both pads
pressed and held still from 1.3 s on; started by the caller, bridge-cli/tests/python_clients.rs:
device 1's simulator stops after --unplugged-after seconds, as if unplugged), bridged with
--allow-commands. Calls: a tare of device 0's pad 1 (succeeds, and the pads' published wrenches
show that pad 1's force went to zero while pad 0 still carries the held load), a tare of the
device (succeeds, and pad 0's force goes to zero too), a valid use case (the device names its
tier), an invalid one (the device refuses), a malformed request, a tare of pad 2 (not served:
the devices have two pads), and a tare of the unplugged device and of one of its pads (answered
success=false within a bounded time). Then a bridge without --allow-commands, for Humble: no
service token, no answer, and the key expressions and tokens carry `TypeHashNotSupported`.

Prints one line per check and a closing "N passed, M failed" line; exits non-zero on any failure.
"""

import argparse
import json
import struct
import subprocess
import sys
import threading
import time

import xxhash
import zenoh
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

TRIGGER_HASH_OF_JAZZY = "RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f"
CALL_BOUND_S = 3.0


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


def service_typestore(set_use_case_srv):
    """rosbags' Jazzy store with std_srvs/srv/Trigger and taxel_msgs/srv/SetUseCase added."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.fielddefs.pop("service_msgs/msg/ServiceEventInfo", None)
    store.register(get_types_from_msg(
        "uint8 event_type\nbuiltin_interfaces/Time stamp\nuint8[16] client_gid\nint64 sequence_number\n",
        "service_msgs/msg/ServiceEventInfo"))

    def renamed(value):
        # get_types_from_msg files `pkg/srv/Name` under `pkg/srv/msg/Name`.
        if isinstance(value, str):
            return value.replace("/srv/msg/", "/srv/")
        if isinstance(value, (tuple, list)):
            return type(value)(renamed(item) for item in value)
        return value

    def add(package, name, srv):
        request, response = srv.split("\n---\n")
        full = f"{package}/srv/{name}"
        types = {}
        types.update(get_types_from_msg(request, f"{full}_Request"))
        types.update(get_types_from_msg(response, f"{full}_Response"))
        types.update(get_types_from_msg(
            f"service_msgs/ServiceEventInfo info\n{full}_Request[<=1] request\n{full}_Response[<=1] response\n",
            f"{full}_Event"))
        types.update(get_types_from_msg(
            f"{full}_Request request_message\n{full}_Response response_message\n{full}_Event event_message\n", full))
        store.register({renamed(key): renamed(value) for key, value in types.items()})

    add("std_srvs", "Trigger", "\n---\nbool success\nstring message\n")
    add("taxel_msgs", "SetUseCase", set_use_case_srv)
    return store


class Client:
    """An rmw_zenoh client's requests, sequence numbers from 1, its GID from a token."""

    def __init__(self, session, store):
        self.session = session
        self.store = store
        self.sequence = 0
        token = "@ros2_lv/0/0123456789abcdef/0/1/SC/%/%/python_client/%taxel%device0%tare"
        self.gid = xxhash.xxh3_128_intdigest(token.encode()).to_bytes(16, "little")

    def call(self, key, payload, timeout=CALL_BOUND_S + 2):
        """-> (replies as (key, payload, attachment) or ("error", text), seconds, sequence)."""
        self.sequence += 1
        payload = bytes(payload)
        attachment = struct.pack("<qqB", self.sequence, time.time_ns(), 16) + self.gid
        started = time.monotonic()
        replies = []
        for reply in self.session.get(key, target=zenoh.QueryTarget.ALL_COMPLETE,
                                      consolidation=zenoh.ConsolidationMode.NONE, payload=payload,
                                      attachment=attachment, timeout=timeout):
            if reply.ok is not None:
                sample = reply.ok
                replies.append((str(sample.key_expr), sample.payload.to_bytes(),
                                sample.attachment.to_bytes() if sample.attachment is not None else b""))
            else:
                replies.append(("error", reply.err.payload.to_bytes()))
        return replies, time.monotonic() - started, self.sequence


def open_session(port):
    config = zenoh.Config()
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def watch_tokens(session):
    tokens = []
    lock = threading.Lock()

    def on_token(sample):
        with lock:
            tokens.append(str(sample.key_expr))

    subscriber = session.liveliness().declare_subscriber("@ros2_lv/**", on_token, history=True)
    return tokens, lock, subscriber


def wait_for(predicate, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bridge", required=True)
    parser.add_argument("--scene", required=True, help="the simulated devices' scene (held.toml)")
    parser.add_argument("--srv", required=True, help="ros2-messages/srv/SetUseCase.srv")
    parser.add_argument("--ports", nargs=2, required=True, help="device 0's and device 1's terminals")
    parser.add_argument("--unplugged-after", type=float, required=True,
                        help="seconds from now after which device 1's simulator has stopped")
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--humble-port", type=int, required=True)
    args = parser.parse_args()
    started = time.monotonic()
    with open(args.srv) as srv:
        store = service_typestore(srv.read())
    checks = Checks()
    trigger_hash = store.hash_rihs01("std_srvs/srv/Trigger")
    use_case_hash = store.hash_rihs01("taxel_msgs/srv/SetUseCase")
    checks.check(trigger_hash == TRIGGER_HASH_OF_JAZZY,
                 f"rosbags' service hash of std_srvs/srv/Trigger is Jazzy's ({trigger_hash})")

    session = open_session(args.port)
    tokens, lock, token_subscriber = watch_tokens(session)
    client = Client(session, store)
    command = [args.bridge, *args.ports, "--allow-commands", "--tare-sets", "16",
               "--connect", f"tcp/127.0.0.1:{args.port}", "--listen", "tcp/127.0.0.1:0", "--duration", "14"]
    bridge = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    services = {(device, word): (f"0/taxel/device{device}/{word}/{dds}/{type_hash}")
                for device in range(2)
                for word, dds, type_hash in (("tare", "std_srvs::srv::dds_::Trigger_", trigger_hash),
                                             ("pad0/tare", "std_srvs::srv::dds_::Trigger_", trigger_hash),
                                             ("pad1/tare", "std_srvs::srv::dds_::Trigger_", trigger_hash),
                                             ("set_use_case", "taxel_msgs::srv::dds_::SetUseCase_", use_case_hash))}

    # Each pad's force (N, pressing positive), as published on its wrench topic, with when it came.
    forces = {0: [], 1: []}

    def on_wrench(pad):
        def on_sample(sample):
            message = store.deserialize_cdr(sample.payload.to_bytes(), "geometry_msgs/msg/WrenchStamped")
            with lock:
                forces[pad].append((time.monotonic(), -message.wrench.force.z))
        return on_sample

    wrench_subscribers = [session.declare_subscriber(f"0/taxel/device0/pad{pad}/wrench/**", on_wrench(pad))
                          for pad in (0, 1)]

    def mean_force_n(pad, since):
        with lock:
            recent = [force for arrived, force in forces[pad] if arrived >= since]
        return sum(recent) / len(recent) if recent else float("nan")

    def service_tokens():
        with lock:
            return [token for token in tokens if token.split("/")[5:6] == ["SS"]]

    wait_for(lambda: len(service_tokens()) >= 8, 10)
    found = service_tokens()
    for (device, word), key in services.items():
        name, dds, type_hash = key.split("/", 1)[1].rsplit("/", 2)
        wanted = f"/SS/%/%/taxel_bridge/{'%' + name.replace('/', '%')}/{dds}/{type_hash}/::,10:,:,:,,"
        checks.check(any(token.endswith(wanted) for token in found),
                     f"a service server token for /{name} ({dds}, {type_hash})")
    checks.check(len(found) == 8, f"eight service tokens, two per device and one per pad ({len(found)})")
    # Device 0 finishes its power-on tare, and its pads are pressed and held, before it is asked
    # for a tare.
    wait_for(lambda: False, max(0.0, 3.0 - (time.monotonic() - started)))

    def decode(replies, response_type):
        if len(replies) != 1 or replies[0][0] == "error":
            return None, None, None
        key, payload, attachment = replies[0]
        return key, store.deserialize_cdr(payload, response_type), attachment

    held = [mean_force_n(pad, time.monotonic() - 0.5) for pad in (0, 1)]
    checks.check(all(abs(force - 0.4) < 0.05 for force in held),
                 f"both pads carry the held 0.4 N before any tare ({held[0]:.3f} N, {held[1]:.3f} N)")
    trigger = store.serialize_cdr(store.types["std_srvs/srv/Trigger_Request"](), "std_srvs/srv/Trigger_Request")
    replies, seconds, _ = client.call(services[(0, "pad1/tare")], trigger)
    key, response, _ = decode(replies, "std_srvs/srv/Trigger_Response")
    checks.check(response is not None and response.success and response.message == "tared pad 1 over 16 sample sets",
                 f"device 0's pad 1 tared in {seconds:.2f} s ({response})")
    checks.check(key == services[(0, "pad1/tare")], f"the pad's reply is on its service's key expression ({key})")
    since = time.monotonic() + 0.2
    wait_for(lambda: False, 0.7)
    after = [mean_force_n(pad, since) for pad in (0, 1)]
    checks.check(abs(after[1]) < 0.05 and abs(after[0] - 0.4) < 0.05,
                 f"only pad 1 was tared: pad 1 reads the held load as zero, pad 0 still reads it ({after[0]:.3f} N, {after[1]:.3f} N)")

    replies, seconds, sequence = client.call(services[(0, "tare")], trigger)
    key, response, attachment = decode(replies, "std_srvs/srv/Trigger_Response")
    checks.check(response is not None and response.success and response.message == "tared over 16 sample sets",
                 f"device 0 tared in {seconds:.2f} s ({response})")
    checks.check(key == services[(0, "tare")], f"the reply is on the service's key expression ({key})")
    since = time.monotonic() + 0.2
    wait_for(lambda: False, 0.7)
    after = [mean_force_n(pad, since) for pad in (0, 1)]
    checks.check(all(abs(force) < 0.05 for force in after),
                 f"the device's tare tared every pad ({after[0]:.3f} N, {after[1]:.3f} N)")
    if attachment:
        reply_sequence, reply_ns, length = struct.unpack_from("<qqB", attachment)
        checks.check(len(attachment) == 33 and reply_sequence == sequence and length == 16
                     and attachment[17:] == client.gid and abs(reply_ns - time.time_ns()) < 5e9,
                     f"the reply's attachment: the request's sequence {reply_sequence}, the client's GID, a timestamp")
    else:
        checks.check(False, "the reply has an attachment")

    use_case_type = store.types["taxel_msgs/srv/SetUseCase_Request"]

    def use_case(*values):
        return store.serialize_cdr(use_case_type(*values), "taxel_msgs/srv/SetUseCase_Request")

    replies, seconds, _ = client.call(services[(0, "set_use_case")], use_case(50.0, 15.0, 35.0, 0.5))
    _, response, _ = decode(replies, "taxel_msgs/srv/SetUseCase_Response")
    checks.check(response is not None and response.success and response.message.startswith("the device chose model tier"),
                 f"device 0 took the gripper use case in {seconds:.2f} s ({response})")
    replies, seconds, _ = client.call(services[(0, "set_use_case")], use_case(50.0, 40.0, 10.0, 0.5))
    _, response, _ = decode(replies, "taxel_msgs/srv/SetUseCase_Response")
    checks.check(response is not None and not response.success and "refused" in response.message,
                 f"device 0 refused a use case whose lowest temperature is above its highest ({response})")
    replies, seconds, _ = client.call(services[(0, "set_use_case")], b"\x00\x01\x00\x00\x00")
    _, response, _ = decode(replies, "taxel_msgs/srv/SetUseCase_Response")
    checks.check(response is not None and not response.success and "not a taxel_msgs/srv/SetUseCase request" in response.message,
                 f"a malformed request is answered, not sent ({response})")
    replies, seconds, _ = client.call("0/taxel/device0/pad2/tare/**", trigger, timeout=1.5)
    checks.check(not replies, f"no tare of a pad the device lacks is served ({len(replies)} replies in {seconds:.1f} s)")
    for subscriber in wrench_subscribers:
        subscriber.undeclare()

    # Device 1 is gone: its call is answered, and soon.
    wait_for(lambda: False, max(0.0, args.unplugged_after + 2.0 - (time.monotonic() - started)))
    replies, seconds, _ = client.call(services[(1, "tare")], trigger)
    _, response, _ = decode(replies, "std_srvs/srv/Trigger_Response")
    checks.check(response is not None and not response.success
                 and ("not connected" in response.message or "went away" in response.message),
                 f"the unplugged device 1's tare is refused ({response})")
    checks.check(seconds < CALL_BOUND_S, f"within {CALL_BOUND_S} s ({seconds:.2f} s)")
    replies, seconds, _ = client.call(services[(1, "pad0/tare")], trigger)
    _, response, _ = decode(replies, "std_srvs/srv/Trigger_Response")
    checks.check(response is not None and not response.success
                 and ("not connected" in response.message or "went away" in response.message)
                 and seconds < CALL_BOUND_S,
                 f"the unplugged device 1's pad 0 tare is refused, in {seconds:.2f} s ({response})")

    _, stderr = bridge.communicate(timeout=60)
    print(stderr, end="")
    checks.check(bridge.returncode == 0, f"the bridge exited 0 ({bridge.returncode})")
    checks.check("commands accepted from ROS 2 (--allow-commands)" in stderr,
                 "the start-up line says commands are accepted")
    checks.check("device 0: tare from ROS 2 done" in stderr and "device 0: pad 1 tare from ROS 2 done" in stderr,
                 "the bridge says what ROS 2 asked of the device and of its pad")
    token_subscriber.undeclare()
    session.close()

    # Without --allow-commands, for Humble: nothing served, no type hash in any name.
    session = open_session(args.humble_port)
    tokens, lock, token_subscriber = watch_tokens(session)
    keys = set()
    data_subscriber = session.declare_subscriber("0/**", lambda sample: keys.add(str(sample.key_expr)))
    client = Client(session, store)
    command = [args.bridge, "--sim", "1", "--sim-scene", args.scene, "--ros-distro", "humble",
               "--connect", f"tcp/127.0.0.1:{args.humble_port}", "--listen", "tcp/127.0.0.1:0", "--duration", "5"]
    bridge = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: any("/MP/" in token for token in list(tokens)), 10)
    wait_for(lambda: False, 1.0)
    replies, seconds, _ = client.call("0/taxel/device0/tare/**", trigger, timeout=1.5)
    checks.check(not replies, f"without --allow-commands no tare is served ({len(replies)} replies)")
    _, stderr = bridge.communicate(timeout=60)
    print(stderr, end="")
    with lock:
        seen = list(tokens)
    publishers = [token for token in seen if "/MP/" in token]
    checks.check(not [token for token in seen if token.split("/")[5:6] == ["SS"]],
                 "without --allow-commands no service token")
    checks.check(publishers and all(token.split("/")[-2] == "TypeHashNotSupported" for token in publishers),
                 f"Humble: every publisher token has TypeHashNotSupported for its hash ({publishers[:1]})")
    checks.check(keys and all(key.endswith("/TypeHashNotSupported") for key in keys),
                 f"Humble: every key expression ends with TypeHashNotSupported ({sorted(keys)[:1]})")
    checks.check("; no commands accepted;" in stderr and "for ROS 2 humble" in stderr,
                 "the start-up line says no commands and Humble")
    data_subscriber.undeclare()
    token_subscriber.undeclare()
    session.close()

    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
