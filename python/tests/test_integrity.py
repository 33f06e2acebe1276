"""The data-integrity guarantees a researcher relies on without checking: any array layout or
type gives the same numbers (or a clear refusal), flags read from any integer, closing from
anywhere ends a blocked read, every wait is bounded, and nothing collected is lost to an
exception."""

import signal
import subprocess
import threading
import time

import numpy as np
import pandas as pd
import pytest

import taxel
from interrupting import InterruptDuring
from test_device import start_cli_simulator

# A pad's reference loads: several unloaded rows, then increasing loads; each taxel has its own
# curve, so reading the (N, 4) array column by column gives numbers that are not a calibration.
LOADS_KPA = np.array([0, 0, 0, 0, 2, 5, 10, 15, 20, 30, 40, 50], dtype=np.int64)


def capacitances(loads_kpa):
    return np.stack(
        [4.5 * (1 + 0.35 * (1 - np.exp(-loads_kpa / (12.0 + 6 * k)))) + 0.01 * k for k in range(4)],
        axis=1,
    )


def fitted(pressure, capacitance, **keywords):
    return taxel.Calibration.fit(pressure, capacitance, **keywords).to_json()


def test_fit_gives_the_same_calibration_for_every_layout_and_type():
    capacitance = capacitances(LOADS_KPA.astype(float))
    reference = fitted(LOADS_KPA.astype(np.float64), np.ascontiguousarray(capacitance))
    frame = pd.DataFrame(capacitance, columns=["c11_pf", "c12_pf", "c21_pf", "c22_pf"])
    frame["load_kpa"] = LOADS_KPA
    doubled = np.repeat(capacitance, 2, axis=0)
    variants = {
        "Fortran order (DataFrame.to_numpy())": (LOADS_KPA.astype(float), np.asfortranarray(capacitance)),
        "int64 loads": (LOADS_KPA, capacitance),
        "lists": (LOADS_KPA.tolist(), capacitance.tolist()),
        "pandas columns": (frame["load_kpa"], frame[["c11_pf", "c12_pf", "c21_pf", "c22_pf"]]),
        "pandas to_numpy": (frame["load_kpa"].to_numpy(), frame[["c11_pf", "c12_pf", "c21_pf", "c22_pf"]].to_numpy()),
        "strided rows": (np.repeat(LOADS_KPA, 2)[::2], doubled[::2]),
    }
    assert frame[["c11_pf", "c12_pf", "c21_pf", "c22_pf"]].to_numpy().flags.f_contiguous
    for name, (pressure, capacitance_pf) in variants.items():
        assert fitted(pressure, capacitance_pf) == reference, name
    # float32 input is taken at its float32 values: the same as converting it first.
    as_float32 = capacitance.astype(np.float32)
    assert fitted(LOADS_KPA, as_float32) == fitted(LOADS_KPA, as_float32.astype(np.float64))
    with_temperature = fitted(LOADS_KPA, capacitance, temp_c=pd.Series(np.full(len(LOADS_KPA), 25.0)))
    assert with_temperature == fitted(LOADS_KPA, capacitance, temp_c=[25.0] * len(LOADS_KPA))


def test_fit_refuses_what_is_not_numbers_or_has_the_wrong_shape():
    capacitance = capacitances(LOADS_KPA.astype(float))
    with pytest.raises(taxel.CalibrationError, match="capacitance_pf cannot be read as an array of numbers"):
        taxel.Calibration.fit(LOADS_KPA, [["a", "b", "c", "d"]] * len(LOADS_KPA))
    with pytest.raises(taxel.CalibrationError, match="capacitance_pf must have 2 dimension"):
        taxel.Calibration.fit(LOADS_KPA, capacitance.ravel())
    with pytest.raises(taxel.CalibrationError, match="pressure_kpa must have 1 dimension"):
        taxel.Calibration.fit(LOADS_KPA[:, None], capacitance)


def test_convert_gives_the_same_numbers_for_every_layout_and_type():
    rng = np.random.default_rng(7)
    rows = 500
    capacitance = 4.5 + np.abs(rng.normal(0, 0.4, size=(rows, 8)))
    capacitance[:20] = 4.5
    temperature = np.full((rows, 2), 25.0) + rng.normal(0, 0.1, size=(rows, 2))
    reference = taxel.convert(capacitance, temperature, tare_rows=10)
    frame = pd.DataFrame(capacitance)
    for name, (cap, temp) in {
        "Fortran order": (np.asfortranarray(capacitance), np.asfortranarray(temperature)),
        "pandas": (frame, pd.DataFrame(temperature)),
        "lists": (capacitance.tolist(), temperature.tolist()),
        "strided": (np.repeat(capacitance, 2, axis=0)[::2], np.repeat(temperature, 2, axis=0)[::2]),
    }.items():
        pressure, flags = taxel.convert(cap, temp, tare_rows=10)
        np.testing.assert_array_equal(pressure, reference[0], err_msg=name)
        np.testing.assert_array_equal(flags, reference[1], err_msg=name)


