//! Unit tests of `schur.rs`.

use super::step::{solve, solve_reduced};
use super::*;
use crate::calibrate::params_for_groups;
use crate::kinematics::KinData;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;
use crate::trial::Trial;
use nalgebra::{DMatrix, DVector, Vector3};

/// A moving leg's markers at parameters away from nominal, with a deterministic wobble.
fn problem_trial(model: &Model, frames: usize) -> Trial {
    let p: Vec<f64> = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(k, x)| x.nominal + 0.15 * (x.upper - x.lower) * (k as f64).sin())
        .collect();
    let mut kin = KinData::new(model);
    let mut positions = Vec::new();
    for f in 0..frames {
        let t = f as f64 / frames as f64;
        let mut q = model.default_coords();
        for (i, v) in q.iter_mut().enumerate() {
            *v += 0.3 * (6.0 * t + i as f64).sin();
        }
        forward_kinematics(model, &p, &q, Want::Positions, &mut kin);
        for (j, x) in kin.markers.iter().enumerate() {
            let e = |k: usize| 0.003 * ((f * 7 + j * 3 + k) as f64 * 1.3).sin();
            positions.push(x + Vector3::new(e(0), e(1), e(2)));
        }
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    Trial::new(labels, 100.0, 1, positions).unwrap()
}

/// One damped step with a given cache budget: `(δs, δq, predicted decrease)`.
fn step(prob: &Problem, budget: usize, lambda: f64) -> (Vec<f64>, Vec<Vec<f64>>, f64) {
    let p = prob.model.nominal_params();
    let qs = prob.initial_coords(&p);
    let mut b = Blocks::with_budget(prob, budget);
    assemble(prob, &p, &qs, &mut b);
    let mut ds = vec![0.0; b.nf];
    let fixed = vec![false; b.nf];
    assert!(solve(prob, &qs, &mut b, lambda, &fixed, &mut ds));
    let mut dq = vec![vec![0.0; b.nq]; qs.len()];
    let pred = back_substitute(prob, &qs, &b, &ds, &mut dq);
    (ds, dq, pred)
}

#[test]
fn recomputed_blocks_give_the_cached_step_bit_for_bit() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let trial = problem_trial(&model, 100);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, model.nominal_params(), &free, &[&trial]).unwrap();
    let (nq, nf) = (model.coordinates().len(), prob.n_free());
    let one_chunk = 8 * CHUNK * (nq * nq + nq * nf + nq);
    let full = step(&prob, usize::MAX, 1e-3);
    for budget in [0, one_chunk, 2 * one_chunk + 100] {
        let other = step(&prob, budget, 1e-3);
        assert_eq!(full, other, "budget {budget}");
    }
}

#[test]
fn schur_step_solves_the_dense_damped_system() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let trial = problem_trial(&model, 40);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, model.nominal_params(), &free, &[&trial]).unwrap();
    let lambda = 1e-2;
    let (ds, dq, pred) = step(&prob, usize::MAX, lambda);
    // The dense block-arrow system from the same blocks.
    let p = model.nominal_params();
    let qs = prob.initial_coords(&p);
    let mut b = Blocks::new(&prob);
    assemble(&prob, &p, &qs, &mut b);
    let (nq, nf, frames) = (b.nq, b.nf, qs.len());
    let dim = frames * nq + nf;
    let mut h = DMatrix::zeros(dim, dim);
    let mut rhs = DVector::zeros(dim);
    let per = b.per();
    for f in 0..frames {
        let blk = &b.store[f * per..(f + 1) * per];
        let (u, rest) = blk.split_at(nq * nq);
        let (w, g) = rest.split_at(nq * nf);
        let o = f * nq;
        for a in 0..nq {
            for c in 0..nq {
                h[(o + a, o + c)] = u[c * nq + a];
            }
            h[(o + a, o + a)] *= 1.0 + lambda;
            rhs[o + a] = g[a];
            for k in 0..nf {
                h[(o + a, frames * nq + k)] = w[k * nq + a];
                h[(frames * nq + k, o + a)] = w[k * nq + a];
            }
        }
    }
    for k in 0..nf {
        for c in 0..nf {
            h[(frames * nq + k, frames * nq + c)] = b.v[c * nf + k];
        }
        h[(frames * nq + k, frames * nq + k)] *= 1.0 + lambda;
        rhs[frames * nq + k] = b.gs[k];
    }
    let x = h.clone().cholesky().expect("positive definite").solve(&rhs);
    let scale = x.amax();
    for k in 0..nf {
        let e = (ds[k] - x[frames * nq + k]).abs();
        assert!(
            e <= 1e-7 * scale,
            "δs[{k}]: {} vs {}",
            ds[k],
            x[frames * nq + k]
        );
    }
    for f in 0..frames {
        for a in 0..nq {
            let e = (dq[f][a] - x[f * nq + a]).abs();
            assert!(e <= 1e-7 * scale, "δq[{f}][{a}]");
        }
    }
    // Predicted decrease 2 hᵀx − xᵀ H₀ x with the undamped H₀.
    let mut h0 = h.clone();
    for i in 0..dim {
        h0[(i, i)] /= 1.0 + lambda;
    }
    let expected = 2.0 * rhs.dot(&x) - x.dot(&(&h0 * &x));
    assert!(
        (pred - expected).abs() <= 1e-7 * expected.abs(),
        "{pred} vs {expected}"
    );
}

