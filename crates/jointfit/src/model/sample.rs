//! Parameter values drawn from the model's priors: synthetic truth for simulation studies.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::Model;

impl Model {
    /// Parameter values drawn from the priors: each parameter `N(prior mean, sd²)` (Box–Muller
    /// on a ChaCha8 stream seeded with `seed`), clipped to its bounds; a parameter without a
    /// prior keeps its nominal value (two draws are spent on it all the same, so the stream does
    /// not depend on which parameters have priors).
    pub fn sample_priors(&self, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        self.parameters()
            .iter()
            .map(|par| {
                let (u1, u2): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
                let g = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                match par.prior_sd {
                    Some(sd) => (par.prior_mean + sd * g).clamp(par.lower, par.upper),
                    None => par.nominal,
                }
            })
            .collect()
    }
}
