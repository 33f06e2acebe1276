"""The simulated device through the package: shapes, streaming without gaps at real time and
faster, the background buffer, losses reported, commands."""

import time

import numpy as np
import pytest

import taxel


def read_for(device, seconds):
    """Every sample set read during `seconds` of wall-clock time."""
    sets = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sets.append(device.read())
    return sets


def assert_consecutive(sequences):
    sequences = np.asarray(sequences, dtype=np.int64)
    assert len(sequences) > 1
    assert np.all(np.diff(sequences) == 1), np.diff(sequences)


def test_one_pad_sample_set_shapes_and_types():
    with taxel.Simulator() as sim:
        assert sim.pads == 1 and sim.taxels == 4
        sample = sim.read()
        assert sample.pressure_kpa.shape == (4,)
        assert sample.capacitance_pf.shape == (4,)
        assert sample.flags.shape == (4,) and sample.flags.dtype == np.uint16
        assert sample.temperature_c.shape == (1,)
        assert sample.force_n.shape == (1,)
        assert sample.temperature_source[0] in ("tmp117", "mcu_internal", "last_known", "none")
        assert np.all(np.isfinite(sample.capacitance_pf))
        assert sample.device_time_us > 0
        assert abs(sample.host_time_s - time.time()) < 5
        info = sim.info
        assert info["pad_count"] == 1
        assert info["board_serial"]
        assert info["tier"] in taxel.TIERS
        assert info["rate_sps"] in (100, 200, 400)


def test_several_pads_give_the_same_shape_family():
    with taxel.Simulator(scene="gripper") as sim:
        assert sim.pads == 2 and sim.taxels == 8
        sample = sim.read()
        assert sample.pressure_kpa.shape == (8,)
        assert sample.temperature_c.shape == (2,)
        assert sample.missing_pads == []
    with taxel.Simulator(pads=3) as sim:
        assert sim.read().capacitance_pf.shape == (12,)


@pytest.mark.parametrize("speed", [1.0, 20.0])
def test_streaming_has_no_gaps(speed):
    with taxel.Simulator(speed=speed) as sim:
        sets = read_for(sim, 1.5)
        assert_consecutive([s.sequence for s in sets])
        assert all(s.sets_missing_before == 0 for s in sets)
        device_times = np.array([s.device_time_us for s in sets], dtype=np.float64)
        assert np.all(np.diff(device_times) > 0)
        simulated_s = (device_times[-1] - device_times[0]) / 1e6
        # The device's clock runs `speed` times faster than the wall clock.
        assert 0.5 * speed < simulated_s / 1.5 < 1.5 * speed
        stats = sim.stats
        assert stats["sequence_gap_frames"] == 0
        assert stats["lost_on_link_frames"] == 0
        assert stats["sets_delivered"] == len(sets)


def test_iteration_yields_sample_sets():
    with taxel.Simulator(speed=10.0) as sim:
        sequences = []
        for sample in sim:
            sequences.append(sample.sequence)
            if len(sequences) == 20:
                break
        assert_consecutive(sequences)
    assert sim.closed
    assert list(sim) == []


def test_buffering_collects_arrays_without_loss():
    with taxel.Simulator(speed=10.0) as sim:
        sim.start_buffering()
        time.sleep(1.0)
        buffer = sim.read_buffer()
        count = len(buffer)
        assert count > 100
        assert buffer.pressure_kpa.shape == (count, 4)
        assert buffer.capacitance_pf.shape == (count, 4)
        assert buffer.flags.shape == (count, 4)
        assert buffer.temperature_c.shape == (count, 1)
        assert buffer.device_time_us.shape == (count,)
        assert buffer.host_time_s.shape == (count,)
        assert buffer.overflowed_sets == 0 and buffer.sequence_gap_sets == 0
        assert_consecutive(buffer.sequence)
        time.sleep(0.2)
        following = sim.read_buffer()
        assert following.sequence[0] == buffer.sequence[-1] + 1
        with pytest.raises(taxel.TaxelError, match="while buffering"):
            sim.read()


