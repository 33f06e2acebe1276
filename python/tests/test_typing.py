"""The package's public API (its stubs and Python modules) and the examples pass
`mypy --strict`, with the configuration in python/pyproject.toml."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1]


def mypy(*arguments):
    try:
        import mypy  # noqa: F401
    except ImportError:
        if os.environ.get("TAXEL_REQUIRE_CLI"):
            pytest.fail("mypy is not installed: pip install \"./python[test]\"")
        pytest.skip("mypy is not installed")
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(PACKAGE / "pyproject.toml"),
         "--no-incremental", "--cache-dir", os.devnull, *arguments],
        capture_output=True,
        text=True,
        timeout=600,
        # Outside the source tree, so that `-p taxel` is the installed package.
        cwd=PACKAGE / "tests",
    )


def test_the_package_passes_mypy_strict():
    result = mypy("-p", "taxel")
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_examples_pass_mypy_strict():
    result = mypy(*sorted(str(path) for path in (PACKAGE / "examples").glob("*.py")))
    assert result.returncode == 0, result.stdout + result.stderr
