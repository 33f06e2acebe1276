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


def cell(value):
    return "" if np.isnan(value) else repr(float(value))


def flag_bits(text):
    bits = 0
    for name in filter(None, text.split("|")):
        bits |= int(taxel.Flags[name.upper()])
    return bits


def cli_convert(taxel_cli, tmp_path, capacitance, temperature, time_s, *arguments):
    """Writes the data as a CSV file, runs `taxel convert` on it, reads its pressures (as the
    f32 values it printed) and flags."""
    source = tmp_path / "input.csv"
    with source.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["time_s", "temp_c", "c11_pf", "c12_pf", "c21_pf", "c22_pf"])
        for row in range(len(time_s)):
            writer.writerow(
                [repr(float(time_s[row])), cell(temperature[row])]
                + [cell(value) for value in capacitance[row]]
            )
    output = tmp_path / "output.csv"
    result = subprocess.run(
        [taxel_cli, "convert", str(source), "-o", str(output), "--no-device-state", *arguments],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    with output.open(newline="") as file:
        rows = list(csv.DictReader(file))
    names = ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"]
    pressure = np.array(
        [[np.float32(row[name]) if row[name] else np.nan for name in names] for row in rows],
        dtype=np.float64,
    )
    flags = np.array(
        [[flag_bits(row[f"flags{name[1:3]}"]) for name in names] for row in rows],
        dtype=np.uint16,
    )
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
    with pytest.raises(ValueError, match="time_s\\[1\\]: the time must be a finite number"):
        taxel.convert(capacitance[:3], temperature[:3], time_s=[0.0, np.nan, 1.0])
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
    """Writes a two-pad recording in `taxel record`'s pad-prefixed layout (a pad's cells all
    empty in the rows of `missing`: its frame is missing from that set), converts it with
    `taxel convert --tare-rows 4` and returns its pressures and flags as (N, 8) arrays."""
    names = ["c11_pf", "c12_pf", "c21_pf", "c22_pf"]
    source = tmp_path / "pads.csv"
    with source.open("w", newline="") as file:
        writer = csv.writer(file)
        header = ["seq"]
        for pad in range(2):
            header += [f"pad{pad}_time_s", f"pad{pad}_temp_c"] + [f"pad{pad}_{n}" for n in names]
        writer.writerow(header)
        for row in range(len(time_s)):
            cells = [str(int(buffer.sequence[row]))]
            for pad in range(2):
                if (row, pad) in missing:
                    cells += [""] * 6
                    continue
                cells += [repr(float(time_s[row])), cell(temperature[row, pad])]
                cells += [cell(value) for value in capacitance[row, 4 * pad : 4 * pad + 4]]
            writer.writerow(cells)
    output = tmp_path / "converted.csv"
    result = subprocess.run(
        [taxel_cli, "convert", str(source), "-o", str(output), "--no-device-state",
         "--tare-rows", "4"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    if missing:
        assert f"{len(missing)} pad frames were missing" in result.stderr, result.stderr
    with output.open(newline="") as file:
        rows = list(csv.DictReader(file))
    columns = [f"pad{pad}_p{k}_kpa" for pad in range(2) for k in ("11", "12", "21", "22")]
    expected = np.array(
        [[np.float32(row[c]) if row[c] else np.nan for c in columns] for row in rows],
        dtype=np.float64,
    )
    flag_columns = [c.replace("_p", "_flags").replace("_kpa", "") for c in columns]
    expected_flags = np.array(
        [[flag_bits(row[c]) for c in flag_columns] for row in rows], dtype=np.uint16
    )
    return expected, expected_flags


@pytest.fixture(scope="module")
def gripper_recording():
    with taxel.Simulator(scene="gripper", speed=50.0, seed=4) as sim:
        sim.start_buffering()
        time.sleep(1.0)
        buffer = sim.read_buffer(strict=False)
    time_s = (buffer.device_time_us - buffer.device_time_us[0]) / 1e6
    return buffer, buffer.capacitance_pf.copy(), buffer.temperature_c.copy(), time_s


def test_several_pads_equal_the_cli(taxel_cli, tmp_path, gripper_recording):
    """A recording of two pads in `taxel record`'s pad-prefixed layout, converted pad by pad by
    the command line, gives what `taxel.convert` gives for the (N, 8) array."""
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
