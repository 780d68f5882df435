//! A trained model-free policy as a [`Controller`]: at the policy rate it builds the same
//! observation as in training, normalises it, takes the network's mean action and sets joint
//! targets; at every physics step the joint PD turns them into torques.

use crate::config::TaskKind;
use crate::policy::Policy;
use crate::tasks::model_free::{joint_targets, observe, ModelFreeConfig, PolicyMemory};
use eemp_core::control::{ControlInput, Controller};
use eemp_core::controller::ControlOutput;
use eemp_core::joint_pd::JointPd;
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::robot::RobotConfig;
use nalgebra::Vector3;

pub struct PolicyController {
    policy: Policy,
    config: ModelFreeConfig,
    kin: LegKinematics,
    q0: LegMap<Vector3<f64>>,
    pd: JointPd,
    memory: PolicyMemory,
    /// Physics steps per policy step.
    decimation: usize,
    tick: usize,
    obs: Vec<f32>,
    /// Policy steps whose observation or action was not finite (the last targets were held).
    pub invalid_steps: usize,
}

impl PolicyController {
    /// `timestep_s`: the physics step of the loop it will run in.
    pub fn new(policy: Policy, robot: &RobotConfig, timestep_s: f64) -> Result<Self, String> {
        if policy.config.task != TaskKind::ModelFree {
            return Err(format!(
                "a {} policy cannot drive the robot",
                policy.config.task.name()
            ));
        }
        let config = policy.config.model_free.clone();
        let ratio = config.policy_period_s / timestep_s;
        if (ratio - ratio.round()).abs() > 1e-6 || ratio < 1.0 {
            return Err(format!(
                "policy period {} s is not a whole number of physics steps of {timestep_s} s",
                config.policy_period_s
            ));
        }
        let q0 = robot.standing_pose();
        Ok(PolicyController {
            kin: LegKinematics::new(robot),
            pd: JointPd {
                gains: config.pd.clone(),
                targets: q0,
                torque_limit_nm: robot.leg.torque_limit_nm,
            },
            memory: PolicyMemory::new(config.history),
            decimation: ratio.round() as usize,
            tick: 0,
            obs: vec![0.0; config.obs_dim()],
            invalid_steps: 0,
            q0,
            config,
            policy,
        })
    }

    /// The joint pose the policy stands in (its action origin).
    pub fn default_pose(&self) -> LegMap<Vector3<f64>> {
        self.q0
    }
}

impl Controller for PolicyController {
    fn control(&mut self, input: &ControlInput) -> ControlOutput {
        if self.tick == 0 {
            self.memory.start(input.state, &self.q0);
        }
        if self.tick.is_multiple_of(self.decimation) {
            observe(
                &self.config,
                &self.kin,
                &self.q0,
                input.state,
                &input.command,
                &self.memory,
                &mut self.obs,
            );
            let action = if self.obs.iter().all(|v| v.is_finite()) {
                self.policy.act(&self.obs).ok()
            } else {
                None
            };
            match action.filter(|a| a.iter().all(|v| v.is_finite())) {
                Some(a) => {
                    self.pd.targets = joint_targets(&self.config, &self.q0, &a);
                    self.memory.push(input.state, &self.q0, &a);
                }
                None => self.invalid_steps += 1,
            }
        }
        self.tick += 1;
        let out = self.pd.control(input);
        for leg in Leg::ALL {
            let k = 3 * leg.index();
            self.memory.last_torques[k..k + 3].copy_from_slice(out.torques[leg].as_slice());
        }
        out
    }

    fn needs_dynamics(&self) -> bool {
        false
    }
}
