"""Calibrations: fitting equals `taxel calibrate` (file and report), files round-trip, bad
data and files raise clear errors; the flag names are the documented ones."""

import csv
import subprocess

import numpy as np
import pytest

import taxel
from taxel import _taxel


def reference_loads():
    """Reference loads of a concave pad: three repeats at each of nine levels."""
    levels = np.repeat(np.arange(0.0, 90.0, 10.0), 3)
    unloaded_pf = np.array([4.5, 4.4, 4.6, 4.5])
    change = 0.3 * (1.0 - np.exp(-levels / 40.0))
    noise = np.random.default_rng(5).normal(0.0, 0.0005, (len(levels), 4))
    capacitance = unloaded_pf * (1.0 + change[:, None]) + noise
    temperature = np.full(len(levels), 25.0)
    return levels, capacitance, temperature


def write_loads(path, pressure, capacitance, temperature):
    with path.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["pressure_kpa", "c11_pf", "c12_pf", "c21_pf", "c22_pf", "temp_c"])
        for row in range(len(pressure)):
            writer.writerow(
                [repr(float(pressure[row]))]
                + [repr(float(value)) for value in capacitance[row]]
                + [repr(float(temperature[row]))]
            )


def test_fit_equals_the_cli(taxel_cli, tmp_path):
    pressure, capacitance, temperature = reference_loads()
    fitted = taxel.Calibration.fit(pressure, capacitance, temperature, id=7)
    loads = tmp_path / "loads.csv"
    write_loads(loads, pressure, capacitance, temperature)
    cli_file = tmp_path / "cli.json"
    result = subprocess.run(
        [taxel_cli, "calibrate", str(loads), "-o", str(cli_file), "--id", "7"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    assert taxel.Calibration.load(cli_file) == fitted
    assert fitted.to_json() == cli_file.read_text()
    assert fitted.fit_report == result.stdout
    assert fitted.id == 7


def test_the_leave_one_out_report():
    pressure, capacitance, temperature = reference_loads()
    fitted = taxel.Calibration.fit(pressure, capacitance, temperature)
    report = fitted.leave_one_out
    assert len(report) == 4 * len(taxel.TIERS)
    cubic = [entry for entry in report if entry["tier"] == "monotone-cubic"]
    assert [entry["taxel"] for entry in cubic] == ["c11", "c12", "c21", "c22"]
    for entry in cubic:
        assert len(entry["leave_one_out_kpa"]) == 7, "one fold per interior level"
        assert entry["leave_one_out_max_kpa"] < 3.0
        assert entry["fit_max_kpa"] < 0.01
    assert "leave-one-out" in fitted.fit_report


def test_save_and_load_round_trip(tmp_path):
    pressure, capacitance, temperature = reference_loads()
    fitted = taxel.Calibration.fit(pressure, capacitance, temperature)
    path = tmp_path / "calibration.json"
    fitted.save(path)
    assert taxel.Calibration.load(path) == fitted
    assert taxel.Calibration.load(str(path)).fit_report is None
    assert list(tmp_path.iterdir()) == [path], "no temporary file left behind"
    assert taxel.Calibration.from_json(path.read_text()) == fitted
    assert taxel.Calibration.default() != fitted


def test_bad_data_raises_the_cli_messages():
    pressure, capacitance, temperature = reference_loads()
    with pytest.raises(taxel.CalibrationError, match="no rows at pressure 0"):
        taxel.Calibration.fit(pressure[3:], capacitance[3:])
    with pytest.raises(taxel.CalibrationError, match="row 4: negative pressure -5"):
        bad = pressure.copy()
        bad[4] = -5.0
        taxel.Calibration.fit(bad, capacitance)
    with pytest.raises(taxel.CalibrationError, match="must be \\(27, 4\\)"):
        taxel.Calibration.fit(pressure, capacitance[:, :3])
    with pytest.raises(taxel.CalibrationError, match="only 1 pressure level"):
        taxel.Calibration.fit(pressure[:3], capacitance[:3])
    with pytest.raises(ValueError):
        taxel.Calibration.fit(pressure, capacitance, temperature[:-1])


def test_bad_files_raise_calibration_errors(tmp_path):
    with pytest.raises(taxel.CalibrationError, match="reading .*missing.json"):
        taxel.Calibration.load(tmp_path / "missing.json")
    other = tmp_path / "other.json"
    other.write_text('{"format": "something-else"}')
    with pytest.raises(taxel.CalibrationError, match="not a calibration file"):
        taxel.Calibration.load(other)


def test_flags_are_the_documented_names():
    assert [(flag.name.lower(), flag.value) for flag in taxel.Flags] == _taxel.flag_bits()
    assert taxel.Flags(0b11) == taxel.Flags.BELOW_BASELINE | taxel.Flags.OVER_RANGE
    assert taxel.TIERS[2] == "monotone-cubic"


def flat_loads():
    """Reference loads whose 40..50 kPa interval is nearly flat in dC/C0 (the converter's
    noise moves the pressure there by far more than the budget), with two rows taken at
    90 °C, outside the temperature law's characterised range."""
    pressure, capacitance, temperature = reference_loads()
    flat = pressure == 50.0
    capacitance[flat] = capacitance[pressure == 40.0] + 1e-6
    temperature = temperature.copy()
    temperature[[5, 6]] = 90.0
    return pressure, capacitance, temperature


def test_fit_warnings_are_python_warnings_with_the_cli_words(taxel_cli, tmp_path):
    pressure, capacitance, temperature = flat_loads()
    with pytest.warns(taxel.TaxelWarning) as caught:
        fitted = taxel.Calibration.fit(pressure, capacitance, temperature, id=3)
    messages = [str(warning.message) for warning in caught]
    assert messages == fitted.fit_warnings
    assert any("2 row(s) outside the characterised" in message for message in messages)
    assert any("40..50 kPa" in message and "over the 0.5 kPa budget" in message for message in messages)
    # The warning points at the caller's line, not at the package.
    assert all(warning.filename == __file__ for warning in caught)
    # The command prints the same warnings on stderr ("warning: " before each), and the same
    # report on stdout.
    loads = tmp_path / "loads.csv"
    write_loads(loads, pressure, capacitance, temperature)
    result = subprocess.run(
        [taxel_cli, "calibrate", str(loads), "-o", str(tmp_path / "c.json"), "--id", "3"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    cli_warnings = [
        line[len("warning: "):] for line in result.stderr.splitlines() if line.startswith("warning: ")
    ]
    assert sorted(cli_warnings) == sorted(messages)
    assert fitted.fit_report == result.stdout


def test_a_clean_fit_warns_nothing():
    import warnings

    pressure, capacitance, temperature = reference_loads()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fitted = taxel.Calibration.fit(pressure, capacitance, temperature)
    assert fitted.fit_warnings == []
    assert taxel.Calibration.default().fit_warnings == []
