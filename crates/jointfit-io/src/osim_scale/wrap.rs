//! A straight path segment wrapped over an OpenSim `WrapCylinder`, as OpenSim 4.x computes
//! it (`WrapCylinder::wrapLine`, `_make_spiral_path`, `_adjust_tangent_point`; definitions
//! read from OpenSim's sources). Everything here is in the cylinder's own frame: the axis is
//! `z` through the origin, the cylinder spans `z ∈ [−L/2, L/2]`.
//!
//! For the end points `p1`, `p2` of a segment (both outside the radius `r`):
//!
//! 1. an unconstrained cylinder (`quadrant` `all`) wraps only when the segment passes within
//!    `r` of the axis between its ends (a *mandatory* wrap); a constrained one (`±x`, `±y`)
//!    also when the ends lie on different sides of the active half-space and the segment's
//!    point nearest the axis is outside it;
//! 2. each end has two tangent lines to the circle of radius `r` in the cross-section
//!    through it; the tangent points `r1`, `r2` are chosen among the four pairs (the pair
//!    closest in angle, or the one on the active side), then slid along the axis onto the
//!    plane through `p1`, `p2` and the apex of the wrap;
//! 3. no wrap when both tangent points lie beyond the cylinder's length;
//! 4. the path over the surface is the helix from `r1` to `r2`: with `θ` the angle between
//!    them about the axis (`2π − θ` for a wrap the long way round) and `a` their axial
//!    distance, its length is `√((rθ)² + a²)`. When the path wraps over more than one
//!    object, the tangent points are moved along the axis until the straight segments
//!    leave the helix within 0.1° of tangency (at most 100 corrections of 1.5 times the
//!    step to the tangent line's crossing), as OpenSim does; a path over a single object
//!    keeps the first tangent points.

use nalgebra::{Matrix3, Vector3};

type V = Vector3<f64>;

/// What a wrap of one segment gave (OpenSim's `WrapAction`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Outcome {
    NoWrap,
    InsideRadius,
    Wrapped,
    Mandatory,
}

/// A wrapped segment: tangent points (cylinder frame) and the length over the surface.
#[derive(Debug, Clone, Copy)]
pub(super) struct Arc {
    pub r1: V,
    pub r2: V,
    pub length: f64,
}

/// A `WrapCylinder`'s shape in its own frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cylinder {
    pub radius: f64,
    pub length: f64,
    /// The active half-space: axis (0 = x, 1 = y, 2 = z) and sign; `None` for `all`.
    pub quadrant: Option<(usize, f64)>,
}

/// The axis: a point on it and its direction.
const P0: V = V::new(0.0, 0.0, -1.0);
const DN: V = V::new(0.0, 0.0, 1.0);
const MAX_ITERATIONS: usize = 100;
const TANGENCY_THRESHOLD: f64 = 0.1 * std::f64::consts::PI / 180.0;
/// OpenSim's `LINE_EPSILON` and `ROUNDOFF_ERROR`.
const LINE_EPSILON: f64 = 1e-5;
const ROUNDOFF: f64 = 2e-13;

/// OpenSim's quadrant names.
pub(super) fn quadrant(name: &str) -> Result<Option<(usize, f64)>, String> {
    let q = match name.trim() {
        "-x" | "-X" => (0, -1.0),
        "x" | "+x" | "X" | "+X" => (0, 1.0),
        "-y" | "-Y" => (1, -1.0),
        "y" | "+y" | "Y" | "+Y" => (1, 1.0),
        "-z" | "-Z" => (2, -1.0),
        "z" | "+z" | "Z" | "+Z" => (2, 1.0),
        "all" | "ALL" | "All" | "Unassigned" | "" => return Ok(None),
        other => return Err(format!("unknown wrap quadrant {other:?}")),
    };
    Ok(Some(q))
}

