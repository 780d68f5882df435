//! A MuJoCo cart-pole the project builds itself: PPO's test task (balance a pole on a cart with
//! a bounded force; +1 per step upright). Small enough to learn in seconds, hard enough that a
//! learning rate of 0 does not.

use crate::env::{Env, StepInfo};
use eemp_core::config_error::{check_range, ConfigError};
use mujoco_rs::prelude::*;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CartPoleConfig {
    /// Policy steps per episode (time limit).
    pub max_steps: usize,
    /// Force at action 1, N.
    pub max_force_n: f64,
    /// The episode fails beyond this pole angle, rad.
    pub max_angle_rad: f64,
}

impl Default for CartPoleConfig {
    fn default() -> Self {
        CartPoleConfig {
            max_steps: 200,
            max_force_n: 20.0,
            max_angle_rad: 0.4,
        }
    }
}

impl CartPoleConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("cart_pole.max_steps", self.max_steps as f64, 1.0, 1e5)?;
        check_range("cart_pole.max_force_n", self.max_force_n, 0.1, 1000.0)?;
        check_range("cart_pole.max_angle_rad", self.max_angle_rad, 0.01, 1.5)
    }
}

const XML: &str = r#"<mujoco model="cartpole">
  <option timestep="0.01" integrator="RK4"/>
  <worldbody>
    <body name="cart">
      <joint name="slider" type="slide" axis="1 0 0" range="-2.4 2.4" limited="true"/>
      <geom type="box" size="0.2 0.1 0.05" mass="1" contype="0" conaffinity="0"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.6" size="0.02" mass="0.1" contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="slider" gear="1" ctrlrange="-1000 1000"/></actuator>
</mujoco>"#;

pub fn cartpole_model() -> Result<Arc<MjModel>, String> {
    MjModel::from_xml_string(XML)
        .map(Arc::new)
        .map_err(|e| format!("cart-pole model: {e}"))
}

pub struct CartPole {
    data: MjData<Arc<MjModel>>,
    config: CartPoleConfig,
    steps: usize,
    fell: bool,
}

impl CartPole {
    pub fn new(model: Arc<MjModel>, config: CartPoleConfig) -> Self {
        CartPole {
            data: MjData::new(model),
            config,
            steps: 0,
            fell: false,
        }
    }

    fn observe(&self, obs: &mut [f32]) {
        let (q, v) = (self.data.qpos(), self.data.qvel());
        obs.copy_from_slice(&[q[0] as f32, q[1] as f32, v[0] as f32, v[1] as f32]);
    }
}

impl Env for CartPole {
    fn obs_dim(&self) -> usize {
        4
    }
    fn act_dim(&self) -> usize {
        1
    }
    fn reward_terms(&self) -> &'static [&'static str] {
        &["alive"]
    }
    fn reset(&mut self, rng: &mut ChaCha8Rng, obs: &mut [f32]) {
        self.data.reset();
        for i in 0..2 {
            self.data.qpos_mut()[i] = rng.random_range(-0.05..0.05);
            self.data.qvel_mut()[i] = rng.random_range(-0.05..0.05);
        }
        self.data.forward();
        self.steps = 0;
        self.fell = false;
        self.observe(obs);
    }
    fn step(
        &mut self,
        action: &[f32],
        _rng: &mut ChaCha8Rng,
        obs: &mut [f32],
        terms: &mut [f64],
    ) -> StepInfo {
        self.data.ctrl_mut()[0] = (action[0] as f64).clamp(-1.0, 1.0) * self.config.max_force_n;
        for _ in 0..2 {
            self.data.step();
        }
        self.steps += 1;
        self.observe(obs);
        let (x, theta) = (self.data.qpos()[0], self.data.qpos()[1]);
        self.fell = theta.abs() > self.config.max_angle_rad || x.abs() > 2.3;
        terms[0] = 1.0;
        StepInfo {
            reward: 1.0,
            terminated: self.fell,
            truncated: !self.fell && self.steps >= self.config.max_steps,
            invalid: false,
            periods: None,
        }
    }
    fn fell(&self) -> bool {
        self.fell
    }
    fn observe(&self, obs: &mut [f32]) {
        CartPole::observe(self, obs)
    }
    fn save_state(&self) -> serde_json::Value {
        serde_json::json!({
            "time": self.data.ffi().time,
            "qpos": self.data.qpos(),
            "qvel": self.data.qvel(),
            "steps": self.steps,
        })
    }
    fn load_state(&mut self, s: &serde_json::Value) -> Result<(), String> {
        let v = |k: &str| -> Result<Vec<f64>, String> {
            serde_json::from_value(s[k].clone()).map_err(|e| format!("cart-pole state {k}: {e}"))
        };
        let (q, qd) = (v("qpos")?, v("qvel")?);
        if q.len() != 2 || qd.len() != 2 {
            return Err("cart-pole state has the wrong size".into());
        }
        self.data.qpos_mut().copy_from_slice(&q);
        self.data.qvel_mut().copy_from_slice(&qd);
        // SAFETY: plain field write on data this env owns.
        unsafe { self.data.ffi_mut().time = s["time"].as_f64().unwrap_or(0.0) };
        self.steps = s["steps"].as_u64().unwrap_or(0) as usize;
        self.data.forward();
        Ok(())
    }
}
