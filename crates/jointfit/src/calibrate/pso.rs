//! Particle swarm optimisation of `e_inner(s)` (Kennedy & Eberhart 1995), followed in the
//! workflow by a joint Levenberg–Marquardt polish.
//!
//! Velocity update `v ← w v + c1 r1 (pbest − x) + c2 r2 (gbest − x)` with the constriction
//! coefficients of Clerc & Kennedy 2002 (IEEE Trans Evol Comput 6:58–73): `w = 0.7298`,
//! `c1 = c2 = 1.49618`, for which the swarm provably contracts; optionally `w` is multiplied
//! by `inertia_decay` whenever the swarm's best value has not improved for
//! `stall_to_shrink` iterations (Schutte et al. 2004's dynamic inertia; off by default).
//! Velocities are clamped to `v_max` (scaled units); positions stay inside `[−1, 1]` by
//! reflection at a bound with the velocity reversed.
//!
//! The paper's settings (`w = 1`, `c1 = c2 = 2`, a particle stopped dead at the bound it
//! crossed) are on the edge of divergence: velocities saturate at `v_max`, particles pile up
//! on the bounds with zero speed, and a best found there drags the swarm to it — the swarm
//! then ran to its iteration limit (300) on every case tried. The swarm only has to find
//! the basin (the polish converges within it), so it stops when its best improved by less
//! than `stall_tolerance` = 1e-4 (relative, and at least that fraction of 1 % of the first
//! best) over `stall_iterations` = 20 iterations.
//!
//! **Basin test.** On real or noisy trials the swarm's best keeps creeping down inside one
//! basin by more than the stall tolerance (opencap_expert1 walking1, hip, 50 frames: still
//! 7e-4 per 20 iterations at iteration 300), so the stall test alone let the swarm run to its
//! limit while the polish would have ended in the same minimum long before. Every
//! `basin_every` iterations the swarm's best is therefore polished by the joint
//! Levenberg–Marquardt solver (at most `basin_polish_iterations` iterations); when the
//! polished minimum has stayed the same (objective within `basin_tolerance`, relative, at
//! least 1e-12 of the first best; every scaled parameter within `basin_tolerance`^½) over
//! `stall_iterations` iterations, the
//! swarm has found no better basin in that time and stops, returning the polished minimum —
//! a memetic swarm's local search (Petalas, Parsopoulos & Vrahatis 2007, Ann Oper Res
//! 156:99–127) used only as the stopping test, so the swarm's own exploration is unchanged.
//!
//! Particles start uniformly inside the bounds. All random numbers come from one seeded
//! generator, drawn in a fixed order on one thread, so a seed gives the same result on any
//! number of threads. Particles are evaluated in parallel, each with its own inner-solver
//! workspace and its own warm-start coordinates.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::joint::{solve_joint, JointOptions};
use super::{Fit, Problem};
use crate::ik::lm::IkWorkspace;
use crate::solver::{Observer, Termination};

/// Settings of the particle swarm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PsoOptions {
    pub particles: usize,
    pub max_iterations: usize,
    /// Stop when the best value improved by less than `stall_tolerance` (relative) over this
    /// many iterations.
    pub stall_iterations: usize,
    pub stall_tolerance: f64,
    pub c1: f64,
    pub c2: f64,
    pub inertia: f64,
    pub inertia_decay: f64,
    pub stall_to_shrink: usize,
    pub v_max: f64,
    pub seed: u64,
    /// Polish the swarm's best every this many iterations for the basin test (0: off).
    pub basin_every: usize,
    /// Joint Levenberg–Marquardt iterations of one basin-test polish.
    pub basin_polish_iterations: usize,
    /// Two polished minima are the same basin when their objectives agree to this
    /// (relative) and their scaled parameters to its square root.
    pub basin_tolerance: f64,
}

impl Default for PsoOptions {
    fn default() -> Self {
        PsoOptions {
            particles: 20,
            max_iterations: 300,
            stall_iterations: 20,
            stall_tolerance: 1e-4,
            c1: 1.49618,
            c2: 1.49618,
            inertia: 0.7298,
            inertia_decay: 1.0,
            stall_to_shrink: 3,
            v_max: 0.5,
            seed: 1,
            basin_every: 10,
            basin_polish_iterations: 30,
            basin_tolerance: 1e-8,
        }
    }
}

