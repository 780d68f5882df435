//! Networks on candle: multilayer perceptrons with seeded initialisation, and the actor-critic
//! (Gaussian policy with a state-independent, bounded-below standard deviation).
//!
//! Parameters are `candle_core::Var`s created from our own seeded RNG (candle's random init
//! draws from a thread RNG, which would break "same seed, same result").

use crate::config::{Activation, NetworkConfig};
use candle_core::{DType, Device, Result, Tensor, Var, D};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// One fully-connected layer: y = x Wᵀ + b.
#[derive(Clone, Debug)]
pub struct Dense {
    pub weight: Var,
    pub bias: Var,
}

impl Dense {
    /// Orthogonal-like init: Gaussian rows scaled by `gain/√fan_in` (He/LeCun-style), bias 0.
    pub fn new(inputs: usize, outputs: usize, gain: f64, rng: &mut ChaCha8Rng) -> Result<Self> {
        let scale = gain / (inputs as f64).sqrt();
        let w: Vec<f32> = (0..inputs * outputs)
            .map(|_| (rng.sample::<f64, _>(StandardNormal) * scale) as f32)
            .collect();
        Ok(Dense {
            weight: Var::from_tensor(&Tensor::from_vec(w, (outputs, inputs), &Device::Cpu)?)?,
            bias: Var::zeros(outputs, DType::F32, &Device::Cpu)?,
        })
    }

    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        x.matmul(&self.weight.as_tensor().t()?)?
            .broadcast_add(self.bias.as_tensor())
    }

    pub fn inputs(&self) -> usize {
        self.weight.dims()[1]
    }

    pub fn outputs(&self) -> usize {
        self.weight.dims()[0]
    }
}

#[derive(Clone, Debug)]
pub struct Mlp {
    pub layers: Vec<Dense>,
    pub activation: Activation,
}

impl Mlp {
    /// `inputs → hidden… → outputs`; the last layer's init gain is `out_gain`.
    pub fn new(
        inputs: usize,
        hidden: &[usize],
        outputs: usize,
        activation: Activation,
        out_gain: f64,
        rng: &mut ChaCha8Rng,
    ) -> Result<Self> {
        let mut sizes = vec![inputs];
        sizes.extend_from_slice(hidden);
        sizes.push(outputs);
        let n = sizes.len() - 1;
        let layers = (0..n)
            .map(|i| {
                let gain = if i + 1 == n { out_gain } else { 2f64.sqrt() };
                Dense::new(sizes[i], sizes[i + 1], gain, rng)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Mlp { layers, activation })
    }

    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut h = x.clone();
        for (i, l) in self.layers.iter().enumerate() {
            h = l.forward(&h)?;
            if i + 1 < self.layers.len() {
                h = match self.activation {
                    Activation::Elu => h.elu(1.0)?,
                    Activation::Tanh => h.tanh()?,
                };
            }
        }
        Ok(h)
    }

    pub fn vars(&self) -> Vec<Var> {
        self.layers
            .iter()
            .flat_map(|l| [l.weight.clone(), l.bias.clone()])
            .collect()
    }

    /// Layer widths, input first.
    pub fn sizes(&self) -> Vec<usize> {
        let mut s = vec![self.layers[0].inputs()];
        s.extend(self.layers.iter().map(|l| l.outputs()));
        s
    }
}

/// Gaussian policy π(a|o) = N(μ(o), diag σ²) and value function V(o), separate networks.
#[derive(Clone, Debug)]
pub struct ActorCritic {
    pub actor: Mlp,
    pub critic: Mlp,
    /// log σ per action dimension.
    pub log_std: Var,
}

const LN_2PI: f64 = 1.837_877_066_409_345_5;

impl ActorCritic {
    pub fn new(
        obs_dim: usize,
        act_dim: usize,
        net: &NetworkConfig,
        init_std: f64,
        rng: &mut ChaCha8Rng,
    ) -> Result<Self> {
        Ok(ActorCritic {
            // A small output layer starts the policy near its mean action (the default pose).
            actor: Mlp::new(
                obs_dim,
                &net.actor_hidden,
                act_dim,
                net.activation,
                net.actor_output_gain,
                rng,
            )?,
            critic: Mlp::new(obs_dim, &net.critic_hidden, 1, net.activation, 1.0, rng)?,
            log_std: Var::from_tensor(&Tensor::full(init_std.ln() as f32, act_dim, &Device::Cpu)?)?,
        })
    }

    pub fn obs_dim(&self) -> usize {
        self.actor.layers[0].inputs()
    }

    pub fn act_dim(&self) -> usize {
        self.log_std.dims()[0]
    }

    /// Every trained parameter, in a fixed order.
    pub fn vars(&self) -> Vec<Var> {
        let mut v = self.actor.vars();
        v.extend(self.critic.vars());
        v.push(self.log_std.clone());
        v
    }

    /// Named parameters (for files).
    pub fn named(&self) -> Vec<(String, Tensor)> {
        let mut out = Vec::new();
        for (net, name) in [(&self.actor, "actor"), (&self.critic, "critic")] {
            for (i, l) in net.layers.iter().enumerate() {
                out.push((format!("{name}.{i}.weight"), l.weight.as_tensor().clone()));
                out.push((format!("{name}.{i}.bias"), l.bias.as_tensor().clone()));
            }
        }
        out.push(("log_std".into(), self.log_std.as_tensor().clone()));
        out
    }

    /// Raises log σ to at least ln(min_std) (after an optimiser step).
    pub fn bound_std(&self, min_std: f64) -> Result<()> {
        let t = self.log_std.as_tensor().clamp(min_std.ln() as f32, 10f32)?;
        self.log_std.set(&t)
    }

    pub fn mean(&self, obs: &Tensor) -> Result<Tensor> {
        self.actor.forward(obs)
    }

    /// V(o) as a vector (batch).
    pub fn value(&self, obs: &Tensor) -> Result<Tensor> {
        self.critic.forward(obs)?.squeeze(D::Minus1)
    }

    /// Σ_i log N(a_i; μ_i, σ_i) per row.
    pub fn log_prob(&self, mean: &Tensor, actions: &Tensor) -> Result<Tensor> {
        let log_std = self.log_std.as_tensor();
        let z = actions.sub(mean)?.broadcast_div(&log_std.exp()?)?;
        let per_dim = (z.sqr()? * -0.5)?
            .broadcast_sub(log_std)?
            .affine(1.0, -0.5 * LN_2PI)?;
        per_dim.sum(D::Minus1)
    }

    /// Entropy of the Gaussian (the same for every state): Σ (log σ_i + ½ ln 2πe).
    pub fn entropy(&self) -> Result<Tensor> {
        self.log_std
            .as_tensor()
            .affine(1.0, 0.5 * (LN_2PI + 1.0))?
            .sum_all()
    }

    pub fn std(&self) -> Result<Vec<f32>> {
        self.log_std.as_tensor().exp()?.to_vec1()
    }
}

/// Log-density of a diagonal Gaussian in f64, for the rollout (matches [`ActorCritic::log_prob`]).
pub fn gaussian_log_prob(a: &[f32], mean: &[f32], std: &[f32]) -> f64 {
    a.iter()
        .zip(mean)
        .zip(std)
        .map(|((&a, &m), &s)| {
            let z = (a as f64 - m as f64) / s as f64;
            -0.5 * z * z - (s as f64).ln() - 0.5 * LN_2PI
        })
        .sum()
}
