"""Buffers and recordings as pandas tables of the recording schema (the columns `taxel record`
writes, one row per pad per set), a buffer saved as a recording that every reader takes, and
a clear message when pandas is missing."""

import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

import taxel


@pytest.fixture(scope="module")
def gripper_buffer():
    with taxel.Simulator(scene="gripper", speed=20.0) as sim:
        sim.start_buffering()
        time.sleep(0.5)
        return sim.read_buffer()


def cli_header(taxel_cli, tmp_path):
    """The header of a recording `taxel convert` writes (the schema's columns, as the tool
    has them)."""
    path = tmp_path / "one.csv"
    with taxel.Simulator(speed=20.0) as sim:
        sim.start_buffering()
        time.sleep(0.2)
        sim.read_buffer().save(path)
    output = tmp_path / "converted.csv"
    subprocess.run([taxel_cli, "convert", str(path), "-o", str(output), "--tare-rows", "4"],
                   check=True, capture_output=True)
    return output.read_text().splitlines()[0].split(",")


def test_a_buffer_is_the_recording_schemas_long_table(gripper_buffer, taxel_cli, tmp_path):
    buffer = gripper_buffer
    frame = buffer.to_pandas()
    assert list(frame.columns) == cli_header(taxel_cli, tmp_path)
    assert len(frame) == 2 * len(buffer)
    assert frame["pad"].tolist()[:4] == [0, 1, 0, 1]
    assert (frame["device"] == 0).all()
    np.testing.assert_array_equal(frame["seq"].to_numpy()[::2], buffer.sequence)
    np.testing.assert_array_equal(frame[["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"]].to_numpy(),
                                  buffer.pressure_kpa.reshape(-1, 4))
    np.testing.assert_array_equal(frame[["cop_x_mm", "cop_y_mm"]].to_numpy(), buffer.cop_mm.reshape(-1, 2))
    assert frame["flags11"].dtype == np.uint16
    assert frame["contact"].dtype == bool and frame["contact"].any()
    assert set(frame["temp_source"]) == {"tmp117"}
    # A tidy table: per-pad summaries are one groupby away.
    peak = frame.groupby("pad")["force_n"].max()
    np.testing.assert_array_equal(peak.to_numpy(), np.nanmax(buffer.force_n, axis=0))


def test_a_saved_buffer_reads_back_as_the_same_table(gripper_buffer, tmp_path, taxel_cli):
    buffer = gripper_buffer
    path = tmp_path / "grip.csv"
    buffer.save(path)
    recording = taxel.read_recording(path)
    assert len(recording) == 2 * len(buffer)
    saved, live = recording.to_pandas(), buffer.to_pandas()
    # The file keeps microseconds of host time; every other cell is the same to the bit.
    np.testing.assert_allclose(saved.pop("host_time_s"), live.pop("host_time_s"), rtol=0, atol=1e-6)
    pd.testing.assert_frame_equal(saved, live, check_dtype=False)
    # The command-line tool reads it too.
    result = subprocess.run([taxel_cli, "convert", str(path), "-o", str(tmp_path / "c.csv"), "--tare-rows", "16"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_a_recordings_table_keeps_its_markers(tmp_path, gripper_buffer):
    path = tmp_path / "marked.csv"
    gripper_buffer.save(path)
    lines = path.read_text().splitlines()
    lines[3] = lines[3] + "grasp"  # the marker column is last and empty
    path.write_text("\n".join(lines) + "\n")
    frame = taxel.read_recording(path).to_pandas()
    assert frame["marker"].tolist()[:4] == ["", "", "grasp", ""]


def test_without_pandas_the_error_says_how_to_install_it(gripper_buffer, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="to_pandas\\(\\) needs pandas.*pip install pandas"):
        gripper_buffer.to_pandas()
