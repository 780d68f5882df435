//! What a planner hands the controller at every control step: the [`Plan`] (stance, swing
//! references, the body reference over the MPC's horizon) and, for viewers and traces, the
//! planner's own [`PlanGeometry`]. Standing plans (`stand_profile`) are plans too.

use super::{PlannedSwing, PlannerParams};
use crate::body_reference::BodyReference;
use crate::leg::LegMap;
use crate::leg_control::FootReference;
use nalgebra::Vector3;

/// What a planner hands the controller at every control step.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Legs commanded to stance now (C_ref at this instant).
    pub stance: LegMap<bool>,
    /// Swing references (body frame) for legs not in stance.
    pub swing: LegMap<Option<FootReference>>,
    /// Body reference now (for tracking metrics).
    pub body_now: BodyReference,
    /// Body reference at the end of each MPC step.
    pub body_horizon: Vec<BodyReference>,
    /// Foot positions (world) during each MPC step.
    pub feet_horizon_world: Vec<LegMap<Vector3<f64>>>,
    /// Contact schedule C_ref over the MPC horizon.
    pub contacts_horizon: Vec<LegMap<bool>>,
    /// The planner parameters this plan was made with (None: a plan without them, standing).
    pub params: Option<PlannerParams>,
    /// The planner's own geometry at this step (None: a plan without it, standing).
    pub geometry: Option<PlanGeometry>,
    /// The speed cap slip handling put on the command for a floor it found slippery, m/s
    /// (`slip.slow_below_friction`; None: the command as given).
    pub speed_cap_mps: Option<f64>,
}

/// What Algorithm 1 sees and decides at one step, in the world frame, for viewers and traces:
/// eq. (5)'s placement ellipses and the running swings (eq. 6's touchdowns, eq. 7's paths).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanGeometry {
    /// Each ellipse's centre: the nominal foothold under the hip, on the ground the stance feet
    /// stand on (z: ground plus the foot radius, as a touchdown), m.
    pub ellipse_centres_world: LegMap<Vector3<f64>>,
    /// The ellipses' axes follow the heading (yaw only), rad.
    pub heading_yaw_rad: f64,
    /// Semi-axes r_x (along the heading) and r_y, m.
    pub ellipse_rx_m: f64,
    pub ellipse_ry_m: f64,
    /// Eq. (5)'s left-hand side per foot: above 1, the foot is outside its ellipse.
    pub ellipse_values: LegMap<f64>,
    /// The running swings (None: the leg is in stance).
    pub swings: LegMap<Option<PlannedSwing>>,
}
