"""The A1 tasks as gymnasium environments: one (`A1Env`) or N stepped in Rust threads behind one
call (`A1VectorEnv`). Observations, actions, rewards, terminations and truncations are the Rust
tasks' own (`eemp-rl`); these classes only check arguments and shape arrays.

Seeding: `A1Env.reset(seed=s)` seeds the environment's RNG (ChaCha8) with `s`;
`A1VectorEnv.reset(seed=s)` seeds sub-environment i with `env_seed(s, i)`, exactly as
`eemp train` seeds its environments for config seed `s`. So sub-environment i of a vector env
reset with seed s steps like an `A1Env` reset with seed `env_seed(s, i)`.

Episode ends: the Rust tasks start the next episode in the same step (gymnasium's SAME_STEP
autoreset; `info["final_obs"]` is an (N, obs_dim) array, zero in the rows of sub-envs whose
episode goes on, `info["_final_obs"]` says which rows hold one). `A1Env.step` returns the final observation of the ended episode; the `reset()`
that follows (without a seed) hands back the first observation of the episode Rust already
started, so a Python rollout is the Rust rollout step for step.
"""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from . import _eemp

#: gymnasium id → the Rust task's name (`eemp train --task NAME`).
TASKS = {
    "A1ModelFree-v0": "model-free",
    "A1Imitation-v0": "imitation",
    "A1EempRl-v0": "eemp-rl",
}


def _task(name: str) -> str:
    if name in TASKS:
        return TASKS[name]
    if name in TASKS.values():
        return name
    raise ValueError(f"unknown task {name!r}: allowed {', '.join(TASKS)}")


def _check_actions(action, shape: tuple[int, ...]) -> np.ndarray:
    """`action` as a C-contiguous float32 array of `shape`, or a clear error."""
    a = np.asarray(action)
    if a.dtype.kind != "f":
        raise TypeError(f"actions must be floating point (float32 or float64), got dtype {a.dtype}")
    if a.shape != shape:
        raise ValueError(f"actions have shape {a.shape}, expected {shape}")
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"action {tuple(int(i) for i in bad)} is {a[tuple(bad)]}: actions must be finite")
    return np.ascontiguousarray(a, dtype=np.float32)


def _spaces(v) -> tuple[gym.spaces.Box, gym.spaces.Box]:
    obs = gym.spaces.Box(-np.inf, np.inf, shape=(v.obs_dim,), dtype=np.float32)
    b = v.action_bound
    act = gym.spaces.Box(-b, b, shape=(v.act_dim,), dtype=np.float32)
    return obs, act


class A1Env(gym.Env):
    """One environment of an A1 task (`A1ModelFree-v0`, `A1Imitation-v0`, `A1EempRl-v0`).

    `config`: a training config TOML (as `eemp train --config`, e.g. policies/a1_model_free.toml)
    for the task's settings; `motion`: the imitation task's reference motion file (default: the
    shipped `motions/a1_trot.csv`, built into the package); `robot`: a robot file
    (robots/go2.toml, robots/go1.toml, your own; default the A1), as `eemp train --robot`.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        task: str = "A1ModelFree-v0",
        config: str | None = None,
        motion: str | None = None,
        robot: str | None = None,
    ):
        self._v = _eemp.VecEnv(_task(task), num_envs=1, seed=0, threads=1, config=config, motion=motion, robot=robot)
        self.observation_space, self.action_space = _spaces(self._v)
        self.reward_terms = self._v.reward_terms
        self._episode_started_by_rust = False
        self._ready = False

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            obs = self._v.reset([int(seed) % 2**64])
        elif self._episode_started_by_rust:
            obs = self._v.observations()
        elif not self._ready:
            obs = self._v.reset([int(self.np_random.integers(2**63))])
        else:
            obs = self._v.reset()
        self._episode_started_by_rust = False
        self._ready = True
        return obs[0], {}

    def step(self, action):
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        a = _check_actions(action, self.action_space.shape)
        obs, rew, term, trunc, final_obs, invalid, terms = self._v.step(a[None, :])
        ended = bool(term[0] or trunc[0])
        self._episode_started_by_rust = ended
        info = {"reward_terms": dict(zip(self.reward_terms, terms[0].tolist())), "invalid": bool(invalid[0])}
        return (final_obs[0] if ended else obs[0]), float(rew[0]), bool(term[0]), bool(trunc[0]), info


class A1VectorEnv(gym.vector.VectorEnv):
    """N environments of an A1 task stepped in `threads` Rust worker threads per `step` call
    (numpy in, numpy out, the GIL released while they step). Same results whatever `threads`."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        task: str = "A1ModelFree-v0",
        num_envs: int = 1,
        threads: int | None = None,
        config: str | None = None,
        motion: str | None = None,
        robot: str | None = None,
    ):
        if not isinstance(num_envs, (int, np.integer)) or not 1 <= num_envs <= 65536:
            raise ValueError(f"num_envs {num_envs!r} is out of range: allowed an int in [1, 65536]")
        if threads is None:
            threads = min(num_envs, os.cpu_count() or 1)
        elif not isinstance(threads, (int, np.integer)) or not 1 <= threads <= 1024:
            raise ValueError(f"threads {threads!r} is out of range: allowed an int in [1, 1024]")
        self._v = _eemp.VecEnv(_task(task), num_envs=num_envs, seed=0, threads=threads, config=config, motion=motion, robot=robot)
        self.num_envs = num_envs
        self.single_observation_space, self.single_action_space = _spaces(self._v)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.reward_terms = self._v.reward_terms
        self._ready = False

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """seed: an int s (sub-env i gets `env_seed(s, i)`, as `eemp train`), a list of one seed
        per sub-env (None: drawn from `np_random`), or None (the first reset draws seeds from
        `np_random`; later ones continue each sub-env's RNG)."""
        if isinstance(seed, (int, np.integer)):
            if seed < 0:
                raise ValueError(f"seed {seed} must be a non-negative int")
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(int(seed))
            obs = self._v.reset([_eemp.env_seed_of(int(seed), i) for i in range(self.num_envs)])
        elif seed is None:
            obs = self._v.reset() if self._ready else self._v.reset(self._drawn_seeds())
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs or not all(
                s is None or (isinstance(s, (int, np.integer)) and s >= 0) for s in seeds
            ):
                raise ValueError(f"seed must be an int or a list of {self.num_envs} non-negative ints or None, got {seed!r}")
            drawn = self._drawn_seeds()
            obs = self._v.reset([drawn[i] if s is None else int(s) for i, s in enumerate(seeds)])
        self._ready = True
        return obs, {}

    def _drawn_seeds(self) -> list[int]:
        return [int(x) for x in self.np_random.integers(2**63, size=self.num_envs)]

    def step(self, actions):
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        a = _check_actions(actions, self.action_space.shape)
        obs, rew, term, trunc, final_obs, invalid, terms = self._v.step(a)
        ended = term | trunc
        final_obs[~ended] = 0.0  # rows of sub-envs whose episode goes on carry nothing
        ones = np.ones(self.num_envs, dtype=bool)
        infos = {
            "final_obs": final_obs,
            "_final_obs": ended,
            "invalid": invalid,
            "_invalid": ones,
            "reward_terms": terms,
            "_reward_terms": ones,
        }
        return obs, rew, term, trunc, infos
