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
