//! Rigid transforms and the elementary motions that joints are chained from: the layer under
//! the model and the kinematics.
//!
//! A [`Pose`] maps coordinates of frame b into frame a (`a_from_b`): `x ↦ R·x + t`. A joint's
//! chain is a product of elementary motions `E_k(s_k)`, each a rotation about, or a translation
//! along, a unit axis by the scalar `s_k`, or a fixed transform. A laboratory whose vertical is
//! not the model's y axis ([`UpAxis`]) is rotated into it by [`up_axis_rotation`].

use nalgebra::{Matrix3, Unit as UnitVec, Vector3};
use serde::{Deserialize, Serialize};

/// A rigid transform `x ↦ rot · x + trans` (`a_from_b` maps b-coordinates into a).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation matrix (orthonormal, determinant +1).
    pub rot: Matrix3<f64>,
    /// Translation (m): the origin of b in a.
    pub trans: Vector3<f64>,
}

impl Pose {
    pub fn identity() -> Self {
        Pose {
            rot: Matrix3::identity(),
            trans: Vector3::zeros(),
        }
    }
    pub(crate) fn is_identity(&self) -> bool {
        self.trans == Vector3::zeros() && self.rot == Matrix3::identity()
    }
    pub fn inverse(&self) -> Pose {
        let rt = self.rot.transpose();
        Pose {
            rot: rt,
            trans: -(rt * self.trans),
        }
    }
    pub fn transform_point(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rot * x + self.trans
    }

    /// Right-multiplies by one elementary transform: `self ← self · E(value)`.
    #[inline]
    pub(crate) fn apply(&mut self, motion: &Motion, value: f64) {
        match motion {
            Motion::RotX => {
                let (s, c) = value.sin_cos();
                let (c1, c2) = (
                    self.rot.column(1).into_owned(),
                    self.rot.column(2).into_owned(),
                );
                self.rot.set_column(1, &(c * c1 + s * c2));
                self.rot.set_column(2, &(c * c2 - s * c1));
            }
            Motion::RotY => {
                let (s, c) = value.sin_cos();
                let (c0, c2) = (
                    self.rot.column(0).into_owned(),
                    self.rot.column(2).into_owned(),
                );
                self.rot.set_column(0, &(c * c0 - s * c2));
                self.rot.set_column(2, &(s * c0 + c * c2));
            }
            Motion::RotZ => {
                let (s, c) = value.sin_cos();
                let (c0, c1) = (
                    self.rot.column(0).into_owned(),
                    self.rot.column(1).into_owned(),
                );
                self.rot.set_column(0, &(c * c0 + s * c1));
                self.rot.set_column(1, &(c * c1 - s * c0));
            }
            Motion::Rot(axis) => {
                let r = nalgebra::Rotation3::from_axis_angle(axis, value);
                self.rot *= r.matrix();
            }
            Motion::TransX => self.trans += value * self.rot.column(0),
            Motion::TransY => self.trans += value * self.rot.column(1),
            Motion::TransZ => self.trans += value * self.rot.column(2),
            Motion::Trans(axis) => self.trans += value * (self.rot * axis.into_inner()),
            Motion::Fixed(p) => {
                self.trans += self.rot * p.trans;
                self.rot *= p.rot;
            }
        }
    }

    /// The world direction of a step's axis when the accumulated pose is `self`.
    #[inline]
    pub(crate) fn axis_of(&self, motion: &Motion) -> Vector3<f64> {
        match motion {
            Motion::RotX | Motion::TransX => self.rot.column(0).into_owned(),
            Motion::RotY | Motion::TransY => self.rot.column(1).into_owned(),
            Motion::RotZ | Motion::TransZ => self.rot.column(2).into_owned(),
            Motion::Rot(a) | Motion::Trans(a) => self.rot * a.into_inner(),
            Motion::Fixed(_) => Vector3::zeros(),
        }
    }
}

