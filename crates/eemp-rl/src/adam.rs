//! Adam on candle tensors, with its moments in the open so checkpoints can hold them.
//!
//! Why not `candle_nn::AdamW`: its moments and step count are private, so a resumed run would
//! restart them from zero and diverge from an uninterrupted one. The update rule is the same
//! (with weight decay 0) and the test below checks it against candle's step for step.

use candle_core::{Result, Tensor, Var};

#[derive(Clone, Debug)]
pub struct Adam {
    pub vars: Vec<Var>,
    pub m: Vec<Tensor>,
    pub v: Vec<Tensor>,
    pub step: u64,
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
}

impl Adam {
    pub fn new(vars: Vec<Var>, lr: f64) -> Result<Self> {
        let m = vars
            .iter()
            .map(|v| v.as_tensor().zeros_like())
            .collect::<Result<Vec<_>>>()?;
        let v = m.clone();
        Ok(Adam {
            vars,
            m,
            v,
            step: 0,
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        })
    }

    /// One step with the gradients `grads[i]` of `vars[i]` (a missing gradient counts as zero).
    pub fn step(&mut self, grads: &[Option<Tensor>]) -> Result<()> {
        self.step += 1;
        let t = self.step as i32;
        let (b1, b2) = (self.beta1, self.beta2);
        let c1 = 1.0 - b1.powi(t);
        let c2 = 1.0 - b2.powi(t);
        for i in 0..self.vars.len() {
            let Some(g) = &grads[i] else { continue };
            let m = ((&self.m[i] * b1)? + (g * (1.0 - b1))?)?;
            let v = ((&self.v[i] * b2)? + (g.sqr()? * (1.0 - b2))?)?;
            let m_hat = (&m / c1)?;
            let v_hat = (&v / c2)?;
            let update = (m_hat / (v_hat.sqrt()? + self.eps)?)?;
            let theta = (self.vars[i].as_tensor() - (update * self.lr)?)?;
            self.vars[i].set(&theta)?;
            self.m[i] = m;
            self.v[i] = v;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;
    use candle_nn::Optimizer;

    #[test]
    fn matches_candle_adamw_without_weight_decay() {
        let dev = Device::Cpu;
        let init = Tensor::new(&[0.5f32, -1.0, 2.0], &dev).unwrap();
        let ours = Var::from_tensor(&init).unwrap();
        let theirs = Var::from_tensor(&init).unwrap();
        let mut a = Adam::new(vec![ours.clone()], 0.05).unwrap();
        let mut b = candle_nn::AdamW::new(
            vec![theirs.clone()],
            candle_nn::ParamsAdamW {
                lr: 0.05,
                weight_decay: 0.0,
                ..Default::default()
            },
        )
        .unwrap();
        for _ in 0..20 {
            // loss = Σ (x − 1)² x, a non-quadratic bowl
            let loss_a = (ours.as_tensor() - 1.0).unwrap().sqr().unwrap();
            let loss_a = (loss_a * ours.as_tensor()).unwrap().sum_all().unwrap();
            let g = loss_a.backward().unwrap();
            a.step(&[g.get(ours.as_tensor()).cloned()]).unwrap();
            let loss_b = (theirs.as_tensor() - 1.0).unwrap().sqr().unwrap();
            let loss_b = (loss_b * theirs.as_tensor()).unwrap().sum_all().unwrap();
            b.backward_step(&loss_b).unwrap();
        }
        let x: Vec<f32> = ours.as_tensor().to_vec1().unwrap();
        let y: Vec<f32> = theirs.as_tensor().to_vec1().unwrap();
        for (x, y) in x.iter().zip(&y) {
            assert!((x - y).abs() < 1e-5, "{x} vs {y}");
        }
        assert!(x != vec![0.5, -1.0, 2.0]);
    }
}
