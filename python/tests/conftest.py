"""Shared fixtures: the `taxel` command-line tool, for comparing the package with it."""

import os
import shutil
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]


def find_cli():
    """The `taxel` executable: $TAXEL_CLI, else a build in the cargo target directory, else the
    one on PATH; None when there is none."""
    explicit = os.environ.get("TAXEL_CLI")
    if explicit:
        return explicit
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPOSITORY / "target"))
    for profile in ("release", "debug"):
        candidate = target / profile / "taxel"
        if candidate.is_file():
            return str(candidate)
    return shutil.which("taxel")


@pytest.fixture(scope="session")
def taxel_cli():
    """The path of the `taxel` executable (python/ci.sh builds it and sets $TAXEL_CLI)."""
    cli = find_cli()
    if cli is None:
        if os.environ.get("TAXEL_REQUIRE_CLI"):
            pytest.fail("the taxel command-line tool was not found: set TAXEL_CLI")
        pytest.skip("the taxel command-line tool is not built (cargo build -p taxel)")
    return cli
