"""`taxel.convert` gives the numbers `taxel convert` gives for the same data, and refuses bad
input with clear messages."""

import csv
import subprocess
import time

import numpy as np
import pytest

import taxel


@pytest.fixture(scope="module")
def recording():
    """Capacitances, temperatures and times recorded from the simulated device (the demo
    scene: presses, a slide, warming, a short)."""
    with taxel.Simulator(speed=50.0, seed=3) as sim:
        sim.start_buffering()
        time.sleep(1.5)
        buffer = sim.read_buffer(strict=False)
    capacitance = buffer.capacitance_pf.copy()
    temperature = buffer.temperature_c[:, 0].copy()
    time_s = (buffer.device_time_us - buffer.device_time_us[0]) / 1e6
    # Holes the CLI reads as empty cells: no reading, no temperature.
    capacitance[10, 2] = np.nan
    temperature[20] = np.nan
    return capacitance, temperature, time_s


def micros(seconds):
    """Seconds with 6 decimals, as `taxel.convert` reads `time_s` (truncated to µs)."""
    whole_us = int(float(seconds) * 1e6)
    return f"{whole_us // 1_000_000}.{whole_us % 1_000_000:06d}"


def cell(value):
    return "" if np.isnan(value) else repr(float(np.float32(value)))


def write_recording(path, capacitance, temperature, time_s, sequence=None):
    """The data as a recording of the schema (device 0, pads side by side in `capacitance`,
    one temperature per pad); a pad whose four capacitances and temperature are all NaN is its
    frame missing from that set (a row with the set's identity only)."""
    rows, taxels = capacitance.shape
    pads = taxels // 4
    temperature = temperature.reshape(rows, -1)
    with path.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(taxel_header())
        for row in range(rows):
            seq = row if sequence is None else int(sequence[row])
            for pad in range(pads):
                caps = capacitance[row, 4 * pad : 4 * pad + 4]
                temp = temperature[row, min(pad, temperature.shape[1] - 1)]
                identity = [micros(time_s[row]), "0", str(pad), str(seq)]
                if pads > 1 and np.all(np.isnan(caps)) and np.isnan(temp):
                    writer.writerow(identity + [""] * 22)
                    continue
                writer.writerow(
                    identity
                    + [micros(time_s[row]), "", cell(temp), "none" if np.isnan(temp) else "tmp117"]
                    + [cell(value) for value in caps]
                    + [""] * 8 + ["", "", "", "0", "0", ""]
                )


def taxel_header():
    return (
        "host_time_s,device,pad,seq,device_time_s,sync_error_ms,temp_c,temp_source,"
        "c11_pf,c12_pf,c21_pf,c22_pf,p11_kpa,p12_kpa,p21_kpa,p22_kpa,"
        "flags11,flags12,flags21,flags22,force_n,cop_x_mm,cop_y_mm,partial,contact,marker"
    ).split(",")


def cli_convert(taxel_cli, tmp_path, capacitance, temperature, time_s, *arguments, sequence=None):
    """Writes the data as a recording of the schema, runs `taxel convert` on it and returns its
    pressures and flags as (N, taxels) arrays, and its messages."""
    source = tmp_path / "input.csv"
    write_recording(source, capacitance, temperature, time_s, sequence)
    output = tmp_path / "output.csv"
    result = subprocess.run(
        [taxel_cli, "convert", str(source), "-o", str(output), "--no-device-state", *arguments],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    converted = taxel.read_recording(output)
    rows, taxels = capacitance.shape
    pads = taxels // 4
    pressure = converted.pressure_kpa.reshape(rows, pads * 4)
    flags = converted.flags.reshape(rows, pads * 4)
    return pressure, flags, result.stderr


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"tier": "linear"},
        {"tier": "polynomial", "tare_rows": 5},
        {"tier": "table", "tare_rows": 50},
    ],
)
def test_convert_equals_the_cli(taxel_cli, tmp_path, recording, options):
    capacitance, temperature, time_s = recording
    arguments = []
    if "tier" in options:
        arguments += ["--tier", options["tier"]]
    if "tare_rows" in options:
        arguments += ["--tare-rows", str(options["tare_rows"])]
    expected_pressure, expected_flags, _ = cli_convert(
        taxel_cli, tmp_path, capacitance, temperature, time_s, *arguments
    )
    pressure, flags = taxel.convert(capacitance, temperature, time_s=time_s, **options)
    assert pressure.shape == capacitance.shape and pressure.dtype == np.float64
    assert flags.shape == capacitance.shape and flags.dtype == np.uint16
    np.testing.assert_array_equal(pressure, expected_pressure)
    np.testing.assert_array_equal(flags, expected_flags)
    assert np.any(pressure > 1.0), "the recording has presses"
    assert np.any(flags & taxel.Flags.NOT_TARED)