fn sign(a: f64) -> f64 {
    if a >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// `(v/|v|, |v|)`, or zero below machine epsilon.
fn unit(v: V) -> (V, f64) {
    let m = v.norm();
    if m >= f64::EPSILON {
        (v / m, m)
    } else {
        (V::zeros(), m)
    }
}

/// The point of the line through `at` along `dir` (any length) closest to `p`.
fn closest_on_line(p: V, at: V, dir: V) -> V {
    let (v1, mag) = unit(p - at);
    let (v2, _) = unit(dir);
    at + v1.dot(&v2) * mag * v2
}

fn dist2_to_axis(p: V) -> f64 {
    let d = P0 - p;
    (d - d.dot(&DN) * DN).norm_squared()
}

/// Closest points of the lines `p1 p2` and `p3 p4` and the first one's parameter along
/// `p1 → p2`; `None` for parallel lines.
fn intersect_lines(p1: V, p2: V, p3: V, p4: V) -> Option<(V, f64, V)> {
    let (v1, mag1) = unit(p2 - p1);
    let (v2, _) = unit(p4 - p3);
    let cross = v1.cross(&v2);
    let denom = cross.norm_squared();
    if denom.abs() <= ROUNDOFF {
        return None;
    }
    let d = p3 - p1;
    let t = Matrix3::from_rows(&[d.transpose(), v1.transpose(), cross.transpose()]).determinant()
        / denom;
    let s = Matrix3::from_rows(&[d.transpose(), v2.transpose(), cross.transpose()]).determinant()
        / denom;
    Some((p1 + s * v1, s / mag1, p3 + t * v2))
}

/// Where the segment `a b` crosses the plane `n·x + d = 0`.
fn cross_plane(a: V, b: V, n: V, d: f64) -> Option<V> {
    let v = b - a;
    let dot = v.dot(&n);
    if dot.abs() < LINE_EPSILON {
        return None;
    }
    let t = (-d - n.dot(&a)) / dot;
    if !(-LINE_EPSILON..=1.0 + LINE_EPSILON).contains(&t) {
        return None;
    }
    Some(a + t * v)
}

/// The two tangent points, in the cross-section through `p`, of the lines from `p` to the
/// circle; and the distance of `p` from the axis.
fn tangents(p: V, radius: f64) -> (V, V, V, f64) {
    let foot = closest_on_line(p, P0, DN);
    let (v, dist) = unit(p - foot);
    let sin = radius / dist;
    let along = radius * sin;
    let centre = foot + along * v;
    let across = (radius * radius - along * along).sqrt();
    let u = DN.cross(&v);
    (centre + across * u, centre - across * u, foot, dist)
}

/// How the tangent points of a constrained cylinder are chosen.
struct Choice {
    r1: V,
    r2: V,
    far_side: bool,
}

impl Cylinder {
    fn side(&self, p: V) -> bool {
        let (axis, s) = self.quadrant.expect("constrained");
        sign(p[axis]) == s
    }

    /// The tangent pair on the active side of a constrained cylinder (OpenSim's case table).
    fn constrained_choice(&self, ra: [V; 2], rb: [V; 2], feet: [V; 2]) -> Choice {
        let (r1a, r1b, r2a, r2b) = (ra[0], rb[0], ra[1], rb[1]);
        let angle = |a: V, b: V| (a.dot(&b) / (a.norm() * b.norm())).acos();
        let alpha = angle(r1a - feet[0], r2b - feet[1]);
        let beta = angle(r1b - feet[0], r2a - feet[1]);
        let b_a = |far_if_alpha_greater: bool| Choice {
            r1: r1b,
            r2: r2a,
            far_side: (alpha > beta) == far_if_alpha_greater,
        };
        let a_b = |far_if_alpha_greater: bool| Choice {
            r1: r1a,
            r2: r2b,
            far_side: (alpha > beta) == far_if_alpha_greater,
        };
        match (self.side(r1a), self.side(r1b)) {
            (true, true) if self.side(r2a) => b_a(false),
            (true, true) => a_b(true),
            (true, false) => a_b(true),
            (false, true) => b_a(false),
            (false, false) if self.side(r2a) => b_a(false),
            (false, false) if self.side(r2b) => a_b(true),
            (false, false) if alpha > beta => Choice {
                r1: r1a,
                r2: r2b,
                far_side: true,
            },
            (false, false) => Choice {
                r1: r1b,
                r2: r2a,
                far_side: true,
            },
        }
    }

    /// Wraps the segment `p1 p2` (cylinder frame); `single`: the path has no other wrap
    /// object (the tangent points are then not corrected).
    pub(super) fn wrap_line(&self, p1: V, p2: V, single: bool) -> (Outcome, Option<Arc>) {
        let r = self.radius;
        if dist2_to_axis(p1) < r * r || dist2_to_axis(p2) < r * r {
            return (Outcome::InsideRadius, None);
        }
        let (start, end) = (
            V::new(0.0, 0.0, -0.5 * self.length),
            V::new(0.0, 0.0, 0.5 * self.length),
        );
        let nan = V::repeat(f64::NAN);
        let (near12, t12, near00) =
            intersect_lines(p1, p2, start, end).unwrap_or((nan, f64::NAN, nan));
        let crosses = (near12 - near00).norm_squared() < r * r && t12 > 0.0 && t12 < 1.0;
        let mut outcome = Outcome::Wrapped;
        if self.quadrant.is_none() {
            if !crosses {
                return (Outcome::NoWrap, None);
            }
            outcome = Outcome::Mandatory;
        }
        let (r1a, r1b, p11, d1) = tangents(p1, r);
        let (r2a, r2b, p22, d2) = tangents(p2, r);

        let (mut r1, mut r2, far_side, long_wrap) = if let Some((axis, s)) = self.quadrant {
            if sign(p1[axis]) == s || sign(p2[axis]) == s {
                if crosses {
                    outcome = Outcome::Mandatory;
                } else if sign(p1[axis]) != sign(p2[axis]) && sign(near12[axis]) != s {
                    outcome = Outcome::Wrapped;
                } else {
                    return (Outcome::NoWrap, None);
                }
            }
            let c = self.constrained_choice([r1a, r2a], [r1b, r2b], [p11, p22]);
            let sum_musc = (c.r1 - p1) + (c.r2 - p2);
            let sum_r = (c.r1 - p11) + (c.r2 - p22);
            (c.r1, c.r2, c.far_side, sum_r.dot(&sum_musc) < 0.0)
        } else {
            let n = |v: V| unit(v).0;
            let (a1, b1, a2, b2) = (n(r1a - p11), n(r1b - p11), n(r2a - p22), n(r2b - p22));
            let (dot1, dot2, dot3, dot4) = (a1.dot(&a2), a1.dot(&b2), b1.dot(&a2), b1.dot(&b2));
            let (r1, r2) = if dot1 > dot2 && dot1 > dot3 && dot1 > dot4 {
                (r1a, r2a)
            } else if dot2 > dot3 && dot2 > dot4 {
                (r1a, r2b)
            } else if dot3 > dot4 {
                (r1b, r2a)
            } else {
                (r1b, r2b)
            };
            (r1, r2, false, false)
        };

        let apex = self.apex(p1, p2, d1 / (d1 + d2), far_side);
        let (u, _) = unit(p1 - apex);
        let (v, _) = unit(p2 - apex);
        let (normal, _) = unit(u.cross(&v));
        let d = -p1.dot(&normal);
        if let Some(r1p) = cross_plane(r1 - 10.0 * DN, r1 + 10.0 * DN, normal, d) {
            let on_axis = closest_on_line(r1p, p11, p22);
            if (on_axis - p22).norm_squared() < (p11 - p22).norm_squared() {
                r1 = r1p;
            }
        }
        if let Some(r2p) = cross_plane(r2 - 10.0 * DN, r2 + 10.0 * DN, normal, d) {
            let on_axis = closest_on_line(r2p, p11, p22);
            if (on_axis - p11).norm_squared() < (p22 - p11).norm_squared() {
                r2 = r2p;
            }
        }
        let half = 0.5 * self.length;
        let beyond = |p: V| p.z < -half || p.z > half;
        if beyond(r1) && beyond(r2) {
            return (Outcome::NoWrap, None);
        }
        let arc = self.spiral(p1, p2, r1, r2, long_wrap, single);
        (outcome, Some(arc))
    }

    /// The apex of the wrap: on the surface, in the plane through `p1`, `p2` and the axis
    /// point nearest the segment's point at fraction `t`, on the segment's side (the far
    /// side for a far-side wrap).
    fn apex(&self, p1: V, p2: V, t: f64, far_side: bool) -> V {
        let mpt = p1 + t * (p2 - p1);
        let axispt = closest_on_line(mpt, P0, DN);
        let (l1, _) = unit(p1 - axispt);
        let (l2, _) = unit(p2 - axispt);
        let (normal, _) = unit(l1.cross(&l2));
        let (vert1, _) = unit(DN.cross(&normal));
        let (vert2, _) = unit(normal.cross(&DN));
        let apex1 = axispt + self.radius * vert1;
        let apex2 = axispt + self.radius * vert2;
        let nearer1 = (mpt - apex1).norm_squared() < (mpt - apex2).norm_squared();
        if nearer1 != far_side {
            apex1
        } else {
            apex2
        }
    }

    /// The helix from `r1` to `r2` (module docs, step 4).
    fn spiral(&self, p1: V, p2: V, mut r1: V, mut r2: V, long_wrap: bool, single: bool) -> Arc {
        let sense = if long_wrap { -1.0 } else { 1.0 };
        let mut iterations = 0;
        loop {
            let r1a = closest_on_line(r1, P0, DN);
            let r2a = closest_on_line(r2, P0, DN);
            let axial = (r2a - r1a).dot(&DN);
            let (u, v) = (r1 - r1a, r2 - r2a);
            let mut theta = u.cross(&v).dot(&DN).atan2(u.dot(&v));
            if long_wrap {
                theta = 2.0 * std::f64::consts::PI - theta;
            }
            let x = self.radius * theta;
            let length = (x * x + axial * axial).sqrt();
            let segments = ((length / 0.002) as i64).max(1);
            if single || segments < 2 || iterations >= MAX_ITERATIONS {
                return Arc { r1, r2, length };
            }
            let at = |r1: V, t: f64| {
                let (s, c) = (sense * t * theta).sin_cos();
                V::new(c * r1.x - s * r1.y, s * r1.x + c * r1.y, r1.z) + DN * (t * axial)
            };
            let t = 1.0 / segments as f64;
            let w1 = at(r1, t);
            let moved1 = adjust_tangent(p1, &mut r1, w1);
            let w2 = at(r1, 1.0 - t);
            let moved2 = adjust_tangent(p2, &mut r2, w2);
            if !(moved1 || moved2) {
                return Arc { r1, r2, length };
            }
            iterations += 1;
        }
    }
}

/// Slides the tangent point `r` along the axis when the line from `p` to it leaves the
/// surface more than 0.1° off the helix direction towards `w` (true when it moved).
fn adjust_tangent(p: V, r: &mut V, w: V) -> bool {
    let (pr, _) = unit(*r - p);
    let (rw, _) = unit(w - *r);
    let alpha = pr.dot(&DN).acos();
    let omega = rw.dot(&DN).acos();
    // A NaN angle (degenerate directions) leaves the point where it is, as in OpenSim.
    let off = (alpha - omega).abs();
    if off.is_nan() || off <= TANGENCY_THRESHOLD {
        return false;
    }
    let pa = closest_on_line(p, *r, DN);
    let wa = closest_on_line(w, *r, DN);
    let target = intersect_lines(p, w, pa, wa).map_or(V::repeat(f64::NAN), |x| x.2);
    *r += 1.5 * (target - *r);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cylinder(quadrant: Option<(usize, f64)>) -> Cylinder {
        Cylinder {
            radius: 0.05,
            length: 1.0,
            quadrant,
        }
    }

    #[test]
    fn a_segment_through_the_axis_wraps_half_round_in_its_plane() {
        // Both ends in the plane z = 0 at distance D on opposite sides: the wrap is the arc
        // between the two tangent points, each at angle acos(r/D) from the end's direction.
        let (r, dd) = (0.05, 0.2);
        let (p1, p2) = (V::new(dd, 0.0, 0.0), V::new(-dd, 0.0, 0.0));
        // Move the ends slightly off the axis plane so the straight line passes at 1 mm.
        let (p1, p2) = (p1 + V::new(0.0, 0.001, 0.0), p2 + V::new(0.0, 0.001, 0.0));
        let (outcome, arc) = cylinder(None).wrap_line(p1, p2, true);
        assert_eq!(outcome, Outcome::Mandatory);
        let arc = arc.unwrap();
        // exact: the arc angle is π − 2 acos(r/D) corrected for the 1 mm offset of each end
        let side = |p: V| (r / p.xy().norm()).acos() + (p.y / p.x.abs()).atan();
        let expected = r * (std::f64::consts::PI - side(p1) - side(p2));
        assert!((arc.length - expected).abs() < 1e-12, "{}", arc.length);
        for t in [arc.r1, arc.r2] {
            assert!((t.xy().norm() - r).abs() < 1e-12);
            assert!(t.z.abs() < 1e-12);
        }
        // the straight legs are tangent: perpendicular to the radius at the tangent point
        assert!((p1 - arc.r1).xy().dot(&arc.r1.xy()).abs() < 1e-12);
    }

    #[test]
    fn a_segment_that_misses_an_unconstrained_cylinder_does_not_wrap() {
        let (p1, p2) = (V::new(0.2, 0.1, 0.0), V::new(-0.2, 0.1, 0.0));
        assert_eq!(cylinder(None).wrap_line(p1, p2, true).0, Outcome::NoWrap);
        let inside = V::new(0.01, 0.0, 0.0);
        assert_eq!(
            cylinder(None).wrap_line(inside, p2, true).0,
            Outcome::InsideRadius
        );
    }

    #[test]
    fn a_constrained_cylinder_wraps_a_path_passing_on_its_inactive_side() {
        // +y active: ends on the active side and a line missing the cylinder do not wrap;
        // a line whose point nearest the axis is at y < 0 between ends on both sides is
        // pulled round the +y side: longer than straight, tangent points on the surface.
        let c = cylinder(Some((1, 1.0)));
        let (p1, p2) = (V::new(0.2, 0.1, 0.0), V::new(-0.2, 0.1, 0.0));
        assert_eq!(c.wrap_line(p1, p2, true).0, Outcome::NoWrap);
        let (p1, p2) = (V::new(0.2, 0.1, 0.0), V::new(0.1, -0.2, 0.0));
        let (outcome, arc) = c.wrap_line(p1, p2, true);
        assert_eq!(outcome, Outcome::Wrapped);
        let arc = arc.unwrap();
        for t in [arc.r1, arc.r2] {
            assert!((t.xy().norm() - 0.05).abs() < 1e-12);
        }
        let wrapped = (p1 - arc.r1).norm() + arc.length + (arc.r2 - p2).norm();
        assert!(wrapped > (p1 - p2).norm() + 0.05, "{wrapped}");
    }

    #[test]
    fn tangent_points_are_corrected_to_tangency_when_the_path_has_other_wraps() {
        // Ends at different heights: the first tangent points leave the helix at an angle;
        // corrected (several wrap objects on the path), each straight leg meets the helix
        // within a fraction of a degree of its direction (angle to the axis compared).
        let p1 = V::new(0.2, 0.001, -0.1);
        let p2 = V::new(-0.2, 0.001, 0.12);
        let c = cylinder(None);
        let gap = |arc: Arc, p: V, r: V, other: V| {
            let (u, v) = (r.xy(), other.xy());
            let theta = (u.x * v.y - u.y * v.x).atan2(u.dot(&v));
            let tangent = V::new(-r.y * theta, r.x * theta, other.z - r.z).normalize();
            let leg = (r - p).normalize();
            let _ = arc;
            (leg.dot(&DN).acos() - tangent.dot(&DN).acos()).abs()
        };
        let (_, first) = c.wrap_line(p1, p2, true);
        let (_, fixed) = c.wrap_line(p1, p2, false);
        let (first, fixed) = (first.unwrap(), fixed.unwrap());
        let before = gap(first, p1, first.r1, first.r2);
        let after = gap(fixed, p1, fixed.r1, fixed.r2);
        assert!(after < 0.5f64.to_radians(), "{}", after.to_degrees());
        assert!(before > after, "{} {}", before, after);
        let legs = |a: Arc| (p1 - a.r1).norm() + a.length + (a.r2 - p2).norm();
        assert!(legs(fixed) <= legs(first) + 1e-9);
    }
}
