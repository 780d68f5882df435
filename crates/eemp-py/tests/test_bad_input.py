"""Bad arguments raise Python exceptions with a message naming the value; nothing crashes."""

import numpy as np
import pytest

import eemp
from eemp import _eemp


def test_unknown_task():
    with pytest.raises(ValueError, match="unknown task 'A1Fly-v0'.*A1ModelFree-v0"):
        eemp.make_env("A1Fly-v0")
    with pytest.raises(ValueError, match="cart-pole"):
        _eemp.VecEnv("cart-pole")
    with pytest.raises(ValueError, match="unknown task 'fly': allowed model-free, imitation, eemp-rl"):
        _eemp.VecEnv("fly")
    with pytest.raises(ValueError, match="motion is for the imitation task"):
        eemp.make_env("A1ModelFree-v0", motion="motions/a1_trot.csv")


@pytest.mark.parametrize("num_envs", [0, 100000])
def test_num_envs_out_of_range(num_envs):
    with pytest.raises(ValueError, match=r"num_envs .* out of range: allowed \[1, 65536\]"):
        _eemp.VecEnv("model-free", num_envs=num_envs)
    with pytest.raises(ValueError, match=r"num_envs .* out of range"):
        eemp.make_vec_env("A1ModelFree-v0", num_envs)
    with pytest.raises(ValueError, match=r"threads 0 is out of range"):
        eemp.make_vec_env("A1ModelFree-v0", 2, threads=0)


def test_wrong_action_shape_dtype_and_nan():
    env = eemp.make_env("A1ModelFree-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(11,\), expected \(12,\)"):
        env.step(np.zeros(11, np.float32))
    with pytest.raises(TypeError, match="floating point.*int64"):
        env.step(np.zeros(12, np.int64))
    bad = np.zeros(12, np.float32)
    bad[4] = np.nan
    with pytest.raises(ValueError, match=r"action \(4,\) is nan"):
        env.step(bad)
    # The environment is still usable.
    env.step(np.zeros(12, np.float64))

    v = eemp.make_vec_env("A1ModelFree-v0", 2)
    v.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(12,\), expected \(2, 12\)"):
        v.step(np.zeros(12, np.float32))
    inf = np.zeros((2, 12), np.float32)
    inf[1, 3] = np.inf
    with pytest.raises(ValueError, match=r"action \(1, 3\) is inf"):
        v.step(inf)


def test_raw_module_checks_too():
    v = _eemp.VecEnv("model-free", num_envs=2)
    with pytest.raises(ValueError, match=r"shape \[2, 5\], expected \[2, 12\]"):
        v.step(np.zeros((2, 5), np.float32))
    nan = np.zeros((2, 12), np.float32)
    nan[0, 0] = np.nan
    with pytest.raises(ValueError, match="must be finite"):
        v.step(nan)
    with pytest.raises(TypeError):
        v.step(np.zeros((2, 12), np.float64))
    with pytest.raises(ValueError, match="3 seeds for 2 environments"):
        v.reset([1, 2, 3])
    with pytest.raises(ValueError, match=r"shape \[4, 2, 5\], expected \[T, 2, 12\]"):
        _eemp.rust_rollout("model-free", 0, np.zeros((4, 2, 5), np.float32))


def test_step_before_reset():
    with pytest.raises(RuntimeError, match="reset"):
        eemp.make_env("A1ModelFree-v0").step(np.zeros(12, np.float32))


def test_config_for_another_task_and_missing_files(tmp_path):
    other = tmp_path / "imitation.toml"
    other.write_text('task = "imitation"\n')
    with pytest.raises(ValueError, match="is for task 'imitation', not 'model-free'"):
        eemp.make_env("A1ModelFree-v0", config=str(other))
    with pytest.raises(ValueError, match="nope.toml"):
        eemp.make_env("A1ModelFree-v0", config=str(tmp_path / "nope.toml"))
    bad = tmp_path / "bad.toml"
    bad.write_text('task = "model-free"\n[model_free]\nepisode_s = -3\n')
    with pytest.raises(ValueError, match="episode_s"):
        eemp.make_env("A1ModelFree-v0", config=str(bad))
    with pytest.raises(ValueError, match="missing.csv"):
        eemp.make_env("A1Imitation-v0", motion=str(tmp_path / "missing.csv"))


def test_controller_and_walk_arguments():
    c = eemp.EempController()
    z3, z12 = np.zeros(3), np.zeros(12)
    with pytest.raises(ValueError, match="quat_wxyz has norm 2"):
        c.step(0.0, z3, np.array([2.0, 0, 0, 0]), z3, z3, z12, z12)
    with pytest.raises(ValueError, match=r"q has 11 values, expected 12"):
        c.step(0.0, z3, np.array([1.0, 0, 0, 0]), z3, z3, np.zeros(11), z12)
    with pytest.raises(ValueError, match=r"v_world\[1\] is NaN"):
        c.step(0.0, z3, np.array([1.0, 0, 0, 0]), np.array([0, np.nan, 0]), z3, z12, z12)
    with pytest.raises((TypeError, ValueError), match="'q'"):
        c.step(0.0, z3, [1.0, 0, 0, 0], z3, z3, "twelve", z12)
    # Lists and float32 arrays are numbers too.
    tau = c.step(0.0, [0, 0, 0.3], [1, 0, 0, 0], z3, z3, np.zeros(12, np.float32), [0.0] * 12)
    assert tau.shape == (12,)
    with pytest.raises(ValueError, match="unknown gait 'gallop'"):
        eemp.EempController(gait="gallop")
    with pytest.raises(ValueError, match="unknown estimator 'oracle'"):
        eemp.walk(duration_s=1.0, estimator="oracle")
    with pytest.raises(ValueError, match=r"duration_s -1.* allowed \(0, 3600\]"):
        eemp.walk(duration_s=-1.0)
