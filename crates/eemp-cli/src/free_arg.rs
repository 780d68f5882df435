//! The free gait's pairing options (`eemp walk`), as the run description takes them.

#[derive(clap::Args, Debug, Default)]
pub struct FreePairingArgs {
    /// Free gait: take a leg's diagonal partner along when its eq. (5) value is above 1 − this
    /// (`FreePairing::pair_tolerance`, 0–1; default 0.5; 0: only when it is outside too).
    #[arg(long)]
    pub free_pair_tolerance: Option<f64>,
    /// Free gait: take the partner along when a lone swing would leave the trunk less than this
    /// inside the other feet's triangle, m (`FreePairing::support_margin_m`, −0.2–0.2; default 0).
    #[arg(long)]
    pub free_support_margin: Option<f64>,
    /// Free gait: the earlier rule, a partner only when it is outside its ellipse too
    /// (`FreePairing::UNPAIRED`; EEMP-RL's first policy was trained with it).
    #[arg(long, conflicts_with_all = ["free_pair_tolerance", "free_support_margin"])]
    pub free_unpaired: bool,
}
