//! `--mpc-friction`, `--mpc-horizon`, `--mpc-period`, `--adapt-friction`/`--no-adapt-friction`,
//! `--initial-friction`, `--hold-cap-after-slip`, `--hold-raise-fraction`,
//! `--ellipse-friction-factor`: the MPC's settings and slip handling of
//! a walk.

#[derive(clap::Args, Clone, Debug)]
pub struct MpcArgs {
    /// Friction coefficient the MPC assumes (its friction pyramid); keep it at or below the
    /// floor's. Default: `MpcConfig`'s 0.6.
    #[arg(long)]
    pub mpc_friction: Option<f64>,
    /// No slip handling (`eemp_core::slip`, on by default for every gait, the walk's below
    /// 0.6 m/s: a sliding stance foot lowers the MPC's friction coefficient, a holding one
    /// raises it).
    #[arg(long, conflicts_with = "adapt_friction")]
    pub no_adapt_friction: bool,
    /// Slip handling on (the default for every gait, so this only restates it; the walk's
    /// runs below 0.6 m/s, above which its landing feet skid on any floor:
    /// `SlipConfig::default_for`, `--slip-max-speed`).
    #[arg(long)]
    pub adapt_friction: bool,
    /// With slip handling: the friction coefficient it starts from, raised by stance feet that
    /// hold (`slip.initial_friction`; default: the robot file's `control.slip_initial_friction`,
    /// else 0.3; the MPC's coefficient or above: no cautious start).
    #[arg(long)]
    pub initial_friction: Option<f64>,
    /// With slip handling: the floor of its coefficient, which slips never take it below
    /// (`slip.min_friction`, 0.05–2; default: the gait's, 0.15 for the trot and the free gait,
    /// 0.2 for the walk; the walk's --slow-below-friction, 0.205, must stay above it).
    #[arg(long)]
    pub min_friction: Option<f64>,
    /// With slip handling: after a slip, feet that hold raise the coefficient to at most this
    /// factor × the coefficient at that slip (`slip.hold_cap_after_slip`; default 0.95; 0: no cap).
    #[arg(long)]
    pub hold_cap_after_slip: Option<f64>,
    /// With slip handling: a foot that holds raises the coefficient to this fraction of the
    /// tangential/normal ratio the MPC asked of it (`slip.hold_raise_fraction`, 0.1–1; default:
    /// the gait's, 0.8 for the trot and the free gait, 1 for the walk).
    #[arg(long)]
    pub hold_raise_fraction: Option<f64>,
    /// With slip handling: the planner's reference speed above which it rests at the nominal
    /// coefficient, m/s (`slip.max_speed_mps`, 0–10; 0: no limit; default: the gait's, the
    /// walk's 0.6, none for the trot and the free gait).
    #[arg(long)]
    pub slip_max_speed: Option<f64>,
    /// With slip handling: once its coefficient is below this, the command's speed is capped at
    /// --slow-speed until the coefficient is back at 0.25 (`slip.slow_below_friction`: 0, never,
    /// or above the coefficient's floor (0.15; the walk's 0.2) up to 0.25; default: the gait's,
    /// the walk's 0.205, none for the trot and the free gait).
    #[arg(long)]
    pub slow_below_friction: Option<f64>,
    /// With slip handling: the speed cap on a floor found slippery, m/s (`slip.slow_speed_mps`,
    /// 0–10; default 0.3; refused where the cap is off: give --slow-below-friction for the trot
    /// and the free gait).
    #[arg(long)]
    pub slow_speed: Option<f64>,
    /// The placement ellipses stay within the friction cone seen from the hip: r ≤ factor · μ̂
    /// · X_z, μ̂ the slip detector's coefficient (`planner.ellipse_friction_factor`, 0–3; 0:
    /// off; default: the gait's, 1 for the trot and the free gait, 0 for the walk).
    #[arg(long)]
    pub ellipse_friction_factor: Option<f64>,
    /// Eq. (6)'s capture step (its feedback term) stays within the friction cone: at most
    /// factor · μ̂ · X_z, μ̂ the MPC's coefficient (`planner.touchdown_friction_factor`, 0–3;
    /// 0: the paper's unbounded step; default: the gait's, 0.5 for the trot and the free gait, 0
    /// for the walk).
    #[arg(long)]
    pub touchdown_friction_factor: Option<f64>,
    /// MPC horizon, steps of its dt (default: MpcConfig's 10).
    #[arg(long)]
    pub mpc_horizon: Option<usize>,
    /// Time between MPC solves, s (a stance change also triggers a solve).
    #[arg(long, default_value_t = eemp_core::controller::ControllerConfig::default().mpc_period_s)]
    pub mpc_period: f64,
}

impl MpcArgs {
    /// `Some(on)` when slip handling was asked for or against; `None`: the gait's default.
    pub fn adapt_friction(&self) -> Option<bool> {
        (self.adapt_friction || self.no_adapt_friction).then_some(self.adapt_friction)
    }
}