struct Particle {
    x: Vec<f64>,
    v: Vec<f64>,
    best_x: Vec<f64>,
    best_cost: f64,
    best_q: Vec<Vec<f64>>,
    qs: Vec<Vec<f64>>,
    ws: IkWorkspace,
    cost: f64,
}

/// Runs the swarm; `q0` are starting coordinates for every particle's first evaluation.
/// `observer.iteration(iteration, best_cost)` is called after every iteration (progress
/// reporting; it cannot change the result). Ends [`Termination::Converged`] when the best
/// value improved by less than `stall_tolerance` (relative) over `stall_iterations`
/// iterations (the swarm's convergence test), else [`Termination::IterationLimit`].
pub(crate) fn solve_pso(
    prob: &Problem,
    q0: &[Vec<f64>],
    opts: &PsoOptions,
    observer: &mut dyn Observer,
) -> Fit {
    let fast = ranking_problem(prob);
    let prob = &fast;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut swarm = initial_swarm(prob, q0, opts, &mut rng);
    evaluate(prob, &mut swarm);
    let mut evaluations = swarm.len();
    let mut g = best_of(&swarm);
    let mut g_x = swarm[g].best_x.clone();
    let mut g_cost = swarm[g].best_cost;
    let mut inertia = opts.inertia;
    let mut since_improved = 0;
    let mut history = vec![g_cost];
    let mut window_start = g_cost;
    let mut window_len = 0;
    let mut iterations = 0;
    let mut termination = Termination::IterationLimit;
    // The basin test: the last polished minimum and the iteration since which it held.
    let mut basin: Option<(Fit, usize)> = None;
    while iterations < opts.max_iterations {
        iterations += 1;
        fly(&mut swarm, &mut rng, inertia, &g_x, opts);
        evaluate(prob, &mut swarm);
        evaluations += swarm.len();
        g = best_of(&swarm);
        if swarm[g].best_cost < g_cost {
            g_cost = swarm[g].best_cost;
            g_x.clone_from(&swarm[g].best_x);
            since_improved = 0;
        } else {
            since_improved += 1;
            if since_improved >= opts.stall_to_shrink {
                inertia *= opts.inertia_decay;
                since_improved = 0;
            }
        }
        history.push(g_cost);
        observer.iteration(iterations, g_cost);
        if opts.basin_every > 0 && iterations % opts.basin_every == 0 {
            let q = swarm[g].best_q.clone();
            let since = polish(prob, &g_x, q, opts, history[0], iterations, &mut basin);
            if iterations - since >= opts.stall_iterations {
                termination = Termination::Converged;
                break;
            }
        }
        window_len += 1;
        if window_len >= opts.stall_iterations {
            // Relative to the window's start, but not below 1 % of the first best: on a
            // noiseless trial the objective heads to 0 and a relative test alone never ends.
            let scale = window_start.abs().max(1e-2 * history[0].abs());
            if window_start - g_cost <= opts.stall_tolerance * scale {
                termination = Termination::Converged;
                break;
            }
            window_start = g_cost;
            window_len = 0;
        }
    }
    let best = &swarm[best_of(&swarm)];
    if let Some((local, _)) = basin.filter(|(l, _)| l.cost < best.best_cost) {
        return Fit {
            iterations,
            evaluations,
            history,
            termination,
            ..local
        };
    }
    Fit {
        p: prob.to_params(&best.best_x),
        s: best.best_x.clone(),
        coords: best.best_q.clone(),
        cost: best.best_cost,
        iterations,
        evaluations,
        history,
        termination,
    }
}

/// `prob` with the inner tolerance a particle's cost needs. A particle's cost only has to
/// rank it against the others: coordinates to 1e-8 rad/m leave the objective exact to
/// ~1e-16 relative (the error in e_inner is quadratic in the coordinate error at the inner
/// minimum), at about half the inner iterations of the tight tolerance that gradient-based
/// outer levels need.
fn ranking_problem<'m>(prob: &Problem<'m>) -> Problem<'m> {
    Problem {
        ik: crate::ik::IkOptions {
            step_tolerance: prob.ik.step_tolerance.max(1e-8),
            ..prob.ik
        },
        ..prob.clone()
    }
}

