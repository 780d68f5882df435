"""The gymnasium environments against the Rust tasks they wrap."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import eemp
from eemp import _eemp

SHORT_EPISODES = """
task = "model-free"
[model_free]
episode_s = 0.5
"""


@pytest.mark.parametrize("task", list(eemp.TASKS))
def test_gymnasium_checker_passes(task):
    env = gym.make(task)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape


def python_rollout(env, seed, actions):
    """Observations after every step as Rust's auto-resetting loop sees them, and the final
    observation of each step that ended an episode (zeros elsewhere)."""
    obs, _ = env.reset(seed=seed)
    seen, rewards, term, trunc, finals = [obs], [], [], [], []
    for a in actions:
        o, r, te, tr, _ = env.step(a)
        finals.append(o if te or tr else np.zeros_like(o))
        if te or tr:
            o, _ = env.reset()  # the episode Rust already started
        seen.append(o)
        rewards.append(r)
        term.append(te)
        trunc.append(tr)
    return np.array(seen), np.array(rewards), np.array(term), np.array(trunc), np.array(finals)


@pytest.mark.parametrize("task,steps", [("A1ModelFree-v0", 120), ("A1Imitation-v0", 60), ("A1EempRl-v0", 12)])
def test_python_rollout_is_the_rust_rollout_bit_for_bit(task, steps):
    env = eemp.make_env(task)
    actions = np.random.default_rng(5).uniform(-1, 1, (steps, env.action_space.shape[0])).astype(np.float32)
    obs, rew, term, trunc, _ = python_rollout(env, eemp.env_seed(11, 0), actions)
    r_obs, r_rew, r_term, r_trunc, _ = _eemp.rust_rollout(eemp.TASKS[task], 11, actions[:, None, :])
    assert np.array_equal(obs, r_obs[:, 0, :])
    assert np.array_equal(rew, r_rew[:, 0])
    assert np.array_equal(term, r_term[:, 0])
    assert np.array_equal(trunc, r_trunc[:, 0])


def test_rollout_through_episode_ends_is_bit_for_bit(tmp_path):
    config = tmp_path / "short.toml"
    config.write_text(SHORT_EPISODES)
    env = eemp.make_env("A1ModelFree-v0", config=str(config))
    actions = np.random.default_rng(6).uniform(-1, 1, (80, 12)).astype(np.float32)
    obs, rew, term, trunc, finals = python_rollout(env, eemp.env_seed(3, 0), actions)
    assert trunc.sum() >= 2, "25-step episodes must end within 80 steps"
    r_obs, r_rew, _, r_trunc, r_finals = _eemp.rust_rollout("model-free", 3, actions[:, None, :], config=str(config))
    assert np.array_equal(obs, r_obs[:, 0, :])
    assert np.array_equal(finals, r_finals[:, 0, :]), "step() returns the ended episode's last observation"
    assert not np.array_equal(finals[trunc], obs[1:][trunc]), "and not the next episode's first"
    assert np.array_equal(rew, r_rew[:, 0])
    assert np.array_equal(trunc, r_trunc[:, 0])


def test_same_seed_same_rollout_and_seeds_matter():
    env = eemp.make_env("A1ModelFree-v0")
    actions = np.random.default_rng(1).uniform(-1, 1, (30, 12)).astype(np.float32)
    a = python_rollout(env, 4, actions)[:4]
    b = python_rollout(env, 4, actions)[:4]
    c = python_rollout(env, 5, actions)[:4]
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


def test_vector_env_equals_n_single_envs_whatever_the_threads(tmp_path):
    config = tmp_path / "short.toml"
    config.write_text(SHORT_EPISODES)
    n, steps, seed = 4, 40, 9
    actions = np.random.default_rng(2).uniform(-1, 1, (steps, n, 12)).astype(np.float32)
    runs = []
    for threads in (1, 3):
        v = eemp.make_vec_env("A1ModelFree-v0", n, threads=threads, config=str(config))
        obs, _ = v.reset(seed=seed)
        out = [(obs, None, None, None)]
        for a in actions:
            o, r, te, tr, info = v.step(a)
            out.append((o, r, te, tr, info["final_obs"].copy()))
        runs.append(out)
    for x, y in zip(*runs):
        for p, q in zip(x, y):
            assert p is None or np.array_equal(p, q)
    for i in range(n):
        single = eemp.make_env("A1ModelFree-v0", config=str(config))
        obs, rew, term, trunc, finals = python_rollout(single, eemp.env_seed(seed, i), actions[:, i, :])
        assert np.array_equal(obs[0], runs[0][0][0][i])
        for t in range(steps):
            o, r, te, tr, final = runs[0][t + 1]
            assert r[i] == rew[t] and te[i] == term[t] and tr[i] == trunc[t]
            assert np.array_equal(o[i], obs[t + 1])
            assert np.array_equal(final[i], finals[t])
    assert any((run[2] | run[3]).any() for run in runs[0][1:]), "some episode must end in the window"


def test_vector_env_is_the_rust_trainers_seeding():
    n, seed = 3, 21
    actions = np.random.default_rng(8).uniform(-1, 1, (10, n, 12)).astype(np.float32)
    v = eemp.make_vec_env("A1ModelFree-v0", n)
    obs, _ = v.reset(seed=seed)
    seen = [obs]
    for a in actions:
        seen.append(v.step(a)[0])
    r_obs, *_ = _eemp.rust_rollout("model-free", seed, actions)
    assert r_obs.shape == (11, n, 96)
    assert np.array_equal(np.array(seen), r_obs)


def test_final_obs_and_truncation_in_vector_env(tmp_path):
    config = tmp_path / "short.toml"
    config.write_text(SHORT_EPISODES)
    v = eemp.make_vec_env("A1ModelFree-v0", 2, config=str(config))
    v.reset(seed=0)
    zero = np.zeros((2, 12), np.float32)
    ends = np.zeros(2, int)
    for t in range(50):
        obs, rew, term, trunc, info = v.step(zero)
        assert not term.any(), "standing still does not fall"
        assert np.array_equal(info["_final_obs"], trunc)
        for i in range(2):
            if trunc[i]:
                ends[i] += 1
                assert not np.array_equal(info["final_obs"][i], obs[i]), "obs is the new episode's first"
            else:
                assert not info["final_obs"][i].any(), "rows of running episodes are zero"
    # 25-step episodes, the first one full-length too (no training stagger): ends at 25 and 50.
    assert (ends == 2).all(), ends


def test_the_first_episode_of_a_fresh_env_runs_its_full_length():
    env = gym.make("A1ModelFree-v0")
    env.reset(seed=0)
    zero = np.zeros(12, np.float32)
    for t in range(1, 1001):
        _, _, term, trunc, _ = env.step(zero)
        assert not term, f"standing still fell at step {t}"
        assert trunc == (t == 1000), f"truncated at step {t} of a 1000-step (20 s) episode"



def test_two_python_threads_on_one_vector_env_do_not_deadlock():
    # Each step releases the GIL while Rust steps; a second thread waiting for the environments
    # must wait without it. Run in a child interpreter: a deadlock would freeze this one.
    import subprocess
    import sys

    code = """
