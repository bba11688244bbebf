//! The scale fit: per-group scale factors, every free marker's offset from its scaled
//! generic placement, and each frame's pose, solved together by Levenberg–Marquardt.
//!
//! Unknowns `θ = (g, u, δ, q_1 … q_F)`: `g` one factor per group (or three, per axis), `u`
//! the log of the overall size (only with the anthropometric prior), `δ_j` the offset (m, in
//! its body) of each free marker `j` from `s_b ⊙ c_j` (`c_j` its generic position), `q_f` the
//! coordinates of frame `f`; frame 0 is normally the averaged static trial. The fit minimizes
//!
//! `F(θ) = Σ_f Σ_j w_fj |x_j(θ) − m_fj|²/σ_d² + Σ_j |δ_j|²/σ_j² + (anthropometric prior) +
//! (weak pose rows)`,
//!
//! `x_j(θ) = T_b(q_f; s) (s_b ⊙ c_j + δ_j)` the model marker on the scaled model
//! ([`crate::geometry`]). The stages, each a module:
//!
//! 1. `markers`: the markers' weights in the static frame;
//! 2. `problem`: the layout of `θ` and the starting point (factors 1 or the stature ratio,
//!    offsets 0, poses by inverse kinematics);
//! 3. `lm`: Levenberg–Marquardt with Nielsen's damping on the rows of `residuals`, each
//!    step eliminating the frames by the Schur complement (`crate::normal`), in up to four
//!    rounds that widen the offset prior of tracking markers (`markers`);
//! 4. `markers`: the registration of markers only the static frame holds;
//! 5. `results`: the factors with their SDs (Laplace approximation) and the markers'
//!    misfits.
//!
//! The maths and the priors are also in `docs/scaling.md`.

mod lm;
mod markers;
mod options;
mod problem;
mod residuals;
mod results;
#[cfg(test)]
mod test_leg;

use nalgebra::Vector3;

use crate::basis::BasisData;
use jointfit::model::spec::ModelSpec;
use lm::Solved;
use markers::ROBUST_ROUNDS;
pub use options::{ScaleError, ScaleGroup, ScaleOptions, SizePrior};
use problem::Problem;
pub use results::{GroupFit, MarkerFit, ScaleFit};

/// Solves in rounds, widening after each the offset prior of markers the data pull far
/// (`markers::widen_offset_priors`) and solving again from where it stopped; the last
/// round's solution with the iterations of all rounds.
fn solve_robust(pb: &mut Problem, mut th: Vec<f64>, ws: &mut BasisData) -> Solved {
    let mut iterations = 0;
    let mut round = 1;
    loop {
        let solved = lm::solve(pb, th, ws);
        iterations += solved.iterations;
        if !markers::widen_offset_priors(pb, &solved.th) || round == ROBUST_ROUNDS {
            return Solved {
                iterations,
                ..solved
            };
        }
        th = solved.th;
        round += 1;
    }
}

/// Fits the scale (module docs). `targets[f][j]`: the measured position (m, world) of model
/// marker `j` in frame `f` (NaN: absent); frame 0 is normally the averaged static trial.
pub fn fit_scale(
    spec: &ModelSpec,
    targets: &[Vec<Vector3<f64>>],
    opts: &ScaleOptions,
) -> Result<ScaleFit, ScaleError> {
    let weight = markers::static_weights(spec, targets, opts);
    let (mut pb, th) = problem::start(spec, targets, opts, weight)?;
    let mut ws = pb.basis.workspace();
    let solved = solve_robust(&mut pb, th, &mut ws);
    let fitted = solved.th;
    let groups = results::group_fits(&pb, &fitted, &mut ws)?;
    let mut placed = fitted.clone();
    markers::register_static_only(&pb, &mut placed)?;
    // The misfit is the fit's, before the static-only markers are placed onto the data.
    let (markers, rms) = results::marker_fits(&pb, &fitted, &placed, &mut ws)?;
    Ok(ScaleFit {
        factors: pb.factors(&placed),
        groups,
        markers,
        coords: (0..targets.len())
            .map(|f| pb.coords(&placed, f).to_vec())
            .collect(),
        rms,
        size: pb.lay.size.map(|u| placed[u].exp()),
        iterations: solved.iterations,
        converged: solved.converged,
    })
}

#[cfg(test)]
mod tests {
    use super::test_leg::{factor_error, scaled_leg, TRUTH};
    use super::*;

    /// The pure fit (no anthropometric prior) recovers the factors and the pose.
    #[test]
    fn recovers_known_factors_of_a_scaled_leg() {
        let (spec, groups, markers) = scaled_leg();
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        let fit = fit_scale(&spec, &[markers], &opts).unwrap();
        assert!(factor_error(&fit) < 1e-6, "{:?}", fit.groups);
        assert!(fit.rms < 1e-8, "rms {}", fit.rms);
        for m in &fit.markers {
            assert!(
                m.moved.iter().all(|d| d.abs() < 1e-6),
                "{}: {:?}",
                m.name,
                m.moved
            );
        }
    }

    /// A body held at its true factors while the others are fitted: they are recovered, and
    /// the held body is reported with SD 0.
    #[test]
    fn bodies_held_at_given_factors_stay_there() {
        let (spec, mut groups, markers) = scaled_leg();
        let k = groups.iter().position(|g| g.name == "shank").unwrap();
        let shank = groups.remove(k);
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        for b in &shank.bodies {
            opts.fixed_factors.insert(b.clone(), [0.92; 3]);
        }
        let fit = fit_scale(&spec, &[markers], &opts).unwrap();
        let held = fit.groups.iter().find(|g| g.bodies == shank.bodies[..1]);
        assert_eq!(held.map(|g| (g.factors, g.sd)), Some(([0.92; 3], [0.0; 3])));
        for b in &shank.bodies {
            assert_eq!(fit.factors[b], [0.92; 3]);
        }
        let others = fit.groups.iter().filter(|g| g.sd[0] > 0.0);
        for g in others {
            let (_, s) = TRUTH.iter().find(|(n, _)| *n == g.name).unwrap();
            assert!((g.factors[0] - s[0]).abs() < 1e-6, "{g:?}");
        }
    }
}