/// The particles at uniform random positions in the scaled box with uniform random
/// velocities up to `v_max`, each starting its inner solves from `q0`.
fn initial_swarm(
    prob: &Problem,
    q0: &[Vec<f64>],
    opts: &PsoOptions,
    rng: &mut ChaCha8Rng,
) -> Vec<Particle> {
    let nf = prob.n_free();
    (0..opts.particles.max(2))
        .map(|_| {
            let x: Vec<f64> = (0..nf).map(|_| rng.gen_range(-1.0..=1.0)).collect();
            let v: Vec<f64> = (0..nf)
                .map(|_| rng.gen_range(-opts.v_max..=opts.v_max))
                .collect();
            Particle {
                best_x: x.clone(),
                x,
                v,
                best_cost: f64::INFINITY,
                best_q: q0.to_vec(),
                qs: q0.to_vec(),
                ws: IkWorkspace::new(prob.model),
                cost: f64::INFINITY,
            }
        })
        .collect()
}

/// Every particle's cost at its position (in parallel), its own best updated.
fn evaluate(prob: &Problem, swarm: &mut [Particle]) {
    swarm.par_iter_mut().for_each(|pt| {
        let p = prob.to_params(&pt.x);
        pt.cost = prob.inner(&p, &mut pt.qs, &mut pt.ws);
        if pt.cost < pt.best_cost {
            pt.best_cost = pt.cost;
            pt.best_x.clone_from(&pt.x);
            pt.best_q.clone_from(&pt.qs);
        }
    });
}

/// The particle with the lowest best cost (the first of equals).
fn best_of(swarm: &[Particle]) -> usize {
    (0..swarm.len())
        .min_by(|&a, &b| swarm[a].best_cost.total_cmp(&swarm[b].best_cost))
        .expect("non-empty swarm")
}

/// One move of every particle: its velocity pulled towards its own best and the swarm's
/// (`g_x`), limited to `v_max`, and its position moved by it, reflected at the bounds.
fn fly(swarm: &mut [Particle], rng: &mut ChaCha8Rng, inertia: f64, g_x: &[f64], opts: &PsoOptions) {
    for pt in swarm.iter_mut() {
        #[allow(clippy::needless_range_loop)] // k indexes five arrays in step
        for k in 0..pt.x.len() {
            let (r1, r2): (f64, f64) = (rng.gen(), rng.gen());
            let v = inertia * pt.v[k]
                + opts.c1 * r1 * (pt.best_x[k] - pt.x[k])
                + opts.c2 * r2 * (g_x[k] - pt.x[k]);
            pt.v[k] = v.clamp(-opts.v_max, opts.v_max);
            // Reflected at a bound, the velocity reversed: a particle that overshoots
            // keeps exploring inside instead of sticking to the bound with no speed.
            let mut x = pt.x[k] + pt.v[k];
            if x > 1.0 {
                x = 2.0 - x;
                pt.v[k] = -pt.v[k];
            } else if x < -1.0 {
                x = -2.0 - x;
                pt.v[k] = -pt.v[k];
            }
            pt.x[k] = x.clamp(-1.0, 1.0);
        }
    }
}

/// The basin test: the swarm's best (`g_x`, its coordinates `q`) polished by a few joint
/// iterations, compared with the last polished minimum `basin` (replaced by this one).
/// Returns the iteration since which the polished minimum stayed in one basin (`first`:
/// the first best cost, the floor of the comparison on a noiseless trial).
fn polish(
    prob: &Problem,
    g_x: &[f64],
    q: Vec<Vec<f64>>,
    opts: &PsoOptions,
    first: f64,
    iterations: usize,
    basin: &mut Option<(Fit, usize)>,
) -> usize {
    let polish_opts = JointOptions {
        max_iterations: opts.basin_polish_iterations,
        tolerance: 1e-8,
        ..JointOptions::default()
    };
    let local = solve_joint(prob, g_x, q, &polish_opts, &mut crate::solver::NoObserver);
    let same = basin.as_ref().is_some_and(|(b, _)| {
        // Relative, with a floor for noiseless trials whose minimum is 0.
        let scale = b.cost.abs().max(1e-12 * first.abs());
        (local.cost - b.cost).abs() <= opts.basin_tolerance * scale
            && local
                .s
                .iter()
                .zip(&b.s)
                .all(|(x, y)| (x - y).abs() <= opts.basin_tolerance.sqrt())
    });
    let since = match (&*basin, same) {
        (Some((_, since)), true) => *since,
        _ => iterations,
    };
    *basin = Some((local, since));
    since
}
