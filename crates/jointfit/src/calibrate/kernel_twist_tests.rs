//! The twist kernel against the explicit products `J̃ᵀJ̃`, `J̃ᵀr̃` of the kinematics'
//! Jacobians (themselves proven against finite differences) and against the tiled kernel.

use nalgebra::{DMatrix, DVector, Vector3};

use crate::calibrate::kernel::{frame_gram, FrameScratch};
use crate::calibrate::{params_for_groups, Problem};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::functions::FunctionSpec;
use crate::model::lower_limb::bilateral::bilateral;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::refine::with_marker_parameters;
use crate::model::spec::{AxisMotion, CouplerSpec, JointKindSpec, ModelSpec, TransformAxisSpec};
use crate::model::Model;
use crate::trial::Trial;

/// `J̃ᵀJ̃` and `J̃ᵀr̃` formed densely from `Want::DqDp` Jacobians.
fn dense(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
) -> (DMatrix<f64>, DVector<f64>) {
    let model = prob.model;
    let (nq, nf) = (model.coordinates().len(), prob.n_free());
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, q, Want::DqDp, &mut kin);
    let rows = 3 * model.markers().len();
    let mut j = DMatrix::zeros(rows, nq + nf);
    let mut r = DVector::zeros(rows);
    for (m, mk) in model.markers().iter().enumerate() {
        if targets[m].x.is_nan() || mk.weight <= 0.0 {
            continue;
        }
        let sw = mk.weight.sqrt();
        let d = targets[m] - kin.markers[m];
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
    (j.transpose() * &j, j.transpose() * &r)
}

/// Frames of `model` at varied coordinates, targets off the model markers by a few mm, a
/// different marker missing in each frame but the first.
fn frames(model: &Model, p: &[f64], n: usize) -> Vec<(Vec<f64>, Vec<Vector3<f64>>)> {
    let nm = model.markers().len();
    let mut kin = KinData::new(model);
    (0..n)
        .map(|f| {
            let mut q = model.default_coords();
            for (i, v) in q.iter_mut().enumerate() {
                *v += 0.3 * ((i + 3 * f) as f64 * 0.9).sin();
            }
            forward_kinematics(model, p, &q, Want::Positions, &mut kin);
            let mut t: Vec<Vector3<f64>> = kin
                .markers
                .iter()
                .enumerate()
                .map(|(j, x)| x + Vector3::new(0.004, -0.003, 0.002) * ((j + f) as f64).cos())
                .collect();
            if f > 0 {
                t[(5 * f) % nm] = Vector3::from_element(f64::NAN);
                t[(5 * f + 7) % nm] = Vector3::from_element(f64::NAN);
            }
            (q, t)
        })
        .collect()
}

/// The kernel of `spec` (free `groups`) against [`dense`] to 1e-12 of each entry's
/// Cauchy–Schwarz scale, `√(G_aa G_bb)` and `√(G_aa · 2·cost)`, and against the tiled kernel;
/// `twist`: whether the problem must take the twist kernel (or fall back).
fn check(spec: &ModelSpec, groups: &[&str], twist: bool) {
    let model = Model::compile(spec).unwrap();
    let p = model.nominal_params();
    let free = params_for_groups(&model, groups).unwrap();
    let frames = frames(&model, &p, 6);
    let labels: Vec<String> = model.markers().iter().map(|m| m.name.clone()).collect();
    let flat: Vec<Vector3<f64>> = frames.iter().flat_map(|(_, t)| t.clone()).collect();
    let trial = Trial::new(labels, 100.0, 1, flat).unwrap();
    let prob = Problem::new(&model, p.clone(), &free, &[&trial]).unwrap();
    let half: Vec<f64> = (0..prob.n_free()).map(|k| prob.half_range(k)).collect();
    let n = model.coordinates().len() + prob.n_free();
    let mut sc = FrameScratch::new(&prob);
    assert_eq!(sc.is_twist(), twist, "{}: kernel choice", spec.name);
    let mut tiled = FrameScratch::tiled(&prob);
    for (f, (q, t)) in frames.iter().enumerate() {
        let cost = frame_gram(&prob, &p, q, t, &half, &mut sc);
        let cost_tiled = frame_gram(&prob, &p, q, t, &half, &mut tiled);
        assert_eq!(cost.to_bits(), cost_tiled.to_bits(), "cost, frame {f}");
        let (g, h) = dense(&prob, &p, q, t, &half);
        for a in 0..n {
            let ha = (g[(a, a)] * 2.0 * cost).sqrt();
            for (got, what) in [(sc.grad[a], "twist"), (tiled.grad[a], "tiled")] {
                assert!(
                    (got - h[a]).abs() <= 1e-12 * ha,
                    "{} frame {f}: h[{a}] {what} {got} vs {}",
                    spec.name,
                    h[a]
                );
            }
            for b in 0..n {
                let s = (g[(a, a)] * g[(b, b)]).sqrt();
                let got = sc.gram[b * n + a];
                assert_eq!(got.to_bits(), sc.gram[a * n + b].to_bits(), "symmetric");
                for (got, what) in [(got, "twist"), (tiled.gram[b * n + a], "tiled")] {
                    assert!(
                        (got - g[(a, b)]).abs() <= 1e-12 * s,
                        "{} frame {f}: G[{a},{b}] {what} {got} vs {}",
                        spec.name,
                        g[(a, b)]
                    );
                }
            }
        }
    }
}

