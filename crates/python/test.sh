#!/usr/bin/env bash
# The Python package's tests: build the wheel (maturin, release), install it into a private
# virtual environment under target/, check the package's types (mypy, stubtest) and run pytest
# on crates/python/tests against the installed package. Needs Python ≥ 3.9 with the
# venv module (PYTHON=… to choose the interpreter) and PyPI for the first run's packages.
set -euo pipefail
cd "$(dirname "$0")/../.."

py=${PYTHON:-python3}
venv=target/python-venv
if ! command -v "$py" >/dev/null 2>&1; then
    echo "crates/python/test.sh: $py not found: install Python ≥ 3.9 (or set PYTHON=…)" >&2
    exit 1
fi
if ! "$py" -c 'import sys; sys.exit(sys.version_info < (3, 9))'; then
    echo "crates/python/test.sh: $py is $("$py" --version 2>&1); femp's Python package needs ≥ 3.9" >&2
    exit 1
fi
if [ ! -x "$venv/bin/python" ]; then
    "$py" -m venv "$venv" || {
        echo "crates/python/test.sh: '$py -m venv' failed (on Debian: apt install python3-venv)" >&2
        exit 1
    }
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    -r crates/python/requirements-test.txt
# The wheel a user installs (abi3, release), installed into the environment: the tests run
# against what ships, not against the source tree.
wheels=target/python-wheel
rm -rf "$wheels"
"$venv/bin/maturin" build --release --quiet --manifest-path crates/python/Cargo.toml \
    --interpreter "$venv/bin/python" --out "$wheels"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall \
    --no-deps "$wheels"/femp-*.whl
# The package's types: mypy on its sources, and stubtest holding the installed native module's
# stub (femp/_femp.pyi) to what the extension really exports, names and signatures.
(cd crates/python/python &&
    "../../../$venv/bin/python" -m mypy --config-file ../pyproject.toml -p femp)
"$venv/bin/python" -m mypy.stubtest femp._femp --mypy-config-file crates/python/pyproject.toml
FEMP_TEST_INSTALLED=1 "$venv/bin/python" -m pytest -q crates/python/tests
