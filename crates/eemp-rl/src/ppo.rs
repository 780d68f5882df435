//! Proximal Policy Optimisation (the clipped objective of the paper's Sec. II-C): rollout
//! storage, generalised advantage estimation, and the minibatch update (clipped surrogate,
//! clipped value loss, entropy bonus, gradient-norm clipping, KL-adaptive learning rate).

use crate::adam::Adam;
use crate::config::{LrSchedule, PpoConfig};
use crate::mirror::MirrorMap;
use crate::nn::ActorCritic;
use candle_core::{Device, Result, Tensor, D};
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// One iteration's transitions, time-major: index `t * n_envs + env`.
#[derive(Clone, Debug, Default)]
pub struct Rollout {
    pub n_envs: usize,
    pub obs_dim: usize,
    pub act_dim: usize,
    /// Normalised observations the policy saw.
    pub obs: Vec<f32>,
    pub actions: Vec<f32>,
    pub log_probs: Vec<f32>,
    pub means: Vec<f32>,
    pub values: Vec<f32>,
    /// Rewards, with γ·V(final state) already added at time-limit truncations.
    pub rewards: Vec<f32>,
    /// The episode ended after this step (termination or truncation).
    pub dones: Vec<bool>,
    /// Semi-MDP: each step's length in nominal periods (γ^periods discounts the next value);
    /// empty: every step one period.
    pub periods: Vec<f32>,
    /// log σ of the policy that collected the batch.
    pub log_std: Vec<f32>,
    /// With the mirror loss: the mirrored observation of each step, normalised as the policy
    /// saw `obs` (empty: no mirror loss).
    pub obs_mirrored: Vec<f32>,
}

impl Rollout {
    pub fn new(n_envs: usize, obs_dim: usize, act_dim: usize) -> Self {
        Rollout {
            n_envs,
            obs_dim,
            act_dim,
            ..Default::default()
        }
    }
}

/// GAE(γ, λ): advantages and returns (advantage + value) for a time-major rollout, bootstrapped
/// from `last_values` (the value of each env's observation after the last step).
#[allow(clippy::too_many_arguments)]
pub fn gae(
    rewards: &[f32],
    values: &[f32],
    dones: &[bool],
    periods: &[f32],
    last_values: &[f32],
    n_envs: usize,
    gamma: f64,
    lambda: f64,
) -> (Vec<f32>, Vec<f32>) {
    let steps = rewards.len() / n_envs;
    let mut adv = vec![0f32; rewards.len()];
    for e in 0..n_envs {
        let mut running = 0f64;
        for t in (0..steps).rev() {
            let i = t * n_envs + e;
            let next_value = if t + 1 == steps {
                last_values[e]
            } else {
                values[i + n_envs]
            } as f64;
            let not_done = if dones[i] { 0.0 } else { 1.0 };
            // A step of k periods discounts the rest by γ^k (semi-MDP; Sutton, Precup & Singh
            // 1999); λ stays per decision.
            let gamma = match periods.get(i) {
                Some(&k) => gamma.powf(k as f64),
                None => gamma,
            };
            let delta = rewards[i] as f64 + gamma * next_value * not_done - values[i] as f64;
            running = delta + gamma * lambda * not_done * running;
            adv[i] = running as f32;
        }
    }
    let ret = adv.iter().zip(values).map(|(a, v)| a + v).collect();
    (adv, ret)
}

/// Means of one update, for the log.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UpdateStats {
    pub policy_loss: f64,
    pub value_loss: f64,
    pub entropy: f64,
    pub kl: f64,
    pub clip_fraction: f64,
    pub grad_norm: f64,
    pub learning_rate: f64,
    /// Mean mirror loss ‖π(M_o o) − M_a π(o)‖² per action value (0 without it).
    pub symmetry_loss: f64,
}

fn gather(src: &[f32], width: usize, idx: &[usize]) -> Vec<f32> {
    let mut out = Vec::with_capacity(idx.len() * width);
    for &i in idx {
        out.extend_from_slice(&src[i * width..(i + 1) * width]);
    }
    out
}

