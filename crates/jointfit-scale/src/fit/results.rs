//! The fit's answer: each group's factors with their standard deviations, and each marker's
//! place with its misfit.
//!
//! **Standard deviations** (Laplace approximation). The covariance of the factors is the
//! factor block of `C = (J_dᵀJ_d / c + J_pᵀJ_p)⁻¹` at the solution: data rows `d` weighted
//! down by the factor `c` by which their residuals show the marker spread to exceed the
//! assumed `σ_d`, prior rows `p` (placement, anthropometric, pose) as they are, since the
//! markers' misfit says nothing of the priors' spread:
//!
//! `c = max(1, χ²_d / (n_d − p))`, `p = tr(C₀ J_dᵀJ_d) = n − tr(C₀ J_pᵀJ_p)`,
//! `C₀ = (JᵀJ)⁻¹`,
//!
//! `χ²_d` the data rows' sum of squares, `n_d` their number, `p` the unknowns the data
//! determine (an unknown the priors alone fix uses up no data row). A body held at given
//! factors is reported with SD 0.
//!
//! **Markers.** Each marker's place is the registered one (`fit::markers`); its RMS distance
//! to the data over the frames it is present in, and the RMS over every present sample, are
//! the fit's, before registration.

use super::options::ScaleError;
use super::problem::Problem;
use crate::basis::BasisData;
use crate::geometry::ScaleFactors;

/// One group's fitted factors with their standard deviations.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GroupFit {
    pub name: String,
    pub bodies: Vec<String>,
    pub factors: [f64; 3],
    pub sd: [f64; 3],
}

/// One registered marker.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MarkerFit {
    pub name: String,
    pub body: String,
    /// Position in the scaled body (m).
    pub position: [f64; 3],
    /// Offset from the scaled generic position (m).
    pub moved: [f64; 3],
    /// RMS distance to the data over the frames it is present in, at the fit's solution
    /// before registration (m; NaN: never present).
    pub rms: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScaleFit {
    pub factors: ScaleFactors,
    pub groups: Vec<GroupFit>,
    pub markers: Vec<MarkerFit>,
    /// Coordinates of every frame at the solution.
    pub coords: Vec<Vec<f64>>,
    /// RMS marker distance over every present marker sample at the fit's solution, before the
    /// static-only markers are registered (m).
    pub rms: f64,
    /// `exp(u)`: the overall size (anthropometric prior only).
    pub size: Option<f64>,
    pub iterations: usize,
    /// Whether the last round stopped by its convergence test, not at
    /// [`ScaleOptions::max_iterations`](super::ScaleOptions::max_iterations).
    pub converged: bool,
}