/// `a * b` is the composition `a · b` (apply `b`, then `a`): `a_from_b * b_from_c = a_from_c`.
impl std::ops::Mul for Pose {
    type Output = Pose;
    #[inline]
    fn mul(self, other: Pose) -> Pose {
        Pose {
            rot: self.rot * other.rot,
            trans: self.trans + self.rot * other.trans,
        }
    }
}

/// The elementary motion of one step of a segment's chain.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Motion {
    RotX,
    RotY,
    RotZ,
    Rot(UnitVec<Vector3<f64>>),
    TransX,
    TransY,
    TransZ,
    Trans(UnitVec<Vector3<f64>>),
    Fixed(Pose),
}

impl Motion {
    pub(crate) fn is_rotation(&self) -> bool {
        matches!(
            self,
            Motion::RotX | Motion::RotY | Motion::RotZ | Motion::Rot(_)
        )
    }
}

/// Which lab axis points up, for [`up_axis_rotation`]. In a model file (`lab_up`) and on
/// the command line it is written `y`, `-y`, `z`, `-z`, `x` or `-x`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum UpAxis {
    /// +Y is up (OpenSim, TRC exports): no rotation.
    #[serde(rename = "y")]
    Y,
    /// −Y is up.
    #[serde(rename = "-y")]
    NegY,
    /// +Z is up (most C3D labs: Vicon, Qualisys default).
    #[serde(rename = "z")]
    Z,
    /// −Z is up.
    #[serde(rename = "-z")]
    NegZ,
    /// +X is up.
    #[serde(rename = "x")]
    X,
    /// −X is up.
    #[serde(rename = "-x")]
    NegX,
}

impl UpAxis {
    /// Every axis, in the order `y, -y, z, -z, x, -x`.
    pub(crate) const ALL: [UpAxis; 6] = [
        UpAxis::Y,
        UpAxis::NegY,
        UpAxis::Z,
        UpAxis::NegZ,
        UpAxis::X,
        UpAxis::NegX,
    ];

    /// The written name: `y`, `-y`, `z`, `-z`, `x`, `-x` (as [`std::fmt::Display`] writes it).
    pub(crate) fn name(self) -> &'static str {
        match self {
            UpAxis::Y => "y",
            UpAxis::NegY => "-y",
            UpAxis::Z => "z",
            UpAxis::NegZ => "-z",
            UpAxis::X => "x",
            UpAxis::NegX => "-x",
        }
    }

    /// The lab's unit vector that points up.
    pub(crate) fn direction(self) -> Vector3<f64> {
        match self {
            UpAxis::Y => Vector3::y(),
            UpAxis::NegY => -Vector3::y(),
            UpAxis::Z => Vector3::z(),
            UpAxis::NegZ => -Vector3::z(),
            UpAxis::X => Vector3::x(),
            UpAxis::NegX => -Vector3::x(),
        }
    }
}

/// The written name: `y`, `-y`, `z`, `-z`, `x`, `-x`.
impl std::fmt::Display for UpAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Parses a written name (case-insensitive, an optional leading `+`).
impl std::str::FromStr for UpAxis {
    type Err = String;
    fn from_str(s: &str) -> Result<UpAxis, String> {
        let t = s.trim().to_ascii_lowercase();
        let t = t.strip_prefix('+').unwrap_or(&t);
        UpAxis::ALL
            .into_iter()
            .find(|a| a.name() == t)
            .ok_or_else(|| format!("unknown up axis {s:?}; choose y, -y, z, -z, x or -x"))
    }
}

/// Rotation from a lab frame with the given vertical axis to the model's Y-up frame (a proper
/// rotation taking `up.direction()` to +y).
///
/// For `Z`: a rotation of −90° about x, mapping lab (x, y, z) to model (x, z, −y): lab X stays
/// the model's x (anterior when subjects walk along +X), lab Z becomes model y (up).
/// For `NegZ`: +90° about x, mapping (x, y, z) to (x, −z, y). For `NegY`: 180° about x,
/// (x, −y, −z). For `X`: +90° about z, (−y, x, z); for `NegX`: −90° about z, (y, −x, z).
pub fn up_axis_rotation(up: UpAxis) -> Matrix3<f64> {
    match up {
        UpAxis::Y => Matrix3::identity(),
        UpAxis::NegY => Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0),
        UpAxis::Z => Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0),
        UpAxis::NegZ => Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0),
        UpAxis::X => Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        UpAxis::NegX => Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
    }
}

