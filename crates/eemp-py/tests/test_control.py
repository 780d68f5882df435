"""EEMP from Python: the controller in a loop the caller owns, and whole walks."""

import numpy as np

import eemp


def test_controller_walks_the_a1_from_a_python_loop():
    sim, ctl = eemp.A1Sim(), eemp.EempController(gait="trot")
    start = sim.state()
    for _ in range(int(3.0 / sim.timestep_s)):
        s = sim.state()
        command = (0.3, 0.0, 0.0) if s["time_s"] >= 0.5 else (0.0, 0.0, 0.0)
        tau = ctl.step(s["time_s"], s["p_world"], s["quat_wxyz"], s["v_world"], s["omega_world"], s["q"], s["qd"], command)
        assert tau.shape == (12,) and np.all(np.isfinite(tau))
        sim.step(tau)
    end = sim.state()
    assert end["p_world"][2] > 0.2, "trunk stays up"
    assert end["p_world"][0] - start["p_world"][0] > 0.4, "0.3 m/s for 2.5 s goes forward"
    assert ctl.stance() is not None


def test_walk_returns_the_summary_metrics():
    s = eemp.walk(gait="trot", speed=0.4, duration_s=4.0)
    assert 0.0 < s["cot"] < 2.0 and 0.0 < s["vel_rmse_mps"] < 0.2
    assert s["distance_m"] > 0.5 and s["steps_total"] > 10
    again = eemp.walk(gait="trot", speed=0.4, duration_s=4.0)
    assert {**again, "realtime_factor": None} == {**s, "realtime_factor": None}, "same seed, same walk"


def test_walk_takes_a_robot_file_and_refuses_another_robots_table():
    import pathlib

    import pytest

    root = pathlib.Path(__file__).resolve().parents[3]
    go1, a1_table = root / "robots" / "go1.toml", root / "tables" / "a1_trot.toml"
    s = eemp.walk(gait="trot", speed=0.3, duration_s=3.0, robot=str(go1),
                  params_table=str(root / "tables" / "go1_trot.toml"))
    assert s["fell"] is False and s["distance_m"] > 0.3
    a1 = eemp.walk(gait="trot", speed=0.3, duration_s=3.0)
    assert s["cot"] != a1["cot"], "another robot, another walk"
    with pytest.raises(ValueError, match="'go1'"):
        eemp.walk(duration_s=1.0, robot=str(go1), params_table=str(a1_table))
    with pytest.raises(ValueError, match="'go1'"):
        eemp.EempController(gait="trot", params_table=str(a1_table), robot=str(go1))


def test_settings_reach_the_walk_and_typos_are_refused_by_name():
    import pytest

    plain = eemp.walk(gait="trot", speed=0.3, duration_s=3.0)
    s = eemp.walk(gait="trot", speed=0.3, duration_s=3.0, settings=["schedule.mpc_period_s=0.04"])
    assert s["settings"] == ["schedule.mpc_period_s=0.04"] and plain["settings"] == []
    assert s["mpc_solves"] < plain["mpc_solves"], "the MPC solves half as often"
    with pytest.raises(ValueError, match="mpc.horizn"):
        eemp.walk(duration_s=1.0, settings=["mpc.horizn=12"])
    with pytest.raises(ValueError, match=r"mpc.horizon = 0 is out of range: allowed \[1, 40\]"):
        eemp.EempController(gait="trot", settings=["mpc.horizon=0"])
