"""`taxel.Device` on serial ports: against `taxel sim` on a pseudo-terminal (the same shapes as
`taxel.Simulator`), and the errors of ports that are missing, wrong or silent."""

import os
import subprocess
import time

import numpy as np
import pytest

import taxel
from interrupting import InterruptDuring


def start_cli_simulator(taxel_cli, tmp_path, *arguments):
    """`taxel sim` as a child process; returns it and the path of its terminal."""
    path_file = tmp_path / "port.txt"
    process = subprocess.Popen(
        [taxel_cli, "sim", "--path-file", str(path_file), "--speed", "5", *arguments],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 20
    while not path_file.exists():
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            raise AssertionError(f"taxel sim did not start: {process.stderr.read().decode()}")
        time.sleep(0.05)
    return process, path_file.read_text()


def shapes(sample):
    return {
        name: (getattr(sample, name).shape, getattr(sample, name).dtype)
        for name in ("pressure_kpa", "capacitance_pf", "flags", "temperature_c", "force_n")
    }


@pytest.mark.parametrize("scene", [None, "gripper"])
def test_device_on_the_cli_simulator_matches_the_simulator(taxel_cli, tmp_path, scene):
    arguments = [] if scene is None else ["--scene", scene]
    process, port = start_cli_simulator(taxel_cli, tmp_path, *arguments)
    try:
        with taxel.Device(port=port) as device:
            sample = device.read()
            sequences = [device.read().sequence for _ in range(20)]
            device_info = device.info
            device.start_buffering()
            time.sleep(0.3)
            # Shapes only: a starved reader on a busy machine may lose sets on a terminal.
            device_buffer = device.read_buffer(strict=False)
        with taxel.Simulator(scene=scene, speed=5.0) as sim:
            simulated = sim.read()
            simulator_info = sim.info
            sim.start_buffering()
            time.sleep(0.3)
            simulator_buffer = sim.read_buffer(strict=False)
    finally:
        process.terminate()
        process.wait(timeout=10)
    assert shapes(sample) == shapes(simulated)
    assert set(device_info) == set(simulator_info)
    assert device_info["pad_count"] == simulator_info["pad_count"]
    assert np.all(np.diff(sequences) >= 1)
    assert device_buffer.pressure_kpa.shape[1:] == simulator_buffer.pressure_kpa.shape[1:]
    assert device_buffer.temperature_c.shape[1:] == simulator_buffer.temperature_c.shape[1:]


def test_missing_and_wrong_ports(tmp_path):
    with pytest.raises(taxel.LinkError, match="does not exist"):
        taxel.Device(port=str(tmp_path / "nothing"))
    regular = tmp_path / "file"
    regular.write_text("")
    with pytest.raises(taxel.LinkError, match="is not a serial port \\(a regular file\\)"):
        taxel.Device(port=str(regular))
    with pytest.raises(ValueError, match="give port or serial"):
        taxel.Device(port="a", serial="b")


def test_no_board_with_that_serial_number():
    with pytest.raises(taxel.DeviceNotFoundError, match="no attached board has serial number"):
        taxel.Device(serial="NO-SUCH-BOARD")


def test_list_devices_returns_dicts():
    for board in taxel.list_devices():
        assert {"port", "serial_number", "vid", "pid"} <= set(board)


def test_a_silent_port_times_out_with_the_cli_message():
    controller, terminal = os.openpty()
    try:
        started = time.monotonic()
        with pytest.raises(taxel.DeviceTimeoutError, match="asking the device who it is: no reply to request 1 within 300 ms"):
            taxel.Device(port=os.ttyname(terminal), timeout=0.3)
        assert time.monotonic() - started < 3
    finally:
        os.close(controller)
        os.close(terminal)


def test_ctrl_c_interrupts_a_blocking_call():
    controller, terminal = os.openpty()
    try:
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            with InterruptDuring(0.3) as interrupt:
                taxel.Device(port=os.ttyname(terminal), timeout=30)
        assert interrupt.sent, "a device that never answers connected"
        assert time.monotonic() - started < 3
    finally:
        os.close(controller)
        os.close(terminal)
