//! Tests of the certified root seed ([`super::seed::certified_root`]) against the grid
//! scouting it short-cuts ([`super::seed_frame_by_scouting`]), and of the Procrustes floor.

use nalgebra::{Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::seed::{certified_count, procrustes_floor, Floor};
use super::{seed_frame, seed_frame_by_scouting, IkOptions, IkWorkspace};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::{CoordKind, Model};

fn random_rotation(rng: &mut ChaCha8Rng) -> Rotation3<f64> {
    // A uniform random unit quaternion (Shoemake 1992).
    let (u1, u2, u3): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
    let tau = std::f64::consts::TAU;
    let q = nalgebra::Quaternion::new(
        (1.0 - u1).sqrt() * (tau * u2).sin(),
        (1.0 - u1).sqrt() * (tau * u2).cos(),
        u1.sqrt() * (tau * u3).sin(),
        u1.sqrt() * (tau * u3).cos(),
    );
    nalgebra::UnitQuaternion::from_quaternion(q).to_rotation_matrix()
}

/// The subject in a random pose, turned to a uniformly random orientation (upside down
/// included) and moved up to 20 m, with 2 mm of marker noise: the certified seed gives the
/// scouted seed's root coordinates (angles wrapped) within 1e-6, and the shortcut is taken.
#[test]
fn certified_seed_equals_scouted_seed_in_any_orientation() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let opts = IkOptions::default();
    let mut ws = IkWorkspace::new(&model);
    let mut kin = KinData::new(&model);
    let mut rng = ChaCha8Rng::seed_from_u64(2611);
    let root_joint = &model.joints()[0];
    let root: Vec<usize> = root_joint.coords.clone().collect();
    let before = certified_count();
    let cases = 60;
    for case in 0..cases {
        let mut q = model.default_coords();
        for (c, coord) in model.coordinates().iter().enumerate() {
            if !root.contains(&c) && coord.kind == CoordKind::Rotational {
                q[c] = rng.gen_range(-0.4..0.4);
            }
        }
        forward_kinematics(&model, &p, &q, Want::Positions, &mut kin);
        let turn = random_rotation(&mut rng);
        let shift = Vector3::new(
            rng.gen_range(-20.0..20.0),
            rng.gen_range(-2.0..2.0),
            rng.gen_range(-20.0..20.0),
        );
        let targets: Vec<Vector3<f64>> = kin
            .markers
            .iter()
            .map(|x| {
                let noise = Vector3::new(
                    rng.gen_range(-0.002..0.002),
                    rng.gen_range(-0.002..0.002),
                    rng.gen_range(-0.002..0.002),
                );
                turn * x + shift + noise
            })
            .collect();
        let fast = seed_frame(&model, &p, &targets, &opts, &mut ws);
        let slow = seed_frame_by_scouting(&model, &p, &targets, &opts, &mut ws);
        for &c in &root {
            let d = if model.coordinates()[c].kind == CoordKind::Rotational {
                let d = (fast[c] - slow[c]).rem_euclid(std::f64::consts::TAU);
                d.min(std::f64::consts::TAU - d)
            } else {
                (fast[c] - slow[c]).abs()
            };
            assert!(
                d < 1e-6,
                "case {case}, {}: certified {} vs scouted {}",
                model.coordinates()[c].name,
                fast[c],
                slow[c]
            );
        }
    }
    // Most cases take the shortcut (near gimbal lock the two Euler triples merge and the
    // seed scouts instead).
    let taken = certified_count() - before;
    assert!(taken * 10 >= cases * 9, "{taken} of {cases} certified");
}

/// The floor is the misfit at the explicit Kabsch rotation `R = V diag(1, 1, d) Uᵀ` (computed
/// here from the SVD's vectors, not its singular values), no random rotation beats it, and
/// noiseless pairs reach 0.
#[test]
fn procrustes_floor_is_the_least_misfit() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for case in 0..20 {
        let n = 3 + case % 5;
        let turn = random_rotation(&mut rng);
        let noise = if case % 2 == 0 { 0.0 } else { 0.01 };
        let mut pairs: Vec<(f64, Vector3<f64>, Vector3<f64>)> = (0..n)
            .map(|_| {
                let x = Vector3::new(
                    rng.gen_range(-0.2..0.2),
                    rng.gen_range(-0.2..0.2),
                    rng.gen_range(-0.2..0.2),
                );
                let e = Vector3::new(rng.gen(), rng.gen(), rng.gen()) * noise;
                (rng.gen_range(0.5..2.0), x, turn * x + e)
            })
            .collect();
        // Centre both sides on their weighted centroids.
        let mass: f64 = pairs.iter().map(|p| p.0).sum();
        let xc = pairs.iter().map(|p| p.0 * p.1).sum::<Vector3<f64>>() / mass;
        let mc = pairs.iter().map(|p| p.0 * p.2).sum::<Vector3<f64>>() / mass;
        for p in &mut pairs {
            p.1 -= xc;
            p.2 -= mc;
        }
        let misfit = |r: &Rotation3<f64>| -> f64 {
            pairs
                .iter()
                .map(|(w, x, m)| w * (m - r * x).norm_squared())
                .sum()
        };
        let Floor {
            misfit: floor,
            scale,
        } = procrustes_floor(&pairs);
        let mut c = nalgebra::Matrix3::zeros();
        for (w, x, m) in &pairs {
            c += *w * m * x.transpose();
        }
        let svd = c.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let d = (u * vt).determinant().signum();
        let mut fix = nalgebra::Matrix3::identity();
        // The smallest singular value's column.
        let smallest = (0..3)
            .min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]))
            .unwrap();
        fix[(smallest, smallest)] = d;
        let best = Rotation3::from_matrix_unchecked(u * fix * vt);
        assert!(
            (misfit(&best) - floor).abs() <= 1e-12 * scale,
            "case {case}: {} vs {floor}",
            misfit(&best)
        );
        for _ in 0..500 {
            assert!(misfit(&random_rotation(&mut rng)) >= floor - 1e-12 * scale);
        }
        if noise == 0.0 {
            assert!(floor <= 1e-12 * scale, "case {case}: {floor}");
        }
    }
}
