#!/usr/bin/env bash
# Installs the MuJoCo 3.17.0 shared library into .mujoco/lib (ignored by git).
# Source: the official PyPI wheel `mujoco==3.17.0`, which carries libmujoco.so.3.17.0
# (it needs nothing but libc). Idempotent: does nothing when the library is already there.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
lib_dir="$root/.mujoco/lib"
version="3.17.0"
if [ -f "$lib_dir/libmujoco.so" ] && [ -f "$lib_dir/.version" ] && [ "$(cat "$lib_dir/.version")" = "$version" ]; then
  exit 0
fi
pip_cmd=""
for c in pip3 pip "python3 -m pip"; do
  if $c --version >/dev/null 2>&1; then pip_cmd="$c"; break; fi
done
if [ -z "$pip_cmd" ]; then
  echo "error: installing MuJoCo $version needs pip (python3 -m pip) to download the PyPI wheel 'mujoco==$version'." >&2
  echo "       Install pip (e.g. 'apt-get install python3-pip') or put libmujoco.so ($version) into $lib_dir yourself." >&2
  exit 1
fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
echo "Installing MuJoCo $version from PyPI into $lib_dir ..."
# The wheel is platform specific; pip picks the one matching this machine.
if ! $pip_cmd download --no-deps --quiet --only-binary=:all: --dest "$tmp" "mujoco==$version" >"$tmp/pip.log" 2>&1; then
  cat "$tmp/pip.log" >&2
  echo "error: could not download the wheel 'mujoco==$version' from PyPI (no network, or no wheel for this platform)." >&2
  echo "       Fix the network/proxy, or put libmujoco.so ($version) into $lib_dir yourself." >&2
  exit 1
fi
wheel="$(ls "$tmp"/mujoco-*.whl | head -n 1)"
python3 - "$wheel" "$tmp" <<'PY'
import sys, zipfile
wheel, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    names = [n for n in z.namelist() if n.startswith("mujoco/libmujoco.so")]
    if not names:
        sys.exit("error: the wheel holds no mujoco/libmujoco.so*")
    z.extract(names[0], out)
    print(names[0])
PY
mkdir -p "$lib_dir"
so="$(ls "$tmp"/mujoco/libmujoco.so* | head -n 1)"
cp "$so" "$lib_dir/libmujoco.so.$version"
ln -sf "libmujoco.so.$version" "$lib_dir/libmujoco.so"
echo "$version" > "$lib_dir/.version"
echo "MuJoCo $version installed: $lib_dir/libmujoco.so"
