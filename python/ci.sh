#!/usr/bin/env bash
# The Python package's CI step: rustfmt and clippy of the extension crate, a fresh virtual
# environment, `pip install ./python` as a user would, `mypy --strict` on the package and the
# examples, the command-line tool the tests compare against, then the pytest suite.
# Usage (from anywhere): bash python/ci.sh
# Environment: PYTHON (default python3), TAXEL_PY_VENV (default: a temporary directory, removed
# afterwards), CARGO_TARGET_DIR (honoured by both builds).
set -euo pipefail

python_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repository="$(dirname "$python_dir")"
python="${PYTHON:-python3}"

fail() {
  echo "python/ci.sh: FAILED: $*" >&2
  exit 1
}

if [[ -n "${TAXEL_PY_VENV:-}" ]]; then
  venv="$TAXEL_PY_VENV"
else
  venv="$(mktemp -d)/venv"
  trap 'rm -rf "$(dirname "$venv")"' EXIT
fi

echo "== python: rustfmt and clippy of the extension crate (its own workspace)"
cargo fmt --manifest-path "$python_dir/Cargo.toml" -- --check || fail "cargo fmt (run: cargo fmt --manifest-path python/Cargo.toml)"
PYO3_PYTHON="$python" cargo clippy --locked --manifest-path "$python_dir/Cargo.toml" --all-targets -- -D warnings \
  || fail "cargo clippy on python/"

echo "== python: virtual environment in $venv"
"$python" -m venv "$venv" || fail "creating the virtual environment with $python"
"$venv/bin/python" -m pip install --quiet --upgrade pip || fail "upgrading pip"

echo "== python: pip install ./python[test] (pytest, pandas, pandas-stubs, mypy)"
(cd "$repository" && "$venv/bin/python" -m pip install --quiet "./python[test]") \
  || fail "pip install ./python"

echo "== python: mypy --strict on the installed package's public API and on python/examples"
# From the tests' directory, so that `-p taxel` is the installed package (its stubs), not the
# source tree.
(cd "$python_dir/tests" \
  && "$venv/bin/python" -m mypy --config-file "$python_dir/pyproject.toml" --cache-dir /dev/null -p taxel \
  && "$venv/bin/python" -m mypy --config-file "$python_dir/pyproject.toml" --cache-dir /dev/null "$python_dir"/examples/*.py) \
  || fail "mypy --strict"

echo "== python: the taxel command-line tool (the tests compare the package with it)"
(cd "$repository" && cargo build --locked -p taxel --bin taxel) || fail "cargo build -p taxel"
target="${CARGO_TARGET_DIR:-$repository/target}"
export TAXEL_CLI="$target/debug/taxel"
export TAXEL_REQUIRE_CLI=1

echo "== python: pytest"
# From the tests' directory, so that `import taxel` is the installed package, not the source.
(cd "$python_dir/tests" && "$venv/bin/python" -m pytest -q -p no:cacheprovider .) \
  || fail "pytest"
echo "== python: all passed"
