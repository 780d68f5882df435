//! EEMP as a [`Controller`]: Algorithm 1 (planner) → MPC + swing law ([`LocomotionController`]),
//! and the standing variant (body-motion profile → MPC on four feet).

use crate::controller::{ControlInput, Controller};
use crate::leg::LegMap;
use crate::locomotion::{ControlOutput, LocomotionController, Plan};
use crate::planner::params_table::ParamsTable;
use crate::planner::{EemPlanner, PlannerParams};
use crate::stand_profile::StandPlanner;

/// Where the planner's five parameters come from at each step.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamsSource {
    /// One set for the whole run (e.g. the paper's Table II).
    Constant(PlannerParams),
    /// EEMP-Analytical: looked up per commanded speed |(v_x, v_y)|.
    Table(ParamsTable),
    /// EEMP-RL's residual: the table's parameters at the commanded speed moved by `delta`
    /// ([`PlannerParams::to_array`]'s order), clamped into the table's ranges
    /// ([`ParamsTable::param_ranges`]). A zero `delta` is the table, bit for bit.
    Residual { table: ParamsTable, delta: [f64; 5] },
}

impl ParamsSource {
    pub fn at_speed(&self, speed_mps: f64) -> PlannerParams {
        match self {
            ParamsSource::Constant(p) => *p,
            ParamsSource::Table(t) => t.lookup(speed_mps),
            ParamsSource::Residual { table, delta } => table
                .lookup(speed_mps)
                .offset_within(delta, &table.param_ranges()),
        }
    }
}

/// The walking controller of the paper.
#[derive(Clone)]
pub struct EempController {
    pub planner: EemPlanner,
    pub locomotion: LocomotionController,
    pub params: ParamsSource,
    last_plan: Option<Plan>,
    planning_time_s: f64,
}

impl EempController {
    pub fn new(
        planner: EemPlanner,
        locomotion: LocomotionController,
        params: ParamsSource,
    ) -> Self {
        EempController {
            planner,
            locomotion,
            params,
            last_plan: None,
            planning_time_s: 0.0,
        }
    }
}

impl Controller for EempController {
    fn control(&mut self, input: &ControlInput) -> ControlOutput {
        let t = input.state.time_s;
        // On a floor slip handling found slippery, the command's speed is capped (as of the
        // last step, as the friction cone below).
        let speed_cap_mps = self.locomotion.speed_cap_mps();
        let c = match speed_cap_mps {
            Some(v) => input.command.with_speed_at_most(v),
            None => input.command,
        };
        let started = std::time::Instant::now();
        // The slip detector's coefficient as of the last step (the nominal until a slip).
        let mu = self.locomotion.friction_coefficient();
        let params = self.planner.config().within_friction_cone(
            &self.params.at_speed(c.vx_mps.hypot(c.vy_mps)),
            mu,
            &c,
        );
        let mut plan = self
            .planner
            .plan(t, input.state, input.feet_world, &c, &params, mu);
        plan.speed_cap_mps = speed_cap_mps;
        self.planning_time_s = started.elapsed().as_secs_f64();
        let out = self
            .locomotion
            .update(t, input.state, &plan, input.dynamics);
        self.last_plan = Some(plan);
        out
    }

    fn plan(&self) -> Option<&Plan> {
        self.last_plan.as_ref()
    }

    fn steps(&self) -> Option<LegMap<usize>> {
        Some(self.planner.steps())
    }

    fn last_planning_time_s(&self) -> f64 {
        self.planning_time_s
    }
}

/// Standing: the body follows a motion profile with all four feet down (the command is unused).
pub struct StandController {
    pub planner: StandPlanner,
    pub locomotion: LocomotionController,
    last_plan: Option<Plan>,
}

impl StandController {
    pub fn new(planner: StandPlanner, locomotion: LocomotionController) -> Self {
        StandController {
            planner,
            locomotion,
            last_plan: None,
        }
    }
}

impl Controller for StandController {
    fn control(&mut self, input: &ControlInput) -> ControlOutput {
        let t = input.state.time_s;
        let plan = self.planner.plan(t, input.feet_world);
        let out = self
            .locomotion
            .update(t, input.state, &plan, input.dynamics);
        self.last_plan = Some(plan);
        out
    }

    fn plan(&self) -> Option<&Plan> {
        self.last_plan.as_ref()
    }
}
