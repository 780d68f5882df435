//! A trained policy (model-free or imitation) as a [`Controller`]: at the policy rate it builds
//! the same observation as in training, normalises it, takes the network's mean action and sets
//! joint targets; at every physics step the joint PD turns them into torques.

use crate::config::TaskKind;
use crate::imitation::motion::ReferenceMotion;
use crate::policy::Policy;
use crate::tasks::imitation::{ImitationAgent, ImitationMemory};
use crate::tasks::model_free::{joint_targets, observe, ModelFreeConfig, PolicyMemory};
use eemp_core::body_state::RobotState;
use eemp_core::controller::{ControlInput, Controller};
use eemp_core::joint_pd::JointPd;
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::locomotion::ControlOutput;
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use nalgebra::Vector3;
use std::path::Path;

/// The task-specific half of a policy controller: observation, targets, memory.
enum Agent {
    ModelFree {
        config: Box<ModelFreeConfig>,
        kin: Box<LegKinematics>,
        memory: PolicyMemory,
    },
    Imitation {
        agent: Box<ImitationAgent>,
        memory: ImitationMemory,
    },
}

pub struct PolicyController {
    policy: Policy,
    agent: Agent,
    q0: LegMap<Vector3<f64>>,
    pd: JointPd,
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
        policy.check_robot(robot)?;
        let q0 = robot.standing_pose();
        let (agent, period_s, pd_gains, obs_dim) = match policy.config.task {
            TaskKind::ModelFree => {
                let config = policy.config.model_free.clone();
                (
                    Agent::ModelFree {
                        kin: Box::new(LegKinematics::new(robot)),
                        memory: PolicyMemory::for_config(&config),
                        config: Box::new(config.clone()),
                    },
                    config.policy_period_s,
                    config.pd.clone(),
                    config.obs_dim(),
                )
            }
            TaskKind::Imitation => {
                let config = policy.config.imitation.clone();
                let text = policy
                    .motion
                    .as_deref()
                    .ok_or("the imitation policy carries no reference motion")?;
                let here = Path::new("<the policy's motion>");
                let motion = ReferenceMotion::parse(here, text).map_err(|e| e.to_string())?;
                motion
                    .check_against(&LegKinematics::new(robot), here)
                    .map_err(|e| e.to_string())?;
                (
                    Agent::Imitation {
                        agent: Box::new(ImitationAgent::new(config.clone(), &motion, robot)),
                        memory: ImitationMemory {
                            policy: PolicyMemory::new(config.history),
                            phase: 0.0,
                        },
                    },
                    config.policy_period_s,
                    config.pd.clone(),
                    config.obs_dim(),
                )
            }
            other => return Err(format!("a {} policy cannot drive the robot", other.name())),
        };
        let ratio = period_s / timestep_s;
        if (ratio - ratio.round()).abs() > 1e-6 || ratio < 1.0 {
            return Err(format!(
                "policy period {period_s} s is not a whole number of physics steps of {timestep_s} s"
            ));
        }
        Ok(PolicyController {
            pd: JointPd {
                gains: pd_gains,
                targets: q0,
                torque_limit_nm: robot.leg.torque_limit_nm,
            },
            agent,
            decimation: ratio.round() as usize,
            tick: 0,
            obs: vec![0.0; obs_dim],
            invalid_steps: 0,
            q0,
            policy,
        })
    }

    /// The joint pose the policy stands in (its action origin).
    pub fn default_pose(&self) -> LegMap<Vector3<f64>> {
        self.q0
    }

    /// Phase of the reference cycle (imitation policies).
    pub fn phase(&self) -> Option<f64> {
        match &self.agent {
            Agent::Imitation { memory, .. } => Some(memory.phase),
            Agent::ModelFree { .. } => None,
        }
    }

    fn start(&mut self, state: &RobotState) {
        match &mut self.agent {
            Agent::ModelFree { memory, .. } => memory.start(state, &self.q0),
            Agent::Imitation { memory, .. } => {
                memory.policy.start(state, &self.q0);
                memory.phase = 0.0;
            }
        }
    }

    fn write_obs(&mut self, state: &RobotState, command: &VelocityCommand) {
        match &self.agent {
            Agent::ModelFree {
                config,
                kin,
                memory,
            } => {
                observe(
                    &config.extra_obs,
                    kin,
                    &self.q0,
                    state,
                    command,
                    memory,
                    &mut self.obs,
                );
            }
            Agent::Imitation { agent, memory } => {
                agent.observe(state, command, memory, &mut self.obs)
            }
        }
    }

    fn apply(&mut self, state: &RobotState, command: &VelocityCommand, action: &[f32]) {
        match &mut self.agent {
            Agent::ModelFree { config, memory, .. } => {
                self.pd.targets = joint_targets(config, &self.q0, action);
                memory.push(state, &self.q0, action);
            }
            Agent::Imitation { agent, memory } => {
                self.pd.targets = agent.targets(memory.phase, command.vx_mps, action);
                memory.policy.push(state, &self.q0, action);
            }
        }
    }

    /// The reference moves on whether or not the action was usable.
    fn advance(&mut self, command: &VelocityCommand) {
        match &mut self.agent {
            Agent::Imitation { agent, memory } => {
                memory.phase = agent.next_phase(memory.phase, command.vx_mps);
            }
            Agent::ModelFree { memory, .. } => memory.advance_clock(),
        }
    }

    fn last_torques(&mut self) -> &mut [f64; 12] {
        match &mut self.agent {
            Agent::ModelFree { memory, .. } => &mut memory.last_torques,
            Agent::Imitation { memory, .. } => &mut memory.policy.last_torques,
        }
    }
}

impl Controller for PolicyController {
    fn control(&mut self, input: &ControlInput) -> ControlOutput {
        if self.tick == 0 {
            self.start(input.state);
        }
        if self.tick.is_multiple_of(self.decimation) {
            self.write_obs(input.state, &input.command);
            let action = if self.obs.iter().all(|v| v.is_finite()) {
                self.policy.act(&self.obs).ok()
            } else {
                None
            };
            match action.filter(|a| a.iter().all(|v| v.is_finite())) {
                Some(a) => self.apply(input.state, &input.command, &a),
                None => self.invalid_steps += 1,
            }
            self.advance(&input.command);
        }
        self.tick += 1;
        let out = self.pd.control(input);
        let tau = self.last_torques();
        for leg in Leg::ALL {
            let k = 3 * leg.index();
            tau[k..k + 3].copy_from_slice(out.torques[leg].as_slice());
        }
        out
    }

    fn needs_dynamics(&self) -> bool {
        false
    }
}
