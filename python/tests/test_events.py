"""Where the contact is, and what the device reports: centre of pressure, contact and partial
per pad in sample sets and buffers, and the device's events through `events()` — compared
with what `taxel record` writes for the same simulated device and seed (the command-line tool
is the reference), and with the scene's known plateaus."""

import subprocess
import time

import numpy as np
import pytest

import taxel
from test_device import start_cli_simulator


def test_sample_sets_carry_force_centre_contact_and_partial_per_pad():
    with taxel.Simulator(scene="gripper", speed=20.0) as sim:
        sample = sim.read()
        assert sample.force_n.shape == (2,)
        assert sample.cop_mm.shape == (2, 2) and sample.cop_mm.dtype == np.float64
        assert sample.contact.shape == (2,) and sample.contact.dtype == np.bool_
        assert sample.partial.shape == (2,) and sample.partial.dtype == np.bool_
        # The gripper closes 1.5 s into the scene: read until both pads are in contact.
        deadline = time.monotonic() + 10
        while not sample.contact.all():
            assert time.monotonic() < deadline, "no contact within the scene's grasp"
            sample = sim.read()
        assert np.all(np.isfinite(sample.cop_mm)) and np.all(sample.force_n > 0)


def test_buffers_carry_the_same_columns_and_the_centred_plateau_has_its_centre_in_the_middle():
    with taxel.Simulator(scene="gripper", speed=20.0) as sim:
        sim.start_buffering()
        time.sleep(0.6)  # 12 s of the scene: one whole grasp
        buffer = sim.read_buffer()
    count = len(buffer)
    assert buffer.cop_mm.shape == (count, 2, 2)
    assert buffer.contact.shape == (count, 2) and buffer.contact.dtype == np.bool_
    assert buffer.partial.shape == (count, 2) and buffer.missing.shape == (count, 2)
    assert buffer.force_n.shape == (count, 2)
    device_s = buffer.device_time_us / 1e6
    # 3.0 to 4.8 s: both fingers hold the object with 20 kPa on every taxel (the scene's
    # plateau): the centre of pressure is at the pad's centre and the force steady.
    plateau = (device_s > 3.0) & (device_s < 4.8)
    assert plateau.sum() > 50
    assert np.all(buffer.contact[plateau])
    assert not buffer.partial[plateau].any()
    assert np.nanmax(np.abs(buffer.cop_mm[plateau])) < 0.3
    force = buffer.force_n[plateau]
    assert np.all(force > 1.0) and np.ptp(force, axis=0).max() < 0.1 * force.mean()
    # Before the grasp there is no contact, no centre and no force.
    before = device_s < 1.4
    assert not buffer.contact[before].any()
    assert np.isnan(buffer.cop_mm[before]).all()
    # 5 to 7 s: the object slips down, the load moves from the top row (c11, c12) to the
    # bottom row (c21, c22): the centre moves along one axis.
    early = (device_s > 5.2) & (device_s < 5.5)
    late = (device_s > 6.5) & (device_s < 6.9)
    shift = np.nanmean(buffer.cop_mm[late, 0], axis=0) - np.nanmean(buffer.cop_mm[early, 0], axis=0)
    assert np.max(np.abs(shift)) > 0.5


def test_events_say_when_contact_starts_and_ends_and_match_the_contact_column():
    with taxel.Simulator(scene="gripper", speed=20.0) as sim:
        sim.start_buffering()
        time.sleep(0.8)
        buffer = sim.read_buffer()
        events = sim.events()
        assert sim.events() == [], "events() returns each event once"
    kinds = [(event.kind, event.pad) for event in events]
    assert ("tare_finished", 0) in kinds and ("tare_finished", 1) in kinds
    tare = next(event for event in events if event.kind == "tare_finished")
    assert tare.fields["tared"] == ["c11", "c12", "c21", "c22"] and tare.fields["tared_mask"] == 15
    assert "new baselines" in tare.text
    for pad in (0, 1):
        changes = [event for event in events if event.pad == pad and event.kind.startswith("contact")]
        assert [event.kind for event in changes][:2] == ["contact_started", "contact_ended"]
        contact = buffer.contact[:, pad]
        flips = np.flatnonzero(np.diff(contact.astype(np.int8))) + 1
        # A contact event carries the device time of the set that confirmed it: the first
        # set whose contact column changed.
        flip_times = buffer.pad_device_time_us[flips, pad].tolist()
        assert [event.device_time_us for event in changes] == flip_times[: len(changes)]
        for event in changes:
            assert event.device == 0
            assert abs(event.host_time_s - time.time()) < 30