def test_convert_with_a_calibration_file_equals_the_cli(taxel_cli, tmp_path, recording):
    capacitance, temperature, time_s = recording
    with taxel.Simulator(speed=None) as sim:
        factory = sim.read_calibration()
    path = tmp_path / "factory.json"
    factory.save(path)
    expected_pressure, expected_flags, _ = cli_convert(
        taxel_cli, tmp_path, capacitance, temperature, time_s, "--calibration", str(path)
    )
    pressure, flags = taxel.convert(
        capacitance, temperature, calibration=taxel.Calibration.load(path), time_s=time_s
    )
    np.testing.assert_array_equal(pressure, expected_pressure)
    np.testing.assert_array_equal(flags, expected_flags)


def test_several_pads_are_converted_each_with_its_own_model(recording):
    capacitance, temperature, time_s = recording
    other = capacitance[::-1].copy()
    both = np.hstack([capacitance, other])
    temperatures = np.stack([temperature, temperature[::-1]], axis=1)
    pressure, flags = taxel.convert(both, temperatures, time_s=time_s, tare_rows=3)
    assert pressure.shape == (len(time_s), 8)
    first, first_flags = taxel.convert(capacitance, temperature, time_s=time_s, tare_rows=3)
    second, second_flags = taxel.convert(other, temperature[::-1], time_s=time_s, tare_rows=3)
    np.testing.assert_array_equal(pressure, np.hstack([first, second]))
    np.testing.assert_array_equal(flags, np.hstack([first_flags, second_flags]))


def test_one_temperature_column_serves_every_pad(recording):
    capacitance, temperature, _ = recording
    both = np.hstack([capacitance, capacitance])
    shared, _ = taxel.convert(both, temperature)
    separate, _ = taxel.convert(both, np.stack([temperature, temperature], axis=1))
    np.testing.assert_array_equal(shared, separate)


def test_bad_input_raises_clear_errors(taxel_cli, recording):
    capacitance, temperature, _ = recording
    with pytest.raises(taxel.ConvertError, match="it needs 4 per pad"):
        taxel.convert(capacitance[:, :3], temperature)
    with pytest.raises(taxel.ConvertError, match="must have shape \\(N, taxels\\)"):
        taxel.convert(capacitance[0], temperature[:1])
    with pytest.raises(taxel.ConvertError, match="temp_c has shape"):
        taxel.convert(capacitance, temperature[:-1])
    with pytest.raises(taxel.ConvertError, match="no rows"):
        taxel.convert(np.zeros((0, 4)), np.zeros(0))
    with pytest.raises(taxel.ConvertError, match="tare_rows must be 1 to 65535"):
        taxel.convert(capacitance, temperature, tare_rows=0)
    with pytest.raises(ValueError, match="time_s\\[1\\] is NaN: a time is a finite, non-negative number"):
        taxel.convert(capacitance[:3], temperature[:3], time_s=[0.0, np.nan, 1.0])
    with pytest.raises(taxel.ConvertError, match="time_s\\[2\\] is -1: a time is a finite, non-negative"):
        taxel.convert(capacitance[:3], temperature[:3], time_s=[0.0, 0.5, -1.0])
    with pytest.raises(taxel.ConvertError) as raised:
        taxel.convert(capacitance, temperature, tier="fastest")
    message = str(raised.value)
    assert message.startswith("unknown tier 'fastest'; valid tiers: linear, ")
    cli = subprocess.run(
        [taxel_cli, "convert", "-", "--tier", "fastest"], capture_output=True, text=True
    )
    assert message in cli.stderr, "the same words as the command line"


def test_an_unfinished_tare_warns_in_the_cli_words(recording):
    capacitance, temperature, _ = recording
    with pytest.warns(taxel.TaxelWarning, match="the tare never finished"):
        pressure, flags = taxel.convert(capacitance[:5], temperature[:5], tare_rows=10)
    assert np.all(np.isnan(pressure))
    assert np.all(flags & taxel.Flags.NOT_TARED)


def two_pad_cli_convert(taxel_cli, tmp_path, buffer, capacitance, temperature, time_s, missing):
    """A two-pad recording of the schema (a pad's frame missing from the sets of `missing`),
    converted with `taxel convert --tare-rows 4`: its pressures and flags as (N, 8) arrays."""
    pressure, flags, messages = cli_convert(
        taxel_cli, tmp_path, capacitance, temperature, time_s, "--tare-rows", "4",
        sequence=buffer.sequence,
    )
    if missing:
        assert f"{len(missing)} pad frames were missing" in messages, messages
    return pressure, flags


@pytest.fixture(scope="module")
def gripper_recording():
    with taxel.Simulator(scene="gripper", speed=50.0, seed=4) as sim:
        sim.start_buffering()
        time.sleep(1.0)
        buffer = sim.read_buffer(strict=False)
    time_s = (buffer.device_time_us - buffer.device_time_us[0]) / 1e6
    return buffer, buffer.capacitance_pf.copy(), buffer.temperature_c.copy(), time_s


