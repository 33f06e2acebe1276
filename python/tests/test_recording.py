"""Recordings from Python: a recording of the schema (written by `taxel record` from two
simulated devices of 1 and 2 pads) read as arrays, and converted again through the host
library's engine — the numbers `taxel convert` writes, and the device's own."""

import subprocess

import numpy as np
import pytest

import taxel
from test_device import start_cli_simulator


@pytest.fixture(scope="module")
def recording(taxel_cli, tmp_path_factory):
    directory = tmp_path_factory.mktemp("recording")
    (directory / "a").mkdir()
    (directory / "b").mkdir()
    one, one_port = start_cli_simulator(taxel_cli, directory / "a")
    two, two_port = start_cli_simulator(taxel_cli, directory / "b", "--pads", "2")
    try:
        path = directory / "rec.csv"
        subprocess.run(
            [taxel_cli, "record", one_port, two_port, "-o", str(path), "--samples", "200"],
            check=True, capture_output=True, timeout=120,
        )
    finally:
        for process in (one, two):
            process.terminate()
            process.wait(timeout=10)
    return path


def test_a_recording_reads_as_arrays_of_every_device_and_pad(recording):
    rec = taxel.read_recording(recording)
    assert len(rec) == 200 * 3
    assert rec.pressure_kpa.shape == (600, 4) and rec.flags.dtype == np.uint16
    assert rec.cop_mm.shape == (600, 2)
    pairs = set(zip(rec.device.tolist(), rec.pad.tolist()))
    assert pairs == {(0, 0), (1, 0), (1, 1)}
    for device, pad in pairs:
        sequences = rec.sequence[(rec.device == device) & (rec.pad == pad)]
        assert len(sequences) == 200 and np.all(np.diff(sequences) == 1)
    assert not rec.missing.any()


def test_convert_recording_reproduces_the_device_and_equals_the_cli(recording, taxel_cli, tmp_path):
    recorded = taxel.read_recording(recording)
    converted = taxel.convert_recording(recording)
    np.testing.assert_array_equal(converted.pressure_kpa, recorded.pressure_kpa)
    np.testing.assert_array_equal(converted.flags, recorded.flags)
    np.testing.assert_array_equal(converted.force_n, recorded.force_n)
    np.testing.assert_array_equal(converted.cop_mm, recorded.cop_mm)
    output = tmp_path / "converted.csv"
    subprocess.run([taxel_cli, "convert", str(recording), "-o", str(output)], check=True, capture_output=True)
    by_cli = taxel.read_recording(output)
    np.testing.assert_array_equal(converted.pressure_kpa, by_cli.pressure_kpa)
    # Another tier changes the pressures, through the same options as the CLI's.
    table = taxel.convert_recording(recording, tier="linear")
    subprocess.run([taxel_cli, "convert", str(recording), "--tier", "linear", "-o", str(output)], check=True, capture_output=True)
    np.testing.assert_array_equal(table.pressure_kpa, taxel.read_recording(output).pressure_kpa)


def test_a_file_of_another_shape_is_refused_and_a_bad_row_is_reported(tmp_path, recording):
    other = tmp_path / "other.csv"
    other.write_text("time_s,temp_c,c11_pf\n0,25,4.5\n")
    with pytest.raises(taxel.ConvertError, match="not a taxel recording"):
        taxel.read_recording(other)
    lines = recording.read_text().splitlines()
    broken = tmp_path / "broken.csv"
    broken.write_text("\n".join(lines[:5] + ["not,a,row"] + lines[5:10]) + "\n")
    with pytest.warns(taxel.TaxelWarning, match="line 6"):
        rec = taxel.read_recording(broken)
    assert len(rec) == 9  # the header, 4 rows, the bad line, 5 rows
