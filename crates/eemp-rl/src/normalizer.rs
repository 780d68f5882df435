//! Running observation normalisation: x ↦ clip((x − μ)/√(σ² + ε), ±clip), with μ, σ² the
//! running moments of every observation seen in rollouts (Chan et al.'s parallel update, in
//! f64). Updated once per iteration after the PPO update, so the statistics a batch was
//! collected with are the ones it is trained with; saved inside the policy file.

#[derive(Clone, Debug, PartialEq)]
pub struct ObsNormalizer {
    pub mean: Vec<f64>,
    pub var: Vec<f64>,
    pub count: f64,
    pub clip: f64,
}

const EPS: f64 = 1e-8;

impl ObsNormalizer {
    pub fn new(dim: usize) -> Self {
        ObsNormalizer {
            mean: vec![0.0; dim],
            var: vec![1.0; dim],
            count: 0.0,
            clip: 5.0,
        }
    }

    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Folds a batch of raw observations (row-major, rows × dim) into the statistics.
    pub fn update(&mut self, batch: &[f32]) {
        let d = self.dim();
        let n = (batch.len() / d) as f64;
        if n == 0.0 {
            return;
        }
        let mut bmean = vec![0.0; d];
        for row in batch.chunks(d) {
            for (m, &x) in bmean.iter_mut().zip(row) {
                *m += x as f64;
            }
        }
        bmean.iter_mut().for_each(|m| *m /= n);
        let mut bvar = vec![0.0; d];
        for row in batch.chunks(d) {
            for ((v, &x), m) in bvar.iter_mut().zip(row).zip(&bmean) {
                *v += (x as f64 - m).powi(2);
            }
        }
        bvar.iter_mut().for_each(|v| *v /= n);
        let total = self.count + n;
        for i in 0..d {
            let delta = bmean[i] - self.mean[i];
            let m2 =
                self.var[i] * self.count + bvar[i] * n + delta * delta * self.count * n / total;
            self.mean[i] += delta * n / total;
            self.var[i] = m2 / total;
        }
        self.count = total;
    }

    /// Normalises `raw` into `out` (same length).
    pub fn apply(&self, raw: &[f32], out: &mut [f32]) {
        let d = self.dim();
        for (row_in, row_out) in raw.chunks(d).zip(out.chunks_mut(d)) {
            for i in 0..d {
                let z = (row_in[i] as f64 - self.mean[i]) / (self.var[i] + EPS).sqrt();
                row_out[i] = z.clamp(-self.clip, self.clip) as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batched_updates_equal_the_moments_of_all_data() {
        let data: Vec<f32> = (0..300)
            .map(|i| ((i * 37) % 101) as f32 * 0.1 - 3.0)
            .collect();
        let mut n = ObsNormalizer::new(3);
        for chunk in data.chunks(3 * 17) {
            n.update(chunk);
        }
        for j in 0..3 {
            let col: Vec<f64> = data.iter().skip(j).step_by(3).map(|&x| x as f64).collect();
            let m = col.iter().sum::<f64>() / col.len() as f64;
            let v = col.iter().map(|x| (x - m).powi(2)).sum::<f64>() / col.len() as f64;
            assert!((n.mean[j] - m).abs() < 1e-9, "mean {j}");
            assert!((n.var[j] - v).abs() < 1e-9, "var {j}");
        }
        assert_eq!(n.count, 100.0);
    }
}