/// The factor `c` of the data rows' variance over the assumed `σ_d²` that the residuals show
/// (module docs).
fn data_variance_factor(pb: &Problem, th: &[f64], ws: &mut BasisData) -> Result<f64, ScaleError> {
    let full = pb.evaluate(th, true, 1.0, ws);
    let prior = pb.evaluate(th, true, 0.0, ws);
    let (nm, pr) = (full.normal.expect("normal"), prior.normal.expect("normal"));
    let (sinv, diags) = nm.inverse_blocks().ok_or(ScaleError::Singular)?;
    let mut p = pb.lay.n as f64 - (sinv * &pr.a).trace();
    for (d, fr) in diags.iter().zip(&pr.frames) {
        p -= d
            .iter()
            .zip(fr.d.diagonal().iter())
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
    let dof = full.data_rows as f64 - p;
    Ok(if dof >= 1.0 {
        (full.data_cost / dof).max(1.0)
    } else {
        1.0
    })
}

/// Each group's factors with their SDs (module docs); then each body held at given factors
/// (SD 0).
pub(super) fn group_fits(
    pb: &Problem,
    th: &[f64],
    ws: &mut BasisData,
) -> Result<Vec<GroupFit>, ScaleError> {
    let c = data_variance_factor(pb, th, ws)?;
    let nm = pb.evaluate(th, true, 1.0 / c, ws).normal.expect("normal");
    let (cov, _) = nm.inverse_blocks().ok_or(ScaleError::Singular)?;
    let fitted = pb
        .opts
        .groups
        .iter()
        .zip(&pb.lay.groups)
        .map(|(g, &(at, n))| {
            let pick = |k: usize| if n == 3 { at + k } else { at };
            GroupFit {
                name: g.name.clone(),
                bodies: g.bodies.clone(),
                factors: std::array::from_fn(|k| th[pick(k)]),
                sd: std::array::from_fn(|k| cov[(pick(k), pick(k))].sqrt()),
            }
        });
    let held = pb.opts.fixed_factors.iter().map(|(b, f)| GroupFit {
        name: b.clone(),
        bodies: vec![b.clone()],
        factors: *f,
        sd: [0.0; 3],
    });
    Ok(fitted.chain(held).collect())
}

/// Per model marker: the sum of squared distances (m²) to its data at `th` over the frames
/// it is present in, and their number.
fn marker_misfits(pb: &Problem, th: &[f64], ws: &mut BasisData) -> Vec<(f64, usize)> {
    let mut sums = vec![(0.0, 0usize); pb.spec.markers.len()];
    for (f, t) in pb.targets.iter().enumerate() {
        let pts = pb.points(th, f, false, ws);
        for (mi, m) in t.iter().enumerate() {
            if m.x.is_finite() {
                sums[mi].0 += (pts.markers[mi] - m).norm_squared();
                sums[mi].1 += 1;
            }
        }
    }
    sums
}

/// The registered markers (their places from `placed`) with their errors at the fit's
/// solution `fitted`, and the RMS over every present sample (m).
pub(super) fn marker_fits(
    pb: &Problem,
    fitted: &[f64],
    placed: &[f64],
    ws: &mut BasisData,
) -> Result<(Vec<MarkerFit>, f64), ScaleError> {
    let model = pb.model(placed)?;
    let sums = marker_misfits(pb, fitted, ws);
    let (total, count) = sums.iter().fold((0.0, 0), |(a, n), (s, k)| (a + s, n + k));
    let markers = pb
        .spec
        .markers
        .iter()
        .zip(&pb.lay.delta)
        .zip(model.markers())
        .zip(&sums)
        .map(|(((m, d), cm), (s, n))| MarkerFit {
            name: m.name.clone(),
            body: m.segment.clone(),
            position: [cm.local.x, cm.local.y, cm.local.z],
            moved: d.map_or([0.0; 3], |at| [placed[at], placed[at + 1], placed[at + 2]]),
            rms: if *n > 0 {
                (s / *n as f64).sqrt()
            } else {
                f64::NAN
            },
        })
        .collect();
    Ok((markers, (total / count.max(1) as f64).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::super::test_leg::{leg_frames, with_noise, UNIFORM_TRUTH};
    use super::super::{fit_scale, ScaleOptions};

    /// Over seeded draws of marker noise, the spread of each fitted factor matches its
    /// reported SD: with noise of the assumed SD, and with twice that (the SD then grows
    /// with the spread the residuals show).
    #[test]
    fn reported_sds_match_the_spread_over_noise_draws() {
        use rand::{Rng, SeedableRng};
        let (spec, groups, clean) = leg_frames(4);
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        opts.fixed_markers = spec.markers.iter().map(|m| m.name.clone()).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(38);
        // A standard normal draw (Box–Muller).
        let mut normal = move || {
            let (u, v): (f64, f64) = (rng.gen_range(1e-300..1.0), rng.gen());
            (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
        };
        for noise in [opts.noise_sd, 2.0 * opts.noise_sd] {
            let draws = 200;
            let mut factors = vec![Vec::new(); UNIFORM_TRUTH.len()];
            let mut sds = vec![0.0; UNIFORM_TRUTH.len()];
            for _ in 0..draws {
                let noisy = with_noise(&clean, || noise * normal());
                let fit = fit_scale(&spec, &noisy, &opts).unwrap();
                for (k, g) in fit.groups.iter().enumerate() {
                    factors[k].push(g.factors[0]);
                    sds[k] += g.sd[0] / draws as f64;
                }
            }
            for (k, f) in factors.iter().enumerate() {
                let mean = f.iter().sum::<f64>() / draws as f64;
                let spread =
                    (f.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (draws - 1) as f64).sqrt();
                let ratio = sds[k] / spread;
                assert!(
                    (0.75..=1.3).contains(&ratio),
                    "noise {noise}: group {k} reports SD {} for a spread of {spread}",
                    sds[k]
                );
            }
        }
    }
}
