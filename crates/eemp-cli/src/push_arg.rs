//! `--push-at S --push-dv DV`, shared by `eemp walk` and `eemp stand`.

#[derive(clap::Args, Debug)]
pub struct PushArgs {
    /// Apply a push at this time (s): a sudden lateral (world y) change of the trunk velocity.
    #[arg(long)]
    pub push_at: Option<f64>,
    /// Lateral velocity change of the push, m/s.
    #[arg(long, default_value_t = 0.3)]
    pub push_dv: f64,
}
