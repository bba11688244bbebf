//! The model a synthetic subject's personalization would give.
//!
//! A synthetic subject's joints sit where its true parameters put them. `jointfit personalize`
//! estimates them from anatomical landmarks (Bell et al. 1990 for the hip centre, the
//! epicondyles and malleoli for the axes) and writes each estimate as the parameter's prior
//! mean, with the method's published error as its SD (`jointfit::model::population`). For a
//! subject drawn far from the generic model (30 mm / 15°, the hard cases), the
//! landmark model is therefore the truth moved by the landmark method's error, not the generic
//! nominal model: [`landmark_model`] draws that error, `N(0, sd²)` per parameter, seeded.

use jointfit::model::spec::ModelSpec;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The landmark model of the subject whose true parameters are `truth`: `spec` with every
/// parameter that has a prior SD given the prior mean `truth + sd·g` (`g` standard normal,
/// seeded by `seed`, the mean clipped to the bounds). Returns the spec and the parameter
/// vector the fit starts from: the prior means, and the nominal value where a parameter has no
/// prior.
pub fn landmark_model(spec: &ModelSpec, truth: &[f64], seed: u64) -> (ModelSpec, Vec<f64>) {
    assert_eq!(
        spec.parameters.len(),
        truth.len(),
        "one truth per parameter"
    );
    let mut out = spec.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(60_000 + seed);
    let mut start = Vec::with_capacity(truth.len());
    for (p, &x) in out.parameters.iter_mut().zip(truth) {
        // Box–Muller; two draws per parameter whether or not it has a prior, so that one
        // parameter's prior does not change the others' errors.
        let (u1, u2): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
        let g = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        match p.prior_sd {
            Some(sd) => {
                let mean = (x + sd * g).clamp(p.lower, p.upper);
                p.prior_mean = Some(mean);
                start.push(mean);
            }
            None => start.push(p.nominal),
        }
    }
    (out, start)
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::lower_limb::{lower_limb, Side};
    use jointfit::model::population::{fill_landmark_priors, HipCentreMethod};

    #[test]
    fn prior_means_scatter_about_the_truth_by_the_prior_sd() {
        let mut spec = lower_limb(Side::Right);
        fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
        let truth: Vec<f64> = spec.parameters.iter().map(|p| p.nominal).collect();
        // z-scores of (mean − truth)/sd over many seeds: mean 0, variance 1 (clipping at the
        // bounds aside, which the landmark SDs are far from).
        let (mut s1, mut s2, mut n) = (0.0, 0.0, 0.0);
        for seed in 0..400 {
            let (out, start) = landmark_model(&spec, &truth, seed);
            for ((p, q), (&x, &m)) in spec
                .parameters
                .iter()
                .zip(&out.parameters)
                .zip(truth.iter().zip(&start))
            {
                let Some(sd) = p.prior_sd else {
                    assert_eq!(m, p.nominal);
                    continue;
                };
                assert_eq!(
                    q.prior_mean,
                    Some(m),
                    "{}: the start is the prior mean",
                    p.name
                );
                let z = (m - x) / sd;
                s1 += z;
                s2 += z * z;
                n += 1.0;
            }
        }
        assert!(n > 1000.0, "the leg's parameters carry priors");
        let (mean, var) = (s1 / n, s2 / n - (s1 / n).powi(2));
        // Standard errors: 1/√n ≈ 0.01 for the mean, √(2/n) ≈ 0.014 for the variance.
        assert!(mean.abs() < 0.05, "mean z {mean}");
        assert!((var - 1.0).abs() < 0.07, "variance of z {var}");
        assert_ne!(
            landmark_model(&spec, &truth, 1).1,
            landmark_model(&spec, &truth, 2).1
        );
        assert_eq!(
            landmark_model(&spec, &truth, 1).1,
            landmark_model(&spec, &truth, 1).1
        );
    }
}