def test_events_are_kept_when_the_set_queue_overflows():
    # A caller who reads nothing: the queue of 8 sets drops its oldest sets, never an event.
    with taxel.Simulator(scene="gripper", speed=20.0, queue_sets=8) as sim:
        sim.read()
        time.sleep(1.4)  # 28 s of the scene: more than two grasps
        events = sim.events()
        stats = sim.stats
        assert stats["sets_dropped_unread"] > 100
        assert stats["events_dropped"] == 0
        # The sets kept are the newest, and the next one read says how many were dropped.
        assert sim.read().sets_missing_before > 100
    for pad in (0, 1):
        changes = [event.kind for event in events if event.pad == pad and event.kind.startswith("contact")]
        assert len(changes) >= 4
        assert changes == ["contact_started", "contact_ended"] * (len(changes) // 2) + (
            ["contact_started"] if len(changes) % 2 else []
        )
        times = [event.device_time_s for event in events if event.pad == pad and event.kind == "contact_started"]
        # One grasp per 12 s scene, each starting just after 1.5 s into it.
        assert all(1.5 < t % 12.0 < 2.5 for t in times), times


@pytest.fixture(scope="module")
def cli_gripper_recording(taxel_cli, tmp_path_factory):
    """`taxel record` of `taxel sim --scene gripper --seed 3` (the reference)."""
    directory = tmp_path_factory.mktemp("gripper")
    process, port = start_cli_simulator(taxel_cli, directory, "--scene", "gripper", "--seed", "3")
    try:
        path = directory / "rec.csv"
        subprocess.run(
            [taxel_cli, "record", port, "-o", str(path), "--samples", "700"],
            check=True, capture_output=True, timeout=120,
        )
    finally:
        process.terminate()
        process.wait(timeout=10)
    return taxel.read_recording(path)


def test_force_centre_and_contact_equal_what_taxel_record_writes(cli_gripper_recording):
    # The simulated device is deterministic for a scene and seed: the set of each sequence
    # number is the same in every run, so the package's sets and the command's rows of the
    # same sequence numbers must hold the same numbers, to the bit.
    recorded = cli_gripper_recording
    with taxel.Simulator(scene="gripper", seed=3, speed=5.0) as sim:
        sim.start_buffering()
        last = int(recorded.sequence.max())
        deadline = time.monotonic() + 60
        collected = []
        while not collected or collected[-1].sequence[-1] < last:
            assert time.monotonic() < deadline, "the simulator did not reach the recording's end"
            time.sleep(0.2)
            buffer = sim.read_buffer()
            if len(buffer):
                collected.append(buffer)
    by_sequence = {}
    for buffer in collected:
        for row, sequence in enumerate(buffer.sequence.tolist()):
            by_sequence[sequence] = (buffer, row)
    compared = 0
    contact_rows = 0
    for index in range(len(recorded)):
        sequence, pad = int(recorded.sequence[index]), int(recorded.pad[index])
        if sequence not in by_sequence:
            continue
        buffer, row = by_sequence[sequence]
        np.testing.assert_array_equal(buffer.force_n[row, pad], recorded.force_n[index])
        np.testing.assert_array_equal(buffer.cop_mm[row, pad], recorded.cop_mm[index])
        assert buffer.contact[row, pad] == recorded.contact[index]
        assert buffer.partial[row, pad] == recorded.partial[index]
        np.testing.assert_array_equal(buffer.pressure_kpa[row, 4 * pad:4 * pad + 4], recorded.pressure_kpa[index])
        compared += 1
        contact_rows += bool(recorded.contact[index])
    assert compared >= 1000, compared
    assert 0 < contact_rows < compared, "the comparison covers contact and no contact"
