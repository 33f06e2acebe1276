"""Several devices on one host timeline (`taxel.Devices`): one host-library worker reads them
all, each set is stamped by the host library's stamping policy (the recorder's: the device
clock mapped onto the host's, never after the arrival, with an error bound), and the sets of
every device come out in host-time order."""

import time

import numpy as np
import pandas as pd
import pytest

import taxel
from test_device import start_cli_simulator


def test_two_simulators_on_one_timeline():
    boards = [taxel.SimulatedBoard(scene="gripper", speed=5.0), taxel.SimulatedBoard(seed=2, speed=5.0)]
    with taxel.Devices(boards) as devices:
        assert len(devices) == 2
        assert devices.pads == [2, 1] and devices.taxels == [8, 4]
        serials = [info["board_serial"] for info in devices.info]
        assert len(set(serials)) == 2
        sets = [devices.read() for _ in range(400)]
        read_at = time.time()
    host_times = np.array([sample.host_time_s for sample in sets])
    assert np.all(np.diff(host_times) >= 0), "merged in host-time order"
    assert host_times[-1] <= read_at
    device_of = np.array([sample.device for sample in sets])
    assert {0, 1} <= set(device_of.tolist())
    for device, pads in ((0, 2), (1, 1)):
        mine = [sample for sample in sets if sample.device == device]
        assert all(sample.pressure_kpa.shape == (4 * pads,) for sample in mine)
        assert np.all(np.diff([sample.sequence for sample in mine]) == 1)
        # Every set waited for its device's clock estimate: all are mapped, with a bound.
        errors = np.array([sample.sync_error_ms for sample in mine])
        assert np.all(np.isfinite(errors)) and np.all(errors < 50)
        # The mapping is the device clock (at 5 times real time) onto the host's: host time
        # minus device time / 5 is the same for every set, within the error bound.
        offset = np.array([s.host_time_s - s.device_time_s / 5.0 for s in mine])
        assert np.ptp(offset) * 1e3 < 2 * errors.max() + 2.0


def test_buffers_events_tare_and_pandas_of_several_devices(tmp_path):
    boards = [taxel.SimulatedBoard(scene="gripper", speed=10.0), taxel.SimulatedBoard(speed=10.0, seed=5)]
    with taxel.Devices(boards) as devices:
        devices.start_buffering()
        time.sleep(2.5)
        buffers = devices.read_buffer()
        devices.stop_buffering()
        events = devices.events()
        stats = devices.stats
    assert [buffer.device for buffer in buffers] == [0, 1]
    assert [buffer.pads for buffer in buffers] == [2, 1]
    assert buffers[0].pressure_kpa.shape[1] == 8 and buffers[1].cop_mm.shape[1:] == (1, 2)
    assert all(len(buffer) > 50 and buffer.lost_sets == 0 for buffer in buffers)
    assert all(np.isfinite(buffer.sync_error_ms).all() for buffer in buffers)
    # Both devices' tares at boot are reported, each by its device.
    tared = {(event.device, event.pad) for event in events if event.kind == "tare_finished"}
    assert {(0, 0), (0, 1), (1, 0)} <= tared
    assert all(entry["sets_delivered"] >= len(buffer) for entry, buffer in zip(stats, buffers))
    assert all(entry["sets_dropped_unread"] == 0 and entry["sequence_gap_frames"] == 0 for entry in stats)
    # One long table of both devices, in host-time order: the recording schema's.
    frame = pd.concat([buffer.to_pandas() for buffer in buffers]).sort_values("host_time_s", kind="stable")
    assert set(zip(frame["device"], frame["pad"])) == {(0, 0), (0, 1), (1, 0)}
    assert frame["sync_error_ms"].notna().all()


def test_a_tare_of_every_device_and_of_one():
    # Real time: the scenes are unloaded for their first 1.5 s, so the devices accept a tare.
    boards = [taxel.SimulatedBoard(scene="gripper"), taxel.SimulatedBoard(seed=5)]
    with taxel.Devices(boards) as devices:
        time.sleep(0.4)  # the tare at boot (16 sets) is over
        devices.tare(sample_sets=8)
        devices.tare(sample_sets=8, device=1)
        devices.tare(sample_sets=8, device=0, pad=1)
        with pytest.raises(ValueError, match="there is no device 2"):
            devices.tare(device=2)
        with pytest.raises(ValueError, match="there is no pad 2"):
            devices.tare(device=0, pad=2)
        with pytest.raises(ValueError, match="give device="):
            devices.tare(pad=0)
        # A tare's reply and its TareFinished events travel separately: take events until every
        # one expected has come (or 5 s).
        events = []
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            events += devices.events()
            finished = [(e.device, e.pad) for e in events if e.kind == "tare_finished"]
            if finished.count((1, 0)) >= 3 and finished.count((0, 1)) >= 3:
                break
            time.sleep(0.05)
    finished = [(event.device, event.pad) for event in events if event.kind == "tare_finished"]
    # At boot, then the tare of every device, then device 1's, then device 0's pad 1 alone.
    assert finished.count((0, 0)) == 2 and finished.count((0, 1)) == 3, finished
    assert finished.count((1, 0)) == 3, finished


def test_devices_read_a_serial_port_and_a_simulator_together(taxel_cli, tmp_path):
    process, port = start_cli_simulator(taxel_cli, tmp_path)
    try:
        with taxel.Devices([port, taxel.SimulatedBoard(speed=5.0, seed=9)]) as devices:
            assert devices.info[0]["port"] == port
            sets = [devices.read() for _ in range(300)]
    finally:
        process.terminate()
        process.wait(timeout=10)
    assert {sample.device for sample in sets} == {0, 1}
    assert np.all(np.diff([sample.host_time_s for sample in sets]) >= 0)


def test_bad_sources_are_refused_and_close_ends_a_read():
    with pytest.raises(ValueError, match="at least one device"):
        taxel.Devices([])
    with pytest.raises(ValueError, match="serial port's path or a taxel.SimulatedBoard"):
        taxel.Devices([42])
    with pytest.raises(taxel.LinkError, match="does not exist"):
        taxel.Devices([taxel.SimulatedBoard(), "/dev/no-such-port"])
    devices = taxel.Devices([taxel.SimulatedBoard(speed=5.0)])
    devices.close()
    devices.close()
    with pytest.raises(taxel.LinkError, match="the device is closed"):
        devices.read()
    assert devices.closed