import threading, numpy as np, eemp
v = eemp.make_vec_env("A1ModelFree-v0", 16, threads=2)
v.reset(seed=0)
def work():
    for _ in range(20):
        v.step(np.zeros((16, 12), np.float32))
        v._v.observations()  # a second method taking the same lock
ts = [threading.Thread(target=work) for _ in range(3)]
[t.start() for t in ts]
[t.join() for t in ts]
print("done")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "done", out.stderr


def test_seeds_of_the_vector_env():
    v = eemp.make_vec_env("A1ModelFree-v0", 2)
    a, _ = v.reset(seed=[5, None])
    b, _ = eemp.make_env("A1ModelFree-v0").reset(seed=5)
    assert np.array_equal(a[0], b)
    with pytest.raises(ValueError, match="non-negative"):
        v.reset(seed=-1)
    with pytest.raises(ValueError, match="list of 2"):
        v.reset(seed=[1, 2, 3])
    first = [eemp.make_vec_env("A1ModelFree-v0", 2).reset()[0] for _ in range(2)]
    assert not np.array_equal(first[0], first[1]), "unseeded first resets draw their seeds"


def test_a_robot_file_makes_the_task_that_robots():
    import pathlib

    go2 = str(pathlib.Path(__file__).resolve().parents[3] / "robots/go2.toml")
    a1, other = eemp.make_env("A1ModelFree-v0"), eemp.make_env("A1ModelFree-v0", robot=go2)
    zero = np.zeros(12, dtype=np.float32)
    a1.reset(seed=4)
    other.reset(seed=4)
    (o_a1, *_), (o_go2, *_) = a1.step(zero), other.step(zero)
    # Same seed and action, another body: the Go2 (15 kg, its own pose) moves otherwise.
    assert o_a1.shape == o_go2.shape and not np.array_equal(o_a1, o_go2)
    with pytest.raises(ValueError, match="nosuch.toml"):
        eemp.make_env("A1ModelFree-v0", robot="nosuch.toml")