def test_flags_read_any_integer_even_zero():
    for value in (np.uint16(0), np.uint16(129), np.int64(4), 0, 129):
        assert int(taxel.Flags(value)) == int(value)
    assert taxel.Flags(np.uint16(0)) == taxel.Flags(0)
    assert taxel.Flags(np.uint16(129)) == taxel.Flags.BELOW_BASELINE | taxel.Flags.NOT_TARED
    with pytest.raises(ValueError):
        taxel.Flags("SHORTED")
    with taxel.Simulator() as device:
        sample = device.read()
        names = [taxel.Flags(flag) for flag in sample.flags]
        assert [int(flag) for flag in names] == sample.flags.tolist()


def blocked_read_ends(device, close):
    """Starts `close` 0.3 s into a read that would wait 30 s; returns the exception and how long
    the read took."""
    started = time.monotonic()
    with pytest.raises(taxel.LinkError, match="the device is closed") as raised:
        close()
        while True:
            device.read(timeout=30)
    return raised.value, time.monotonic() - started


def test_close_from_another_thread_ends_a_blocked_read():
    # A slow simulator: a set every few seconds, so the read is waiting when close() comes.
    device = taxel.Simulator(speed=0.5, timeout=20)
    device.read(timeout=20)
    timer = threading.Timer(0.3, device.close)
    _, elapsed = blocked_read_ends(device, timer.start)
    timer.join()
    assert elapsed < 3, f"the read ended {elapsed:.2f} s after it began"
    assert device.closed


def test_close_from_a_signal_handler_ends_a_blocked_read():
    device = taxel.Simulator(speed=0.5, timeout=20)
    device.read(timeout=20)
    previous = signal.signal(signal.SIGALRM, lambda *_: device.close())
    try:
        _, elapsed = blocked_read_ends(device, lambda: signal.setitimer(signal.ITIMER_REAL, 0.3))
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert elapsed < 3


def test_a_slow_simulator_never_waits_beyond_its_timeout():
    started = time.monotonic()
    with pytest.raises(taxel.DeviceTimeoutError, match="within 1000 ms"):
        taxel.Simulator(speed=1e-4, timeout=1.0)
    assert time.monotonic() - started < 2.5
    started = time.monotonic()
    try:
        taxel.Simulator(speed=0.01, timeout=2.0).close()
    except taxel.DeviceTimeoutError:
        pass
    assert time.monotonic() - started < 3.5


def test_ctrl_c_interrupts_a_slow_simulator():
    # At 1e-9 simulated seconds per second the device answers its first request at most: the
    # connection cannot finish before the interrupt.
    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        with InterruptDuring(0.3) as interrupt:
            taxel.Simulator(speed=1e-9, timeout=60)
    assert interrupt.sent, "the slow simulator connected before Ctrl-C"
    assert time.monotonic() - started < 3


def test_unplugging_while_buffering_keeps_what_was_collected(taxel_cli, tmp_path):
    process, port = start_cli_simulator(taxel_cli, tmp_path)
    try:
        device = taxel.Device(port=port)
        device.start_buffering()
        time.sleep(0.8)
    finally:
        process.kill()
        process.wait(timeout=10)
    # The buffer thread sees the link fail within its read timeout; the first read after that
    # must raise and carry every set collected before the failure.
    time.sleep(1.5)
    with pytest.raises(taxel.LinkError) as raised:
        device.read_buffer(strict=False)
    kept = raised.value.buffer
    assert kept is not None and len(kept) > 20, "the sets collected before the unplug were lost"
    assert np.all(np.diff(kept.sequence) == 1)
    # Every later call says the same, with nothing new.
    with pytest.raises(taxel.LinkError) as again:
        device.read_buffer()
    assert len(again.value.buffer) == 0
    device.close()


def test_stop_buffering_returns_what_was_not_read():
    with taxel.Simulator(speed=5.0) as device:
        device.start_buffering()
        time.sleep(0.3)
        rest = device.stop_buffering()
        assert len(rest) > 0
        assert np.all(np.diff(rest.sequence) == 1)
        after = device.read()
        assert after.sequence > rest.sequence[-1]


def test_host_time_is_the_arrival_and_latest_is_the_newest_set():
    with taxel.Simulator(speed=1.0) as device:
        device.read()
        time.sleep(1.0)
        # A slow loop: the oldest queued set arrived about a second ago, and says so.
        oldest = device.read()
        assert time.time() - oldest.host_time_s > 0.7
        newest = device.latest()
        assert time.time() - newest.host_time_s < 0.3
        assert newest.sequence > oldest.sequence + 10
        assert not newest.missing_pads
        # After latest(), read() continues from the newest on.
        following = device.read()
        assert following.sequence > newest.sequence


def test_the_version_and_the_simulators_default_seed_are_the_command_lines(taxel_cli, tmp_path):
    import importlib.metadata

    assert taxel.__version__ == importlib.metadata.version("taxel")
    version = subprocess.run([taxel_cli, "--version"], capture_output=True, text=True)
    assert version.stdout.split()[-1] == taxel.__version__
    process, port = start_cli_simulator(taxel_cli, tmp_path)
    try:
        with taxel.Device(port=port) as device:
            cli_serial = device.info["board_serial"]
    finally:
        process.terminate()
        process.wait(timeout=10)
    with taxel.Simulator() as simulator:
        assert simulator.info["board_serial"] == cli_serial