/// The rigid transform that best carries `local` points onto `world` points in the least-squares
/// sense: the [`Pose`] minimizing `Σ_k ‖world_k − (R·local_k + t)‖²` over proper rotations `R`.
///
/// The method of Arun, Huang & Blostein 1987 (IEEE PAMI 9:698–700; "Kabsch"), with Umeyama's 1991
/// sign correction (IEEE PAMI 13:376–380) so that `R` is never a reflection: with the centroids
/// `c_l`, `c_w` and `H = Σ_k (local_k − c_l)(world_k − c_w)ᵀ = U Σ Vᵀ`,
/// `R = V diag(1, 1, sign det(V Uᵀ)) Uᵀ` and `t = c_w − R c_l`. The points are paired by index
/// (the shorter slice decides how many); at least three that are not collinear determine the fit.
///
/// When `det H > 0`, `V Uᵀ` is the orthogonal factor of the polar decomposition
/// `Hᵀ = (V Uᵀ)(U Σ Uᵀ)`, which [`polar_rotation`] computes without the SVD; the SVD is
/// used when `H` is near singular or a reflection would fit better.
pub fn rigid_fit(local: &[Vector3<f64>], world: &[Vector3<f64>]) -> Pose {
    let n = local.len().min(world.len());
    let (local, world) = (&local[..n], &world[..n]);
    let centroid = |p: &[Vector3<f64>]| p.iter().sum::<Vector3<f64>>() / n as f64;
    let (cl, cw) = (centroid(local), centroid(world));
    let mut h = Matrix3::zeros();
    for (l, w) in local.iter().zip(world) {
        h += (l - cl) * (w - cw).transpose();
    }
    let rot = match n {
        3 => three_point_rotation(local, world, &h),
        _ => polar_rotation(&h),
    };
    let rot = rot.unwrap_or_else(|| svd_rotation(&h));
    Pose {
        rot,
        trans: cw - rot * cl,
    }
}

/// The fit of three points, whose `H` is singular: its null vectors are the unit normals
/// `n_l`, `n_w` of the two triangles, and `R = V diag(1, 1, d) Uᵀ` maps `n_l` to `d·n_w`.
/// `H ± c n_l n_wᵀ` (`c = ‖H‖_F`, the sign that makes its determinant positive) keeps `U`,
/// `V` and the first two singular values and puts `c` third, so its polar factor is that same
/// `R` ([`polar_rotation`]). `None` for collinear points.
fn three_point_rotation(
    local: &[Vector3<f64>],
    world: &[Vector3<f64>],
    h: &Matrix3<f64>,
) -> Option<Matrix3<f64>> {
    let normal = |p: &[Vector3<f64>]| (p[1] - p[0]).cross(&(p[2] - p[0])).try_normalize(0.0);
    let (nl, nw) = (normal(local)?, normal(world)?);
    let lift = nl * nw.transpose() * h.norm();
    let up = h + lift;
    match up.determinant() > 0.0 {
        true => polar_rotation(&up),
        false => polar_rotation(&(h - lift)),
    }
}

/// `V diag(1, 1, sign det(V Uᵀ)) Uᵀ` from the SVD `H = U Σ Vᵀ`.
fn svd_rotation(h: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        unreachable!("the SVD was asked for both U and Vᵀ")
    };
    let d = (vt.transpose() * u.transpose()).determinant().signum();
    vt.transpose() * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose()
}

/// `det H` relative to `‖H‖_F³` below which [`polar_rotation`] leaves `H` to the SVD (for
/// singular values `σ₁ ≥ σ₂ ≥ σ₃`, `det H / ‖H‖_F³ ≤ σ₃ / σ₁`: a nearly flat or collinear
/// configuration, or a reflection).
const POLAR_MIN_DET: f64 = 1e-8;