/// The PPO loss of one minibatch and its parts.
pub struct Loss {
    pub total: Tensor,
    pub policy: Tensor,
    pub value: Tensor,
    pub entropy: Tensor,
    /// The mirror loss (0 without it).
    pub symmetry: Tensor,
    pub mean: Tensor,
    pub ratio: Tensor,
}

/// The action mirror as tensors: `mirror(x)[:, i] = sign[i] · x[:, source[i]]`.
pub struct ActionMirror {
    source: Tensor,
    sign: Tensor,
}

impl ActionMirror {
    pub fn new(map: &MirrorMap) -> Result<Self> {
        let n = map.len();
        let source: Vec<u32> = map.source().iter().map(|&j| j as u32).collect();
        Ok(ActionMirror {
            source: Tensor::from_vec(source, n, &Device::Cpu)?,
            sign: Tensor::from_vec(map.sign().to_vec(), n, &Device::Cpu)?,
        })
    }

    pub fn apply(&self, x: &Tensor) -> Result<Tensor> {
        x.index_select(&self.source, 1)?.broadcast_mul(&self.sign)
    }
}

/// Minibatch tensors.
pub struct Minibatch<'a> {
    pub obs: Tensor,
    pub actions: Tensor,
    pub old_log_probs: Tensor,
    pub old_values: Tensor,
    pub returns: Tensor,
    pub advantages: Tensor,
    /// The mirrored observations and the action mirror (the mirror loss), or none.
    pub mirrored: Option<(Tensor, &'a ActionMirror)>,
}

/// L = −E[min(r A, clip(r, 1±ε) A)] + c_v E[max((V−R)², (V_old + clip(V−V_old, ±ε) − R)²)] − c_e H
/// (+ c_s E‖π(M_o o) − M_a π(o)‖² with the mirror loss, the target side held fixed as rsl_rl's
/// mirror loss does).
pub fn ppo_loss(ac: &ActorCritic, mb: &Minibatch, cfg: &PpoConfig) -> Result<Loss> {
    let eps = cfg.clip;
    let mean = ac.mean(&mb.obs)?;
    let log_prob = ac.log_prob(&mean, &mb.actions)?;
    let ratio = (log_prob - &mb.old_log_probs)?.exp()?;
    let surr1 = (&ratio * &mb.advantages)?;
    let surr2 = (ratio.clamp(1.0 - eps, 1.0 + eps)? * &mb.advantages)?;
    let policy = surr1.minimum(&surr2)?.mean_all()?.neg()?;
    let v = ac.value(&mb.obs)?;
    let value = if cfg.clip_value_loss {
        let v_clipped = (&mb.old_values + (&v - &mb.old_values)?.clamp(-eps, eps)?)?;
        let l1 = (&v - &mb.returns)?.sqr()?;
        let l2 = (v_clipped - &mb.returns)?.sqr()?;
        l1.maximum(&l2)?.mean_all()?
    } else {
        (&v - &mb.returns)?.sqr()?.mean_all()?
    };
    let entropy = ac.entropy()?;
    let symmetry = match &mb.mirrored {
        Some((obs_m, am)) => {
            let target = am.apply(&mean.detach())?;
            (ac.mean(obs_m)? - target)?.sqr()?.mean_all()?
        }
        None => Tensor::new(0f32, &Device::Cpu)?,
    };
    let total = ((&policy + (&value * cfg.value_coef)?)? - (&entropy * cfg.entropy_coef)?)?;
    let total = (total + (&symmetry * cfg.symmetry_coef)?)?;
    Ok(Loss {
        total,
        policy,
        value,
        entropy,
        symmetry,
        mean,
        ratio,
    })
}

