#!/usr/bin/env bash
# A virtual environment in .venv with the Python package's build and test tools
# (crates/eemp-py/requirements-dev.txt), from PyPI. Run by `make python`.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; assert sys.version_info >= (3, 10)' 2>/dev/null; then
    echo "error: $PY is missing or older than Python 3.10 (set PYTHON=/path/to/python3)" >&2
    exit 2
fi
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
.venv/bin/pip install --quiet --disable-pip-version-check -r crates/eemp-py/requirements-dev.txt
touch .venv/.installed
