"""A screenshot of the Rerun viewer on a walk, without a display (docs/img/viewer.png).

Needs the viewer (`pip install rerun-sdk==0.36.3`), a Vulkan software rasteriser
(Debian: `apt-get install mesa-vulkan-drivers`) and an `eemp` (any build: it records through
this Python's rerun-sdk, or through the Rust SDK in a `make viewer` build). The headless viewer listens on gRPC; the walk streams into it with
`--rerun-connect`, as a live view would, and the viewer saves what it shows at the end.

    python scripts/viewer-screenshot.py [--eemp target/release/eemp] [--out docs/img/viewer.png]
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

from rerun.experimental import ViewerClient


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--eemp", default="target/release/eemp")
    ap.add_argument("--out", default="docs/img/viewer.png")
    ap.add_argument("--settle-s", type=float, default=8.0, help="wait for the viewer to draw")
    ap.add_argument("walk", nargs="*", default=["--gait", "free", "--speed", "0.3", "--duration", "20"])
    a = ap.parse_args()
    viewer = ViewerClient.spawn(headless=True)
    try:
        with tempfile.TemporaryDirectory() as d:
            cmd = [a.eemp, "walk", *a.walk, "--rerun-connect", viewer.url, "--out", d]
            print(" ".join(cmd))
            env = {**os.environ, "EEMP_PYTHON": sys.executable}
            subprocess.run(cmd, check=True, env=env)
        time.sleep(a.settle_s)
        viewer.save_screenshot(a.out)
        print("wrote", a.out)
    finally:
        viewer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