/// The orthogonal polar factor of `Hᵀ` (a proper rotation, `det H > 0`), by Higham's Newton
/// iteration `X ← ½ (γ X + γ⁻¹ X⁻ᵀ)` from `X = Hᵀ` with the Frobenius-norm scaling
/// `γ = (‖X⁻¹‖_F / ‖X‖_F)^½` while the iterates still move by more than 1e-2 (Higham 1986,
/// SIAM J. Sci. Stat. Comput. 7:1160–1174; quadratic convergence). `None` when `H` is too
/// close to singular or to a reflection ([`POLAR_MIN_DET`]), or the iteration does not settle.
fn polar_rotation(h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let size = h.norm();
    // (A NaN fails the comparison too.)
    let solid = h.determinant() > POLAR_MIN_DET * size * size * size;
    if !solid {
        return None;
    }
    let mut x = h.transpose() / size;
    let mut scaled = true;
    for _ in 0..32 {
        let inv_t = x.try_inverse()?.transpose();
        let gamma = if scaled {
            (inv_t.norm() / x.norm()).sqrt()
        } else {
            1.0
        };
        let next = (x * gamma + inv_t / gamma) * 0.5;
        let moved = (next - x).norm();
        x = next;
        if moved <= 1e-15 {
            return Some(x);
        }
        if moved < 1e-2 {
            scaled = false;
        }
        if moved < 1e-8 {
            // Quadratic convergence: one more step brings the change below rounding.
            let inv_t = x.try_inverse()?.transpose();
            return Some((x + inv_t) * 0.5);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn cluster() -> [Vector3<f64>; 4] {
        [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.1, 0.0, 0.02),
            Vector3::new(0.0, 0.12, 0.0),
            Vector3::new(0.03, 0.05, -0.08),
        ]
    }

    #[test]
    fn rigid_fit_recovers_a_transform() {
        let rot = Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        let t = Vector3::new(0.1, -0.4, 2.0);
        let world: Vec<_> = cluster().iter().map(|p| rot * p + t).collect();
        let fit = rigid_fit(&cluster(), &world);
        assert!((fit.rot - rot).abs().max() < 1e-12);
        assert!((fit.trans - t).abs().max() < 1e-12);
    }

    /// With noisy targets the fit is a minimum: no small rotation or translation of it lowers
    /// the sum of squared distances (the first-order condition, checked by finite steps).
    #[test]
    fn rigid_fit_is_the_least_squares_pose() {
        let rot = Rotation3::from_euler_angles(-0.7, 0.4, 0.2).into_inner();
        let noise = [
            Vector3::new(0.004, -0.002, 0.001),
            Vector3::new(-0.003, 0.001, 0.002),
            Vector3::new(0.002, 0.003, -0.004),
            Vector3::new(-0.001, -0.002, 0.003),
        ];
        let world: Vec<_> = cluster()
            .iter()
            .zip(noise)
            .map(|(p, e)| rot * p + Vector3::new(1.0, 0.9, -0.3) + e)
            .collect();
        let cost = |pose: &Pose| -> f64 {
            cluster()
                .iter()
                .zip(&world)
                .map(|(l, w)| (w - pose.transform_point(l)).norm_squared())
                .sum()
        };
        let fit = rigid_fit(&cluster(), &world);
        let best = cost(&fit);
        let h = 1e-4;
        for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
            for sign in [-1.0, 1.0] {
                let turn = Rotation3::from_axis_angle(&axis, sign * h).into_inner();
                let turned = Pose {
                    rot: turn * fit.rot,
                    ..fit
                };
                let moved = Pose {
                    trans: fit.trans + sign * h * axis.into_inner(),
                    ..fit
                };
                assert!(cost(&turned) > best && cost(&moved) > best);
            }
        }
        assert!((fit.rot.determinant() - 1.0).abs() < 1e-12);
    }

    /// Mirrored targets have no proper rotation that matches them; the fit stays a rotation.
    #[test]
    fn rigid_fit_never_returns_a_reflection() {
        let mirror = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        let world: Vec<_> = cluster().iter().map(|p| mirror * p).collect();
        let fit = rigid_fit(&cluster(), &world);
        assert!((fit.rot.determinant() - 1.0).abs() < 1e-12);
        assert!(
            (fit.rot * fit.rot.transpose() - Matrix3::identity())
                .abs()
                .max()
                < 1e-12
        );
    }

    /// The polar iteration gives the SVD's rotation on skin-marker-like clusters: 3 to 6
    /// markers up to 15 cm apart, any orientation, noise from none to a third of their spread
    /// (clusters that the largest noise mirrors go to the SVD).
    #[test]
    fn polar_rotation_is_the_svd_rotation() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (mut polar, mut solid) = (0, 0);
        for case in 0..2000 {
            let n = 3 + case % 4;
            let local: Vec<Vector3<f64>> = (0..n)
                .map(|_| Vector3::from_fn(|_, _| rng.gen_range(-0.15..0.15)))
                .collect();
            let angles: [f64; 3] = [
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-1.5..1.5),
                rng.gen_range(-3.0..3.0),
            ];
            let rot = Rotation3::from_euler_angles(angles[0], angles[1], angles[2]).into_inner();
            let noise = [0.0, 1e-4, 0.005, 0.05][(case / 4) % 4];
            let world: Vec<_> = local
                .iter()
                .map(|p| rot * p + Vector3::from_fn(|_, _| rng.gen_range(-1.0..1.0) * noise))
                .collect();
            let cl = local.iter().sum::<Vector3<f64>>() / n as f64;
            let cw = world.iter().sum::<Vector3<f64>>() / n as f64;
            let h: Matrix3<f64> = local
                .iter()
                .zip(&world)
                .map(|(l, w)| (l - cl) * (w - cw).transpose())
                .sum();
            let reference = svd_rotation(&h);
            // The rotation is determined to rounding over the smallest sum of two singular
            // values (a thin triangle or a flat cluster turns easily about its long axis).
            let sv = h.singular_values();
            let tol = 1e-13 * sv.max() / (sv[1] + sv[2]).min(sv[0] + sv[2]).min(sv[0] + sv[1]);
            let r = match n {
                3 => three_point_rotation(&local, &world, &h),
                _ => polar_rotation(&h),
            };
            if noise < 0.05 {
                solid += 1;
                polar += usize::from(r.is_some());
            }
            if let Some(r) = r {
                assert!((r - reference).abs().max() < tol, "case {case}");
                if noise == 0.0 {
                    assert!(
                        (r - rot).abs().max() < tol,
                        "case {case}: the true rotation"
                    );
                }
                assert!((r * r.transpose() - Matrix3::identity()).abs().max() < 1e-14);
            }
            let fit = rigid_fit(&local, &world);
            assert!((fit.rot - reference).abs().max() < tol, "case {case}");
        }
        // Nearly every cluster below the largest noise takes the iteration; the SVD is the
        // exception.
        assert!(
            polar * 100 >= solid * 99,
            "{polar} of {solid} by the polar iteration"
        );
    }

    /// Collinear points leave one rotation free: the SVD decides, and the fit is a rotation
    /// that carries the points onto their targets.
    #[test]
    fn collinear_points_still_give_a_rotation() {
        let local: Vec<_> = (0..4)
            .map(|k| Vector3::new(0.05 * k as f64, 0.0, 0.0))
            .collect();
        let rot = Rotation3::from_euler_angles(0.2, 0.5, -0.4).into_inner();
        let world: Vec<_> = local.iter().map(|p| rot * p).collect();
        let fit = rigid_fit(&local, &world);
        assert!((fit.rot.determinant() - 1.0).abs() < 1e-12);
        for (l, w) in local.iter().zip(&world) {
            assert!((fit.transform_point(l) - w).norm() < 1e-12);
        }
    }
}
