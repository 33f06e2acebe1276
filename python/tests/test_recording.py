"""Recordings from Python: a recording of the schema (written by `taxel record` from two
simulated devices of 1 and 2 pads) read as arrays, and converted again through the host
library's engine — the numbers `taxel convert` writes, and the device's own."""

import json
import subprocess
import time

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


def scaled_calibration(factor):
    """The default calibration with every curve's dC/C0 scaled by ``factor``: a calibration the
    device does not start with."""
    spec = json.loads(taxel.Calibration.default().to_json())
    for taxel_spec in spec["calibration"]["taxels"]:
        for point in taxel_spec["points"]:
            point["relative_change"] *= factor
    return taxel.Calibration.from_json(json.dumps(spec))


def test_a_saved_buffer_converts_again_to_what_the_device_computed(tmp_path):
    # Pad 1 gets a calibration of its own while the device streams: converting the saved
    # buffer again must use it and the device's baselines (the state saved beside it), not the
    # defaults and a tare on the first rows; the sets read before the change are named.
    with taxel.Simulator(scene="gripper", speed=20.0) as sim:
        sim.start_buffering()
        time.sleep(0.2)
        sim.write_calibration(scaled_calibration(1.4), pad=1)
        time.sleep(0.5)
        buffer = sim.stop_buffering()
    path = tmp_path / "grip.csv"
    with pytest.warns(taxel.TaxelWarning, match="changed while these sets were read \\(pad 1 before set"):
        buffer.save(path)
    state = json.loads((tmp_path / "grip.csv.dev0.device.json").read_text())
    changed_from = state["pads"][1]["state_from_sequence"]
    assert state["pads"][0]["state_from_sequence"] == 0
    assert buffer.sequence[0] < changed_from < buffer.sequence[-1] - 10
    live = buffer.to_pandas()
    with pytest.warns(taxel.TaxelWarning, match=f"rows before sequence {changed_from} may have been computed"):
        again = taxel.convert_recording(path).to_pandas()
    after = live["seq"] >= changed_from
    columns = ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa", "flags11", "flags12", "flags21",
               "flags22", "force_n", "cop_x_mm", "cop_y_mm", "contact"]
    assert live.loc[after, "contact"].any() and np.isfinite(live.loc[after, "p11_kpa"]).any()
    for column in columns:
        np.testing.assert_array_equal(again.loc[after, column].to_numpy(), live.loc[after, column].to_numpy(),
                                      err_msg=column)
    # The same file without the state beside it converts with the defaults: pad 1 differs.
    defaults = taxel.convert_recording(path, use_device_state=False).to_pandas()
    pad_one = after & (live["pad"] == 1)
    assert not np.allclose(defaults.loc[pad_one, "p11_kpa"], live.loc[pad_one, "p11_kpa"], equal_nan=True)
