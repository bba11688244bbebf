//! Column twists and the grouping of columns by the segments they move: the pieces shared
//! by the IK's composite normal equations (`ik::composite`) and the calibration's frame
//! kernel (`calibrate::kernel_twist`).
//!
//! A column (a coordinate or a joint parameter) that reads steps `k` with scales `c_k`
//! moves every marker `x` it reaches by `∂x/∂θ = Σ_k c_k ∂x/∂s_k` (module docs of
//! [`super`]), a rigid velocity field `ω × (x − P) + v` about any point `P`, with
//! `ω = Σ_rot c_k ω_k` and `v = Σ_rot c_k ω_k × (P − o_k) + Σ_trans c_k ω_k`.

use nalgebra::Vector3;

use super::KinData;

/// One column's step contributions `(step, scale, rotation)`.
pub(crate) type Steps = Vec<(usize, f64, bool)>;

/// The distinct segment sets of the columns (`owners[c]`: the segments column `c` moves),
/// in the order of their first column, and each column's set (`usize::MAX`: moves none).
pub(crate) fn group_columns(owners: &[Vec<usize>]) -> (Vec<Vec<usize>>, Vec<usize>) {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut col_group = vec![usize::MAX; owners.len()];
    for (c, mine) in owners.iter().enumerate() {
        if mine.is_empty() {
            continue;
        }
        col_group[c] = match groups.iter().position(|g| g == mine) {
            Some(g) => g,
            None => {
                groups.push(mine.clone());
                groups.len() - 1
            }
        };
    }
    (groups, col_group)
}

/// The weighted centroid of the markers of `segments` whose `weight` is positive (`None`:
/// there are none), summed segment by segment in order.
#[inline(always)]
pub(crate) fn weighted_centroid(
    segments: &[Vec<usize>],
    kin: &KinData,
    weight: impl Fn(usize) -> f64,
) -> Option<Vector3<f64>> {
    let mut mass = 0.0;
    let mut centre = Vector3::zeros();
    for seg in segments {
        for &j in seg {
            let w = weight(j);
            if w > 0.0 {
                mass += w;
                centre += w * kin.markers[j];
            }
        }
    }
    (mass != 0.0).then(|| centre / mass)
}

/// The twist `(ω, v)` about `centre` of the column with step contributions `steps`, at the
/// last evaluation of `kin` (module docs).
#[inline(always)]
pub(crate) fn column_twist(
    kin: &KinData,
    steps: &[(usize, f64, bool)],
    centre: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let (mut w, mut v) = (Vector3::zeros(), Vector3::zeros());
    for &(step, scale, rotation) in steps {
        let (axis, origin) = kin.step_frame(step);
        if rotation {
            w += scale * axis;
            v += scale * axis.cross(&(centre - origin));
        } else {
            v += scale * axis;
        }
    }
    (w, v)
}