/// Short trials get an even number of chunks of nearly equal length; long ones keep
/// [`CHUNK`]; the chunks always cover the trial.
#[test]
fn short_trials_get_an_even_number_of_chunks() {
    for frames in 1..2000 {
        let len = super::chunk_len(frames);
        let chunks = frames.div_ceil(len);
        assert!((1..=CHUNK).contains(&len), "{frames}: {len}");
        if frames.div_ceil(CHUNK) < 16 {
            assert!(
                chunks % 2 == 0 || frames == 1,
                "{frames}: {chunks} chunks of {len}"
            );
        } else {
            assert_eq!(len, CHUNK, "{frames}");
        }
    }
    assert_eq!(super::chunk_len(143), 24);
    assert_eq!(super::chunk_len(25), 13);
    assert_eq!(super::chunk_len(10_000), CHUNK);
}

/// A parameter at a bound whose gradient points inside but whose coupled Gauss–Newton step
/// points out (found by trying pairs of parameters at their bounds): the step that holds it
/// (and solves again for the rest) leaves no parameter pushing out of its bound, the held
/// one does not move, and the step descends in the model.
#[test]
fn parameters_pushing_out_of_their_bounds_are_held_and_the_step_descends() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let trial = problem_trial(&model, 60);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, model.nominal_params(), &free, &[&trial]).unwrap();
    let nf = prob.n_free();
    let lambda = 1e-2;
    let mut b = Blocks::new(&prob);
    let mut ds = vec![0.0; nf];
    let s0 = prob.to_scaled(&model.nominal_params());
    let mut found = None;
    // Two coupled parameters at bounds (as the ankle axes of gait2392 subject01 walk1).
    'search: for k in 0..nf {
        for l in k + 1..nf {
            for (bk, bl) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
                let mut s = s0.clone();
                s[k] = bk;
                s[l] = bl;
                let p = prob.to_params(&s);
                let qs = prob.initial_coords(&p);
                assemble(&prob, &p, &qs, &mut b);
                assert!(reduce(&prob, &qs, &mut b, lambda));
                let fixed = active_bounds(&s, &b.gs);
                assert!(solve_reduced(&b, None, &fixed, &mut ds));
                for (j, bound) in [(k, bk), (l, bl)] {
                    if !fixed[j] && ds[j] * bound > 0.0 {
                        found = Some((j, s, qs, fixed));
                        break 'search;
                    }
                }
            }
        }
    }
    let (k, s, qs, mut fixed) = found.expect("a parameter whose step leaves its bound");
    assert!(solve_reduced_at_bounds(&b, None, &s, &mut fixed, &mut ds));
    assert!(fixed[k], "parameter {k} is held");
    for j in 0..nf {
        let outward = (s[j] >= 1.0 && ds[j] > 0.0) || (s[j] <= -1.0 && ds[j] < 0.0);
        assert!(!outward, "parameter {j} at {} steps {}", s[j], ds[j]);
        if fixed[j] {
            assert_eq!(ds[j], 0.0);
            assert_eq!(s[j].abs(), 1.0, "only parameters at a bound are held");
        }
    }
    let step: Vec<f64> = (0..nf)
        .map(|j| (s[j] + ds[j]).clamp(-1.0, 1.0) - s[j])
        .collect();
    let mut dq = vec![vec![0.0; b.nq]; qs.len()];
    let predicted = back_substitute(&prob, &qs, &b, &step, &mut dq);
    assert!(predicted > 0.0, "predicted decrease {predicted:e}");
}

