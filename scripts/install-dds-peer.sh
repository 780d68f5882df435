#!/usr/bin/env bash
# Installs the Cyclone DDS interop peer's Python environment into .venv-dds (ignored by git
# through its own .gitignore): Eclipse Cyclone DDS's Python binding `cyclonedds` from PyPI,
# pinned. 11.0.1 is the only version with a CPython 3.11 manylinux wheel (which bundles
# libddsc, so no C build is needed); 0.10.2 (what the Go2 runs) and 0.10.5 ship no cp311 wheel
# and would build from source against a separately installed Cyclone C library.
# Beside it, Unitree's Python SDK (`unitree-sdk2` 1.0.1, unitree_sdk2py) without its
# dependencies: it pins cyclonedds==0.10.2 (no wheel for CPython 3.11); the peer uses only its
# IDL classes and its pure-Python CRC (scripts/dds_peer/go2_peer.py --sdk-types).
# Idempotent: does nothing when the pinned version is already there.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv-dds"
version="11.0.1"
sdk_version="1.0.1"
stamp="$venv/.installed-cyclonedds-$version-unitree-sdk2-$sdk_version"
if [ -f "$stamp" ]; then
  exit 0
fi
python="${PYTHON:-python3}"
if ! "$python" -m venv --help >/dev/null 2>&1; then
  echo "error: the DDS interop peer needs python3 with venv (e.g. 'apt-get install python3-venv')." >&2
  exit 1
fi
echo "Installing cyclonedds==$version into $venv ..."
rm -rf "$venv"
"$python" -m venv "$venv"
# Keeps the environment out of git without touching the repository's .gitignore.
echo '*' > "$venv/.gitignore"
if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --only-binary=:all: \
  "cyclonedds==$version" >"$venv/pip.log" 2>&1; then
  cat "$venv/pip.log" >&2
  echo "error: could not install the wheel 'cyclonedds==$version' from PyPI (no network, or no" >&2
  echo "       wheel for this Python/platform: it exists for CPython 3.8-3.13 on manylinux x86_64/aarch64)." >&2
  exit 1
fi
if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --only-binary=:all: \
  --no-deps "unitree-sdk2==$sdk_version" >>"$venv/pip.log" 2>&1; then
  cat "$venv/pip.log" >&2
  echo "error: could not install the wheel 'unitree-sdk2==$sdk_version' from PyPI." >&2
  exit 1
fi
"$venv/bin/python" -c "import cyclonedds.domain, cyclonedds.idl"
touch "$stamp"
