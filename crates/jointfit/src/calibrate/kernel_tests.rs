//! Tests of the per-frame kernel against dense products and the plain dot products.

use super::*;
use crate::calibrate::params_for_groups;
use crate::model::lower_limb::bilateral::bilateral;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;
use crate::trial::Trial;
use nalgebra::DMatrix;

/// One frame of `model` away from its default pose, its targets off the markers by up to
/// 2.7 cm with marker 3 missing: the parameters, coordinates, targets and a trial of it.
fn moved_frame(model: &Model) -> (Vec<f64>, Vec<f64>, Vec<Vector3<f64>>, Trial) {
    let p = model.nominal_params();
    let mut q = model.default_coords();
    for (i, v) in q.iter_mut().enumerate() {
        *v += 0.2 * (i as f64 + 1.0).sin();
    }
    let mut kin = KinData::new(model);
    forward_kinematics(model, &p, &q, Want::Positions, &mut kin);
    let mut targets: Vec<Vector3<f64>> = kin
        .markers
        .iter()
        .enumerate()
        .map(|(j, x)| x + Vector3::new(0.01, -0.02, 0.015) * ((j as f64) * 0.7).cos())
        .collect();
    targets[3] = Vector3::from_element(f64::NAN);
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let trial = Trial::new(labels, 100.0, 1, targets.clone()).unwrap();
    (p, q, targets, trial)
}

/// The kernel's `G` and `h` against the dense products `J̃ᵀJ̃`, `J̃ᵀr̃` formed with nalgebra
/// from the kinematics' Jacobians, with a missing marker and unequal weights.
#[test]
fn gram_matches_dense_products() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let (p, q, targets, trial) = moved_frame(&model);
    let mut kin = KinData::new(&model);
    let all = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, p.clone(), &all, &[&trial]).unwrap();
    let half: Vec<f64> = (0..prob.n_free()).map(|k| prob.half_range(k)).collect();
    let mut sc = FrameScratch::tiled(&prob);
    let cost = frame_gram(&prob, &p, &q, &targets, &half, &mut sc);

    forward_kinematics(&model, &p, &q, Want::DqDp, &mut kin);
    let (nq, nf) = (model.coordinates().len(), prob.n_free());
    let n = nq + nf;
    let rows = 3 * model.markers().len();
    let mut j = DMatrix::zeros(rows, n);
    let mut r = DMatrix::zeros(rows, 1);
    let mut expected_cost = 0.0;
    for (m, mk) in model.markers().iter().enumerate() {
        if targets[m].x.is_nan() {
            continue;
        }
        let sw = mk.weight.sqrt();
        let d = targets[m] - kin.markers[m];
        expected_cost += mk.weight * d.norm_squared();
        for axis in 0..3 {
            let row = 3 * m + axis;
            r[row] = sw * d[axis];
            for a in 0..nq {
                j[(row, a)] = sw * kin.jq[(row, a)];
            }
            for k in 0..nf {
                j[(row, nq + k)] = sw * half[k] * kin.jp[(row, prob.free[k])];
            }
        }
    }
    let g = j.transpose() * &j;
    let h = j.transpose() * &r;
    assert!((cost - expected_cost).abs() <= 1e-12 * expected_cost);
    let scale = g.amax();
    for a in 0..n {
        assert!((sc.grad[a] - h[a]).abs() <= 1e-12 * h.amax(), "h[{a}]");
        for b in 0..n {
            let got = sc.gram[b * n + a];
            assert!((got - g[(a, b)]).abs() <= 1e-12 * scale, "G[{a},{b}]");
            assert_eq!(got, sc.gram[a * n + b], "symmetric");
        }
    }
}

/// The old kernel's sums, one [`dot`] per entry over the rows where both columns can be
/// nonzero, from `J̃` column-major: the oracle of the tiled kernel, which must agree bit for
/// bit (its tiles only regroup the same sums).
fn plain_gram(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let model = prob.model;
    let (nq, n) = (
        model.coordinates().len(),
        model.coordinates().len() + prob.n_free(),
    );
    let nrows = 3 * model.markers().len();
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, q, Want::DqDp, &mut kin);
    let mut rows = Vec::new();
    let mut rw = Vec::new();
    for j in depth_first_markers(model) {
        let (t, w) = (targets[j], model.markers()[j].weight);
        if t.x.is_nan() || w <= 0.0 {
            continue;
        }
        let r = t - kin.markers[j];
        for axis in 0..3 {
            rw.push(w.sqrt() * r[axis]);
            rows.push((3 * j + axis, w.sqrt()));
        }
    }
    let nr = rows.len();
    let mut jw = vec![0.0; n * nr];
    let mut range = vec![(0, 0); n];
    for a in 0..n {
        let (src, scale) = if a < nq {
            (&kin.jq.as_slice()[a * nrows..(a + 1) * nrows], 1.0)
        } else {
            let pi = prob.free[a - nq];
            (
                &kin.jp.as_slice()[pi * nrows..(pi + 1) * nrows],
                half[a - nq],
            )
        };
        let col = &mut jw[a * nr..(a + 1) * nr];
        for (x, &(row, sw)) in col.iter_mut().zip(&rows) {
            *x = sw * scale * src[row];
        }
        let first = col.iter().position(|&x| x != 0.0).unwrap_or(nr);
        let end = col
            .iter()
            .rposition(|&x| x != 0.0)
            .map_or(0, |i| (i / 3 + 1) * 3);
        range[a] = if first < end { (first, end) } else { (0, 0) };
    }
    let mut gram = vec![0.0; n * n];
    let mut grad = vec![0.0; n];
    for b in 0..n {
        let (rb, eb) = range[b];
        let cb = &jw[b * nr..(b + 1) * nr];
        grad[b] = dot(&rw[rb..eb], &cb[rb..eb]);
        for a in b..n {
            let (lo, hi) = (rb.max(range[a].0), eb.min(range[a].1));
            let v = if lo < hi {
                dot(&cb[lo..hi], &jw[a * nr + lo..a * nr + hi])
            } else {
                0.0
            };
            gram[b * n + a] = v;
            gram[a * n + b] = v;
        }
    }
    (gram, grad)
}