/// One leg (a chain), every parameter free, with unequal weights and markers missing.
#[test]
fn twist_kernel_matches_dense_on_the_leg() {
    let mut spec = lower_limb(Side::Right);
    for (k, m) in spec.markers.iter_mut().enumerate() {
        m.weight = 0.5 + (k % 3) as f64;
    }
    check(&spec, &["all"], true);
    check(&spec, &["knee"], true);
}

/// Both legs on one pelvis (a tree: the two legs' columns share no markers).
#[test]
fn twist_kernel_matches_dense_on_two_legs() {
    check(&bilateral(), &["all"], true);
}

/// Refined markers: each one's position three parameters of its own weld frame.
#[test]
fn twist_kernel_matches_dense_with_refined_markers() {
    let leg = lower_limb(Side::Right);
    let names: Vec<&str> = leg
        .markers
        .iter()
        .step_by(3)
        .map(|m| m.name.as_str())
        .collect();
    let spec = with_marker_parameters(&leg, &names, 0.01);
    check(&spec, &["all"], true);
    check(&spec, &["markers", "hip"], true);
}

/// The left knee follows the right knee's coordinate (a coupler through a custom joint): the
/// right knee's column moves both shanks by different steps, not one twist, so the problem
/// falls back to the tiled kernel, which still matches the dense products.
#[test]
fn coordinate_driving_two_branches_falls_back() {
    let mut spec = bilateral();
    let knee = spec
        .joints
        .iter_mut()
        .find(|j| j.coordinates.iter().any(|c| c.name() == "knee_flexion_l"))
        .expect("left knee");
    let JointKindSpec::Pin { axis } = knee.kind.clone() else {
        panic!("the knee is a pin joint");
    };
    knee.kind = JointKindSpec::Custom {
        axes: vec![TransformAxisSpec {
            motion: AxisMotion::Rotation,
            axis,
            coordinate: Some("knee_flexion_l".into()),
            function: FunctionSpec::identity(),
        }],
    };
    spec.couplers.push(CouplerSpec {
        name: "knees".into(),
        dependent: "knee_flexion_l".into(),
        independent: "knee_flexion_r".into(),
        function: FunctionSpec::Linear {
            slope: 0.8,
            intercept: 0.1,
        },
    });
    check(&spec, &["all"], false);
}

/// The AVX2 products and mirror give the portable loops' numbers bit for bit (same products,
/// same sums, same order), for column counts that are and are not multiples of four, with
/// masked lanes, uneven quad ranges and entries of every sign and scale.
#[cfg(target_arch = "x86_64")]
#[test]
fn avx2_products_and_mirror_are_the_portable_ones() {
    use super::{mirror, mirror_avx2};
    use crate::kinematics::twist::{products, products_avx2};
    if !std::is_x86_feature_detected!("avx2") {
        eprintln!("skipped: no AVX2 on this processor");
        return;
    }
    // A small deterministic generator (xorshift), values spread over many magnitudes.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let u = (state >> 11) as f64 / (1u64 << 53) as f64;
        (u - 0.5) * 10f64.powi((state % 7) as i32 - 3)
    };
    for n in [1usize, 3, 4, 5, 8, 12, 27, 39, 42] {
        let np = n.div_ceil(4) * 4;
        let y: Vec<[f64; 6]> = (0..n).map(|_| std::array::from_fn(|_| next())).collect();
        let xs: Vec<[[f64; 4]; 6]> = (0..np / 4)
            .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| next())))
            .collect();
        // Lower triangle formed in column b (a ≥ b), a lane masked out now and then.
        let mut mask = vec![0.0; n * np];
        for b in 0..n {
            for a in b..n {
                if (a * 7 + b * 3) % 11 != 5 {
                    mask[b * np + a] = 1.0;
                }
            }
        }
        let quads: Vec<std::ops::Range<usize>> = (0..n)
            .map(|b| b / 4..(np / 4).min(b / 4 + 1 + b % 3))
            .collect();
        let (mut c1, mut c2) = (vec![0.0; n * np], vec![0.0; n * np]);
        products(&y, &xs, &mask, &quads, np, &mut c1);
        // SAFETY: AVX2 is present (checked above).
        unsafe { products_avx2(&y, &xs, &mask, &quads, np, &mut c2) };
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&c1), bits(&c2), "products, n = {n}");
        assert!(c1.iter().any(|&x| x != 0.0), "products formed, n = {n}");
        let (mut g1, mut g2) = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
        mirror(&c1, n, np, &mut g1);
        // SAFETY: as above.
        unsafe { mirror_avx2(&c1, n, np, &mut g2) };
        assert_eq!(bits(&g1), bits(&g2), "mirror, n = {n}");
        for b in 0..n {
            assert_eq!(g1[b * n + b], c1[b * np + b], "diagonal {b}, n = {n}");
            for a in b + 1..n {
                assert_eq!(g1[b * n + a], c1[b * np + a] + c1[a * np + b]);
                assert_eq!(g1[b * n + a].to_bits(), g1[a * n + b].to_bits());
            }
        }
    }
}