def test_several_pads_equal_the_cli(taxel_cli, tmp_path, gripper_recording):
    """A recording of two pads in the schema, converted pad by pad by the command line, gives
    what `taxel.convert` gives for the (N, 8) array."""
    buffer, capacitance, temperature, time_s = gripper_recording
    expected, expected_flags = two_pad_cli_convert(
        taxel_cli, tmp_path, buffer, capacitance, temperature, time_s, set()
    )
    pressure, flags = taxel.convert(capacitance, temperature, time_s=time_s, tare_rows=4)
    np.testing.assert_array_equal(pressure, expected)
    np.testing.assert_array_equal(flags, expected_flags)
    assert np.any(pressure > 1.0)


def test_missing_pad_frames_equal_the_cli(taxel_cli, tmp_path, gripper_recording):
    """Frames missing from sample sets (NaN capacitances and temperature for that pad, as a
    buffer holds them; empty cells in the CSV file): skipped by the pad's model in both, during
    the tare and after it, with NaN pressures and no flags in their rows."""
    buffer, capacitance, temperature, time_s = gripper_recording
    missing = {(1, 1), (2, 0), (40, 1), (41, 1), (len(time_s) - 1, 0)}
    capacitance, temperature = capacitance.copy(), temperature.copy()
    for row, pad in missing:
        capacitance[row, 4 * pad : 4 * pad + 4] = np.nan
        temperature[row, pad] = np.nan
    expected, expected_flags = two_pad_cli_convert(
        taxel_cli, tmp_path, buffer, capacitance, temperature, time_s, missing
    )
    pressure, flags = taxel.convert(capacitance, temperature, time_s=time_s, tare_rows=4)
    np.testing.assert_array_equal(pressure, expected)
    np.testing.assert_array_equal(flags, expected_flags)
    for row, pad in missing:
        assert np.all(np.isnan(pressure[row, 4 * pad : 4 * pad + 4]))
        assert np.all(flags[row, 4 * pad : 4 * pad + 4] == 0)
    # The other pad of those sets is converted.
    assert not np.all(np.isnan(pressure[40, 0:4]))


def test_out_takes_the_results_and_is_returned(recording):
    capacitance, temperature, time_s = recording
    want_pressure, want_flags = taxel.convert(capacitance, temperature, time_s=time_s, tare_rows=3)
    # Filled with values the conversion must overwrite, cell by cell.
    out = (np.full(want_pressure.shape, -7.0), np.full(want_flags.shape, 0xABCD, dtype=np.uint16))
    pressure, flags = taxel.convert(capacitance, temperature, time_s=time_s, tare_rows=3, out=out)
    assert pressure is out[0] and flags is out[1]
    np.testing.assert_array_equal(pressure, want_pressure)
    np.testing.assert_array_equal(flags, want_flags)
    # Several pads with a missing frame: its cells are written too (NaN, no flags).
    both = np.hstack([capacitance, capacitance])
    both[5, 4:] = np.nan
    temperatures = np.stack([temperature, temperature], axis=1)
    temperatures[5, 1] = np.nan
    want_pressure, want_flags = taxel.convert(both, temperatures)
    out = (np.full(want_pressure.shape, -7.0), np.full(want_flags.shape, 0xABCD, dtype=np.uint16))
    taxel.convert(both, temperatures, out=out)
    np.testing.assert_array_equal(out[0], want_pressure)
    np.testing.assert_array_equal(out[1], want_flags)
    assert np.isnan(out[0][5, 4:]).all() and (out[1][5, 4:] == 0).all()


def test_out_that_cannot_take_the_results_is_refused(recording):
    capacitance, temperature, _ = recording
    shape = capacitance.shape
    good_pressure, good_flags = np.empty(shape), np.empty(shape, dtype=np.uint16)
    read_only = np.empty(shape)
    read_only.flags.writeable = False
    cases = [
        ((np.empty(shape, dtype=np.float32), good_flags), "out's pressure array has dtype float32"),
        ((good_pressure, np.empty(shape, dtype=np.int64)), "out's flags array has dtype int64"),
        ((np.empty((shape[0], 8)), good_flags), "out's pressure array has shape \\[.*, 8\\]"),
        ((np.empty(shape, order="F"), good_flags), "out's pressure array is not C-ordered"),
        ((read_only, good_flags), "out's pressure array is read-only"),
        ((good_pressure.tolist(), good_flags), "out's pressure array is not a numpy array"),
        ((capacitance, good_flags), "out's pressure array shares memory with capacitance_pf"),
    ]
    for out, message in cases:
        with pytest.raises(taxel.ConvertError, match=message):
            taxel.convert(capacitance, temperature, out=out)
    shared = np.empty(shape)
    with pytest.raises(taxel.ConvertError, match="out's pressure and flags arrays share memory"):
        taxel.convert(capacitance, temperature, out=(shared, shared.view(np.uint16)[:, :4]))
    with pytest.raises(taxel.ConvertError, match="out must be a tuple \\(pressure, flags\\)"):
        taxel.convert(capacitance, temperature, out=good_pressure)