/// Mean analytical KL(π_old ‖ π_new) of diagonal Gaussians over a minibatch.
fn gaussian_kl(
    old_mean: &Tensor,
    old_log_std: &Tensor,
    new_mean: &Tensor,
    new_log_std: &Tensor,
) -> Result<f64> {
    let var_old = (old_log_std * 2.0)?.exp()?;
    let var_new = (new_log_std * 2.0)?.exp()?;
    let dm2 = (old_mean - new_mean)?.sqr()?;
    let num = dm2.broadcast_add(&var_old)?;
    let term = num.broadcast_div(&(var_new * 2.0)?)?;
    let kl = term
        .broadcast_add(&(new_log_std - old_log_std)?)?
        .affine(1.0, -0.5)?
        .sum(D::Minus1)?
        .mean_all()?;
    kl.to_scalar::<f32>().map(|v| v as f64)
}

/// Global L2 norm of the gradients.
fn grad_norm(grads: &[Option<Tensor>]) -> Result<f64> {
    let mut s = 0f64;
    for g in grads.iter().flatten() {
        s += g.sqr()?.sum_all()?.to_scalar::<f32>()? as f64;
    }
    Ok(s.sqrt())
}

/// Runs `cfg.epochs` passes of `cfg.minibatches` minibatches over the rollout.
/// `progress` (0..1 of the run) drives the linear schedule.
#[allow(clippy::too_many_arguments)]
pub fn update(
    ac: &ActorCritic,
    opt: &mut Adam,
    cfg: &PpoConfig,
    rollout: &Rollout,
    last_values: &[f32],
    progress: f64,
    action_mirror: Option<&ActionMirror>,
    rng: &mut ChaCha8Rng,
) -> Result<UpdateStats> {
    let dev = Device::Cpu;
    let (d, a) = (rollout.obs_dim, rollout.act_dim);
    let (mut adv, ret) = gae(
        &rollout.rewards,
        &rollout.values,
        &rollout.dones,
        &rollout.periods,
        last_values,
        rollout.n_envs,
        cfg.gamma,
        cfg.lambda,
    );
    // Advantages normalised over the whole rollout (rsl_rl, brax).
    let n = adv.len();
    let mean = adv.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
    let var = adv.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n as f64;
    let sd = var.sqrt() + 1e-8;
    adv.iter_mut()
        .for_each(|x| *x = ((*x as f64 - mean) / sd) as f32);
    if cfg.lr_schedule == LrSchedule::Linear {
        opt.lr = cfg.lr_min + (cfg.learning_rate - cfg.lr_min) * (1.0 - progress).max(0.0);
    }
    let old_log_std = Tensor::from_vec(rollout.log_std.clone(), a, &dev)?;
    let vars = ac.vars();
    let mb_size = n / cfg.minibatches;
    let mut stats = UpdateStats::default();
    let mut count = 0usize;
    let mut order: Vec<usize> = (0..n).collect();
    for _ in 0..cfg.epochs {
        order.shuffle(rng);
        for k in 0..cfg.minibatches {
            let idx = &order[k * mb_size..(k + 1) * mb_size];
            let m = idx.len();
            let mb = Minibatch {
                obs: Tensor::from_vec(gather(&rollout.obs, d, idx), (m, d), &dev)?,
                actions: Tensor::from_vec(gather(&rollout.actions, a, idx), (m, a), &dev)?,
                old_log_probs: Tensor::from_vec(gather(&rollout.log_probs, 1, idx), m, &dev)?,
                old_values: Tensor::from_vec(gather(&rollout.values, 1, idx), m, &dev)?,
                returns: Tensor::from_vec(gather(&ret, 1, idx), m, &dev)?,
                advantages: Tensor::from_vec(gather(&adv, 1, idx), m, &dev)?,
                mirrored: match action_mirror {
                    Some(am) if !rollout.obs_mirrored.is_empty() => Some((
                        Tensor::from_vec(gather(&rollout.obs_mirrored, d, idx), (m, d), &dev)?,
                        am,
                    )),
                    _ => None,
                },
            };
            let old_mean = Tensor::from_vec(gather(&rollout.means, a, idx), (m, a), &dev)?;
            let loss = ppo_loss(ac, &mb, cfg)?;
            let kl = gaussian_kl(
                &old_mean,
                &old_log_std,
                &loss.mean.detach(),
                &ac.log_std.as_tensor().detach(),
            )?;
            if cfg.lr_schedule == LrSchedule::Adaptive {
                if kl > 2.0 * cfg.desired_kl {
                    opt.lr = (opt.lr / 1.5).max(cfg.lr_min);
                } else if kl < 0.5 * cfg.desired_kl && kl > 0.0 {
                    opt.lr = (opt.lr * 1.5).min(cfg.lr_max);
                }
            }
            let grads = loss.total.backward()?;
            let mut g: Vec<Option<Tensor>> = vars
                .iter()
                .map(|v| grads.get(v.as_tensor()).cloned())
                .collect();
            let norm = grad_norm(&g)?;
            if !norm.is_finite() {
                // A non-finite gradient would write NaN into every weight and moment.
                return Err(candle_core::Error::Msg(format!(
                    "non-finite gradient (loss {:?}); the update is refused and nothing is saved",
                    loss.total.to_scalar::<f32>().ok()
                )));
            }
            if norm > cfg.max_grad_norm {
                let s = cfg.max_grad_norm / (norm + 1e-6);
                for t in g.iter_mut().flatten() {
                    *t = (&*t * s)?;
                }
            }
            opt.step(&g)?;
            ac.bound_std(cfg.min_std)?;
            let clipped = loss
                .ratio
                .affine(1.0, -1.0)?
                .abs()?
                .gt(cfg.clip)?
                .to_dtype(candle_core::DType::F32)?
                .mean_all()?
                .to_scalar::<f32>()? as f64;
            stats.policy_loss += loss.policy.to_scalar::<f32>()? as f64;
            stats.value_loss += loss.value.to_scalar::<f32>()? as f64;
            stats.entropy += loss.entropy.to_scalar::<f32>()? as f64;
            stats.symmetry_loss += loss.symmetry.to_scalar::<f32>()? as f64;
            stats.kl += kl;
            stats.clip_fraction += clipped;
            stats.grad_norm += norm;
            count += 1;
        }
    }
    let c = count.max(1) as f64;
    stats.policy_loss /= c;
    stats.value_loss /= c;
    stats.entropy /= c;
    stats.symmetry_loss /= c;
    stats.kl /= c;
    stats.clip_fraction /= c;
    stats.grad_norm /= c;
    stats.learning_rate = opt.lr;
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gae_matches_a_hand_computed_two_step_case() {
        // One env, two steps, no done: δ1 = 1 + 0.9·3 − 2 = 1.7; δ0 = 0 + 0.9·2 − 1 = 0.8;
        // A1 = 1.7; A0 = 0.8 + 0.9·0.5·1.7 = 1.565.
        let (adv, ret) = gae(
            &[0.0, 1.0],
            &[1.0, 2.0],
            &[false, false],
            &[],
            &[3.0],
            1,
            0.9,
            0.5,
        );
        assert!((adv[1] - 1.7).abs() < 1e-6);
        assert!((adv[0] - 1.565).abs() < 1e-6);
        assert!((ret[0] - 2.565).abs() < 1e-6);
        // A done at step 0 cuts the bootstrap: A0 = 0 − 1.
        let (adv, _) = gae(
            &[0.0, 1.0],
            &[1.0, 2.0],
            &[true, false],
            &[],
            &[3.0],
            1,
            0.9,
            0.5,
        );
        assert!((adv[0] + 1.0).abs() < 1e-6);
        // Semi-MDP: step 0 lasted 2 periods, so its bootstrap is γ² = 0.81: δ0 = 0 + 0.81·2 − 1
        // = 0.62; A0 = 0.62 + 0.81·0.5·1.7 = 1.3085 (step 1, one period, as before).
        let (adv, _) = gae(
            &[0.0, 1.0],
            &[1.0, 2.0],
            &[false, false],
            &[2.0, 1.0],
            &[3.0],
            1,
            0.9,
            0.5,
        );
        assert!((adv[1] - 1.7).abs() < 1e-6);
        assert!((adv[0] - 1.3085).abs() < 1e-5, "{}", adv[0]);
    }
}
