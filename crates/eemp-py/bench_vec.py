"""Python-side vectorised stepping against Rust-only stepping of the same task, in one run.

    python crates/eemp-py/bench_vec.py [--task A1ModelFree-v0] [--envs 256] [--steps 30] [--threads 2]

Both step `envs` environments `steps` times with uniform random actions in [-1, 1] on `threads`
worker threads: the Rust side with `eemp bench rl`'s stepping loop (`eemp_rl::env::stepping_rate`),
the Python side through `A1VectorEnv.step` (argument checks, numpy arrays in and out, infos).
Rounds alternate so machine noise hits both; the medians and their ratio are printed.
"""

import argparse
import json
import statistics
import time

import numpy as np

import eemp
from eemp import _eemp


def python_rate(task, envs, steps, threads):
    v = eemp.make_vec_env(task, envs, threads=threads)
    v.reset(seed=7)
    actions = np.random.default_rng(3).uniform(-1, 1, (steps, envs, v.single_action_space.shape[0])).astype(np.float32)
    t = time.perf_counter()
    for a in actions:
        v.step(a)
    return steps * envs / (time.perf_counter() - t)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="A1ModelFree-v0", choices=list(eemp.TASKS))
    p.add_argument("--envs", type=int, default=256)
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args()
    rust, py = [], []
    for _ in range(a.rounds):
        rust.append(_eemp.rust_stepping_rate(eemp.TASKS[a.task], a.envs, a.steps, a.threads))
        py.append(python_rate(a.task, a.envs, a.steps, a.threads))
    r, q = statistics.median(rust), statistics.median(py)
    print(f"| stepping ({a.task}, {a.envs} envs, {a.threads} threads) | env steps/s |")
    print("|---|---|")
    print(f"| Rust only (eemp bench rl's loop) | {r:.0f} |")
    print(f"| Python A1VectorEnv.step | {q:.0f} |")
    print(f"| Python / Rust | {q / r:.3f} |")
    print(json.dumps({"task": a.task, "envs": a.envs, "threads": a.threads, "rust_env_steps_per_s": rust, "python_env_steps_per_s": py, "ratio": q / r}))


if __name__ == "__main__":
    main()