def test_buffering_shape_of_several_pads():
    with taxel.Simulator(scene="glove", speed=10.0) as sim:
        sim.start_buffering()
        time.sleep(0.5)
        buffer = sim.read_buffer()
        assert buffer.pads == 6
        assert buffer.pressure_kpa.shape == (len(buffer), 24)
        assert buffer.temperature_c.shape == (len(buffer), 6)


def test_a_full_buffer_is_reported():
    with taxel.Simulator(speed=20.0) as sim:
        sim.start_buffering(capacity_sets=10)
        time.sleep(0.5)
        with pytest.raises(taxel.DataLossError, match="buffer of 10 sets was full") as raised:
            sim.read_buffer()
        kept = raised.value.buffer
        assert len(kept) == 10
        assert kept.overflowed_sets > 0
        assert kept.lost_sets == kept.overflowed_sets
        time.sleep(0.3)
        relaxed = sim.read_buffer(strict=False)
        assert len(relaxed) == 10 and relaxed.overflowed_sets > 0


def test_sets_nobody_read_are_dropped_counted_and_the_next_set_says_so():
    # A reader that does not keep up with a queue of 50 sets: the oldest are dropped, and the
    # first set read after them says how many are missing before it.
    with taxel.Simulator(speed=None, queue_sets=50) as sim:
        sim.read()
        time.sleep(0.5)
        sets = [sim.read() for _ in range(60)]
        gaps = [s.sets_missing_before for s in sets]
        assert gaps[0] > 0
        # The queue keeps dropping while the simulator runs flat out: what was dropped (by the
        # queue, the device or the link; one pad, so frames are sets) is at least what these
        # reads say is missing.
        stats = sim.stats
        dropped = stats["sets_dropped_unread"] + stats["device_dropped_frames"] + stats["lost_on_link_frames"]
        assert dropped >= sum(gaps) > 0
        sequences = [s.sequence for s in sets]
        for previous, current, gap in zip(sequences, sequences[1:], gaps[1:]):
            assert current - previous == gap + 1


def test_a_gap_while_buffering_raises_data_loss():
    with taxel.Simulator(speed=None, link_buffer_bytes=4096) as sim:
        sim.start_buffering(capacity_sets=1_000_000)
        time.sleep(0.5)
        try:
            buffer = sim.read_buffer()
        except taxel.DataLossError as error:
            assert "missing from the sequence numbers" in str(error)
            assert error.buffer.sequence_gap_sets > 0
        else:
            # The host kept up with the simulated device running flat out: then nothing is lost.
            assert buffer.lost_sets == 0
            assert_consecutive(buffer.sequence)


def test_commands():
    with taxel.Simulator(speed=20.0) as sim:
        sim.tare(sample_sets=8)
        sim.set_rate(200)
        assert sim.info["rate_sps"] == 200
        with pytest.raises(ValueError, match="rate 123 S/s is not supported"):
            sim.set_rate(123)
        sim.set_tier("linear")
        assert sim.info["tier"] == "linear"
        with pytest.raises(ValueError, match="unknown tier 'nope'; valid tiers: linear"):
            sim.set_tier("nope")
        chosen = sim.set_use_case("gripper")
        assert chosen in taxel.TIERS and sim.info["tier"] == chosen
        with pytest.raises(ValueError, match="unknown use case"):
            sim.set_use_case("juggling")
        factory = sim.read_calibration()
        assert factory.id == sim.info["calibration_id"] == 1
        sim.write_calibration(taxel.Calibration.default())
        assert sim.info["calibration_source"] == "host"
        assert sim.read_calibration().to_json() == taxel.Calibration.default().to_json()
        sim.save_calibration()
        sim.restore_defaults()
        counters = sim.read_counters()
        assert set(counters) >= {"dropped_sample_frames", "i2c_errors"}
        with pytest.raises(ValueError, match="the device reads 1 pad: there is no pad 3"):
            sim.read_calibration(pad=3)
        # Samples kept flowing through the commands, without gaps.
        assert_consecutive([sim.read().sequence for _ in range(10)])