/// The tiled kernel against [`plain_gram`], bit for bit, on a chain (one leg) and a tree
/// (both legs, where the columns of the two legs share no rows and fall back to single dot
/// products), over frames with markers missing in turn, all through one workspace (so the
/// column order of one frame serves the next, whose ranges differ).
#[test]
fn tiles_sum_exactly_as_plain_dot_products() {
    for spec in [lower_limb(Side::Right), bilateral()] {
        let model = Model::compile(&spec).unwrap();
        let p = model.nominal_params();
        let all = params_for_groups(&model, &["all"]).unwrap();
        let labels: Vec<String> = model.markers().iter().map(|m| m.name.clone()).collect();
        let nm = model.markers().len();
        let mut kin = KinData::new(&model);
        let mut frames = Vec::new();
        for f in 0..6 {
            let mut q = model.default_coords();
            for (i, v) in q.iter_mut().enumerate() {
                *v += 0.3 * ((i + 3 * f) as f64 * 0.9).sin();
            }
            forward_kinematics(&model, &p, &q, Want::Positions, &mut kin);
            let mut t: Vec<Vector3<f64>> = kin
                .markers
                .iter()
                .enumerate()
                .map(|(j, x)| x + Vector3::new(0.004, -0.003, 0.002) * ((j + f) as f64).cos())
                .collect();
            if f > 0 {
                // A different marker missing in each frame (the first frame has all).
                t[(5 * f) % nm] = Vector3::from_element(f64::NAN);
            }
            frames.push((q, t));
        }
        let flat: Vec<Vector3<f64>> = frames.iter().flat_map(|(_, t)| t.clone()).collect();
        let trial = Trial::new(labels, 100.0, 1, flat).unwrap();
        let prob = Problem::new(&model, p.clone(), &all, &[&trial]).unwrap();
        let half: Vec<f64> = (0..prob.n_free()).map(|k| prob.half_range(k)).collect();
        let mut sc = FrameScratch::tiled(&prob);
        for (q, t) in frames.iter().chain(frames.iter().rev()) {
            frame_gram(&prob, &p, q, t, &half, &mut sc);
            let (gram, grad) = plain_gram(&prob, &p, q, t, &half);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&sc.gram), bits(&gram), "{}: G", spec.name);
            assert_eq!(bits(&sc.grad), bits(&grad), "{}: h", spec.name);
        }
    }
}

/// The gradient alone is the gradient of the Gram kernel, bit for bit, and so is the
/// objective, with the twist kernel and the tiled one, for one leg and both.
#[test]
fn gradient_alone_is_the_grams_gradient() {
    for model in [
        Model::compile(&lower_limb(Side::Right)).unwrap(),
        Model::compile(&bilateral()).unwrap(),
    ] {
        let (p, q, targets, trial) = moved_frame(&model);
        let all = params_for_groups(&model, &["all"]).unwrap();
        let prob = Problem::new(&model, p.clone(), &all, &[&trial]).unwrap();
        let half: Vec<f64> = (0..prob.n_free()).map(|k| prob.half_range(k)).collect();
        let n = model.coordinates().len() + prob.n_free();
        let twist = FrameScratch::new(&prob);
        assert!(twist.is_twist(), "the twist kernel serves the leg");
        for mut sc in [twist, FrameScratch::tiled(&prob)] {
            let cost = frame_gram(&prob, &p, &q, &targets, &half, &mut sc);
            let grad = sc.grad[..n].to_vec();
            sc.grad.iter_mut().for_each(|g| *g = f64::NAN);
            let alone = frame_gradient(&prob, &p, &q, &targets, &half, &mut sc);
            assert_eq!(alone.to_bits(), cost.to_bits());
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&sc.grad[..n]), bits(&grad));
        }
    }
}
