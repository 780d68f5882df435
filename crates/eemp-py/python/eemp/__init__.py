"""EEMP for the Unitree A1, from Python: the project's A1 tasks as gymnasium environments and
the EEMP controller (planner + MPC + swing law), all running in the Rust crates.

    import eemp
    env = eemp.make_env("A1ModelFree-v0")               # or gymnasium.make("A1ModelFree-v0")
    venv = eemp.make_vec_env("A1ModelFree-v0", num_envs=64)
    summary = eemp.walk(gait="trot", speed=0.5, duration_s=10.0)
"""

from __future__ import annotations

import json

import gymnasium as gym

from ._eemp import LEG_ORDER, A1Sim, EempController
from ._eemp import env_seed_of as env_seed
from .envs import TASKS, A1Env, A1VectorEnv

__all__ = ["A1Env", "A1Sim", "A1VectorEnv", "EempController", "LEG_ORDER", "TASKS", "env_seed", "make_env", "make_vec_env", "walk"]


def make_env(task: str, **kwargs) -> A1Env:
    """One environment of `task` (a key of `TASKS`); kwargs: config, motion."""
    return A1Env(task, **kwargs)


def make_vec_env(task: str, num_envs: int, **kwargs) -> A1VectorEnv:
    """`num_envs` environments of `task` stepped in Rust threads; kwargs: threads, config, motion."""
    return A1VectorEnv(task, num_envs=num_envs, **kwargs)


def walk(gait: str = "trot", speed: float = 0.3, duration_s: float = 20.0, **kwargs) -> dict:
    """A walk under EEMP in the project's scenario and metrics (what `eemp walk` runs): fell,
    cot, manipulability, vel_rmse_mps, distance_m, energy_j, params_table, ... as a dict. kwargs:
    seed, lateral, yaw_rate, params (TOML), params_table (TOML; default: the robot's shipped
    table of the gait, tables/<robot>_<gait>.toml, when the working folder has it), table_ii
    (True: the paper's Table II constants), estimator ("ground-truth" or "kf"), robot, settings
    (a list of "key=value" controller settings, as `eemp walk --set`, e.g.
    ["mpc.horizon=12"]; `eemp config show` lists the keys)."""
    return json.loads(_walk_json(gait=gait, speed=speed, duration_s=duration_s, **kwargs))


from ._eemp import walk_json as _walk_json  # noqa: E402

for _id, _name in TASKS.items():
    if _id not in gym.registry:
        gym.register(
            id=_id,
            entry_point="eemp.envs:A1Env",
            vector_entry_point="eemp.envs:A1VectorEnv",
            kwargs={"task": _id},
        )
