"""The example script runs against the simulator."""

import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "record_simulator.py"


def test_the_example_records_from_the_simulator(tmp_path):
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), "--seconds", "1", "--speed", "5",
         "--output", str(tmp_path / "plot.png")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert "none lost" in result.stdout


FIRST_HOUR = Path(__file__).resolve().parents[1] / "examples" / "first_hour.py"


def test_the_first_hour_streams_saves_converts_and_fits(tmp_path):
    result = subprocess.run(
        [sys.executable, "-W", "error::UserWarning", str(FIRST_HOUR), "--seconds", "2.5", "--speed", "20"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    output = result.stdout
    assert ", 0 lost" in output
    assert "contact_started" in output and "contact_ended" in output
    assert (tmp_path / "first_hour.csv").exists()
    assert "50 kPa plateau" in output and "20 kPa plateau" in output