/// The kept curvature's passes: the gradient and objective alone at a point are those of a
/// whole assembly there (bit for bit), and the reduced right-hand side from the kept factors
/// is the reduction's at the same point and damping (to round-off); at a second point the
/// gradient is that point's while `U_i`, `W_i`, `V`, `S` and the damping stay the first's.
#[test]
fn kept_curvature_takes_the_new_points_gradient() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let trial = problem_trial(&model, 60);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let mut prob = Problem::new(&model, model.nominal_params(), &free, &[&trial]).unwrap();
    let nf = prob.n_free();
    prob.prior = Some(crate::calibrate::prior::Prior {
        mean: (0..nf)
            .map(|k| model.parameters()[prob.free[k]].nominal + 0.2 * prob.half_range(k))
            .collect(),
        sd: (0..nf).map(|k| 0.5 * prob.half_range(k)).collect(),
        noise: 0.01,
        inflation: vec![1.0; nf],
        spread: vec![1.0; nf],
    });
    let p = model.nominal_params();
    let qs = prob.initial_coords(&p);
    let lambda = 1e-7;
    let mut fresh = Blocks::new(&prob);
    assemble(&prob, &p, &qs, &mut fresh);
    assert!(reduce(&prob, &qs, &mut fresh, lambda));
    let mut kept = Blocks::new(&prob);
    assemble(&prob, &p, &qs, &mut kept);
    assert!(reduce(&prob, &qs, &mut kept, lambda));
    assert!(kept.can_keep());
    assemble_gradient(&prob, &p, &qs, &mut kept);
    reduce_gradient(&mut kept);
    assert_eq!(kept.gs, fresh.gs);
    assert_eq!(kept.cost.to_bits(), fresh.cost.to_bits());
    assert_eq!(kept.store, fresh.store);
    let scale = fresh.rhs.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (a, b) in kept.rhs.iter().zip(&fresh.rhs) {
        assert!((a - b).abs() <= 1e-10 * scale, "{a} against {b}");
    }
    // A second point: its gradient, the first point's curvature.
    let mut p2 = p.clone();
    for (k, &i) in prob.free.iter().enumerate() {
        p2[i] += 1e-3 * prob.half_range(k) * (k as f64).cos();
    }
    let qs2: Vec<Vec<f64>> = qs
        .iter()
        .map(|q| q.iter().map(|x| x + 1e-3).collect())
        .collect();
    let mut there = Blocks::new(&prob);
    assemble(&prob, &p2, &qs2, &mut there);
    assemble_gradient(&prob, &p2, &qs2, &mut kept);
    assert_eq!(kept.gs, there.gs);
    assert_eq!(kept.cost.to_bits(), there.cost.to_bits());
    let per = kept.per();
    let nq = kept.nq;
    for f in 0..qs.len() {
        let (k, t, a) = (&kept.store, &there.store, &fresh.store);
        let r = f * per..(f + 1) * per;
        assert_eq!(k[r.end - nq..r.end], t[r.end - nq..r.end], "g of frame {f}");
        assert_eq!(
            k[r.start..r.end - nq],
            a[r.start..r.end - nq],
            "U, W of frame {f}"
        );
    }
    assert_eq!(kept.v, fresh.v);
    assert_eq!(kept.damping(), lambda);
    assert!(kept.can_keep());
}
