//! The walk's support check (`eemp walk`), as the run description takes it.

#[derive(clap::Args, Debug, Default)]
pub struct WalkSupportArgs {
    /// Walk: the next leg of its order swings only while the capture point of the velocity
    /// error stays at least this inside the other feet's triangle, m, else the next leg that
    /// keeps it (`WalkSupport::margin_m`, −0.2–0; default −0.05: outside by up to 5 cm).
    #[arg(long, allow_negative_numbers = true)]
    pub walk_support_margin: Option<f64>,
    /// Walk: that check runs while the commanded speed is below this, m/s
    /// (`WalkSupport::max_speed_mps`, 0–10; default 0.6; 0: at every speed).
    #[arg(long)]
    pub walk_support_max_speed: Option<f64>,
    /// Walk: no support check, the paper's fixed order (`WalkSupport::OFF`).
    #[arg(long, conflicts_with_all = ["walk_support_margin", "walk_support_max_speed"])]
    pub no_walk_support: bool,
}

impl WalkSupportArgs {
    /// `Some(false)` with --no-walk-support; `None`: the default.
    pub fn check(&self) -> Option<bool> {
        self.no_walk_support.then_some(false)
    }
}
