"""Train the model-free A1 task with Stable-Baselines3's PPO on the vectorised environment.

    pip install stable-baselines3            # not a project dependency: brings torch
    python crates/eemp-py/examples/sb3_ppo.py --iterations 5 --envs 256 --threads 2

Stepping happens in Rust threads behind one call per batch (`eemp.A1VectorEnv`); this file only
adapts gymnasium's vector API (same-step autoreset, `final_obs`) to SB3's `VecEnv` and times
the run. PPO settings follow `policies/a1_model_free.toml` where SB3 has them (24 steps per env,
5 epochs, 4 minibatches, lr 3e-4, clip 0.2, γ 0.99, λ 0.95, 128×128 ELU networks).
"""

import argparse
import time

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv

import eemp


class Sb3VecEnv(VecEnv):
    """`eemp.A1VectorEnv` as an SB3 vectorised environment."""

    def __init__(self, venv: eemp.A1VectorEnv, seed: int):
        self.venv, self._seed, self._actions = venv, seed, None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    def reset(self):
        obs, _ = self.venv.reset(seed=self._seed)
        return obs

    def step_async(self, actions):
        self._actions = actions

    def step_wait(self):
        obs, rew, term, trunc, info = self.venv.step(self._actions)
        dones = term | trunc
        infos = [{} for _ in range(self.num_envs)]
        for i in np.nonzero(dones)[0]:
            infos[i]["terminal_observation"] = info["final_obs"][i]
            infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
        return obs, rew.astype(np.float32), dones, infos

    def close(self):
        pass

    def get_attr(self, attr_name, indices=None):
        return [getattr(self.venv, attr_name)] * self.num_envs

    def set_attr(self, attr_name, value, indices=None):
        raise AttributeError(f"{attr_name} cannot be set on the Rust environments")

    def env_method(self, method_name, *args, indices=None, **kwargs):
        raise AttributeError(f"{method_name} is not available on the Rust environments")

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * self.num_envs


def main():
    p = argparse.ArgumentParser(description="SB3 PPO on eemp's vectorised A1 task")
    p.add_argument("--task", default="A1ModelFree-v0", choices=list(eemp.TASKS))
    p.add_argument("--envs", type=int, default=256)
    p.add_argument("--iterations", type=int, default=5)
    p.add_argument("--threads", type=int, default=2, help="Rust stepping threads and torch threads")
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    env = Sb3VecEnv(eemp.make_vec_env(a.task, a.envs, threads=a.threads), a.seed)
    model = PPO(
        "MlpPolicy",
        env,
        n_steps=24,
        batch_size=a.envs * 24 // 4,
        n_epochs=5,
        learning_rate=3e-4,
        clip_range=0.2,
        gamma=0.99,
        gae_lambda=0.95,
        ent_coef=0.001,
        policy_kwargs=dict(net_arch=[128, 128], activation_fn=torch.nn.ELU),
        seed=a.seed,
        verbose=0,
        device="cpu",
    )
    steps = a.iterations * a.envs * 24
    t = time.perf_counter()
    model.learn(total_timesteps=steps)
    wall = time.perf_counter() - t
    print(f"SB3 PPO on {a.task}: {steps} env steps in {wall:.1f} s = {steps / wall:.0f} env steps/s "
          f"({a.envs} envs, {a.threads} threads)")


if __name__ == "__main__":
    main()
