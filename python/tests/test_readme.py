"""Every Python block of python/README.md runs as written, and every example runs."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1]
README = PACKAGE / "README.md"
EXAMPLES = sorted((PACKAGE / "examples").glob("*.py"))

# The arguments each example is tested with (short runs); a new example needs an entry.
EXAMPLE_ARGUMENTS = {
    "record_simulator.py": ["--seconds", "1", "--speed", "5", "--no-plot"],
    "first_hour.py": ["--seconds", "2.5", "--speed", "20"],
}


def python_blocks():
    text = README.read_text()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)


def test_the_readme_has_python_blocks():
    assert len(python_blocks()) >= 1


@pytest.mark.parametrize("index", range(len(python_blocks())))
def test_a_readme_block_runs(index, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = python_blocks()[index]
    exec(compile(code, f"{README.name} block {index + 1}", "exec"), {"__name__": "__readme__"})


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda path: path.name)
def test_every_example_runs(example, tmp_path):
    assert example.name in EXAMPLE_ARGUMENTS, f"{example.name}: add its test arguments"
    result = subprocess.run(
        [sys.executable, str(example), *EXAMPLE_ARGUMENTS[example.name]],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