def test_per_pad_calibration_on_several_pads():
    with taxel.Simulator(scene="gripper", speed=20.0) as sim:
        sim.write_calibration(taxel.Calibration.default(), pad=1)
        assert sim.read_calibration(pad=1).to_json() == taxel.Calibration.default().to_json()
        assert sim.read_calibration(pad=0).id == 1


def test_closed_device_and_bad_arguments():
    sim = taxel.Simulator()
    sim.close()
    sim.close()
    with pytest.raises(taxel.LinkError, match="the device is closed"):
        sim.read()
    with pytest.raises(taxel.TaxelError, match="no scene file nope"):
        taxel.Simulator(scene="nope")
    with pytest.raises(ValueError, match="speed must be a positive number"):
        taxel.Simulator(speed=0)
    with pytest.raises(ValueError, match="timeout must be a positive number"):
        taxel.Simulator(timeout=-1)


HELD_SCENE = """
name = "two pads held"
repeat = false
{pads}
"""

HELD_PAD = """
[[pad]]
name = "pad {pad}"
[[pad.keyframe]]
time_s = 0.0
pressure_kpa = [0.0, 0.0, 0.0, 0.0]
temperature_c = 25.0
[[pad.keyframe]]
time_s = 0.8
pressure_kpa = [0.0, 0.0, 0.0, 0.0]
temperature_c = 25.0
[[pad.keyframe]]
time_s = 1.0
pressure_kpa = [4.0, 4.0, 4.0, 4.0]
temperature_c = 25.0
[[pad.keyframe]]
time_s = 1000.0
pressure_kpa = [4.0, 4.0, 4.0, 4.0]
temperature_c = 25.0
"""


def tare_events_within(sim, seconds, until=None):
    """The (kind, pad) of the tare events `sim.events()` gives within `seconds`, or until `until`
    is among them."""
    found = []
    deadline = time.monotonic() + seconds
    while True:
        found += [(event.kind, event.pad) for event in sim.events() if event.kind.startswith("tare")]
        if until in found or time.monotonic() >= deadline:
            return found
        time.sleep(0.02)


def test_a_tare_of_one_pad_leaves_the_other_pads_alone(tmp_path):
    # Both pads unloaded for the tare at power-on, then pressed with 4 kPa and held still: a
    # tare takes the held load as the tared pad's zero, so each pad's pressure shows whether
    # that pad was tared.
    scene = tmp_path / "held.toml"
    scene.write_text(HELD_SCENE.format(pads="".join(HELD_PAD.format(pad=pad) for pad in (0, 1))))
    with taxel.Simulator(scene=str(scene), speed=5.0) as sim:
        assert sim.pads == 2
        sample = sim.read()
        while sample.device_time_s < 1.5:
            sample = sim.read()
        np.testing.assert_allclose(sample.pressure_kpa, 4.0, atol=0.5)
        sim.events()
        sim.tare(sample_sets=8, pad=1)
        # The device sends the tare's events before its reply, but they reach `events()` through
        # the reading thread, which may hand them over just after the reply came back.
        tares = tare_events_within(sim, 2.0, until=("tare_finished", 1))
        time.sleep(0.2)
        tares += tare_events_within(sim, 0.0)
        assert tares == [("tare_finished", 1)]
        time.sleep(0.2)
        pressures = sim.latest().pressure_kpa
        np.testing.assert_allclose(pressures[:4], 4.0, atol=0.5, err_msg="pad 0 keeps its baseline")
        np.testing.assert_allclose(pressures[4:], 0.0, atol=0.5, err_msg="pad 1 was tared under the load")

        with pytest.raises(ValueError, match="there is no pad 2"):
            sim.tare(sample_sets=8, pad=2)
        sim.tare(sample_sets=8)
        time.sleep(0.2)
        np.testing.assert_allclose(sim.latest().pressure_kpa, 0.0, atol=0.5)
