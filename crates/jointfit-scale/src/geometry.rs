//! A model description scaled by per-body factors, with the geometric rules of OpenSim 4.x
//! `Model::scale` (`OffsetFrame`, `Station`, `SpatialTransform` and
//! `CoordinateCouplerConstraint` scaling):
//!
//! * a joint's parent offset translation is multiplied component-wise by the parent body's
//!   factors `[sx, sy, sz]`, its child offset translation by the child body's;
//! * a marker's position in its body is multiplied component-wise by that body's factors;
//! * a custom joint's translation along unit axis `a` that is a function of coordinates (or a
//!   constant) is multiplied by `|a|·s` of the *parent* body (`|a|` element-wise), except the
//!   identity `f(q) = q`, which is a degree of freedom;
//! * a coupler whose dependent coordinate is a translation is multiplied by the parent body's
//!   `sx` (OpenSim accepts only uniform factors there).
//!
//! Rotations are never scaled. Bodies without an entry keep their size (OpenSim's
//! `InvalidScaleFactors`).

use std::collections::BTreeMap;

use jointfit::model::functions::FunctionSpec;
use jointfit::model::spec::{
    AxisMotion, AxisSpec, JointKindSpec, ModelSpec, OffsetSpec, ScalarSpec,
};

/// Scale factors `[sx, sy, sz]` (dimensionless, along the body's own axes) by body name.
pub type ScaleFactors = BTreeMap<String, [f64; 3]>;

/// The unit vector of an axis description (`"x"`, `"-y"`, a vector); `None` when malformed.
pub(crate) fn axis_vector(axis: &AxisSpec) -> Option<[f64; 3]> {
    match axis {
        AxisSpec::Vector(v) => {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            (n > 0.0).then(|| [v[0] / n, v[1] / n, v[2] / n])
        }
        AxisSpec::Named(s) => {
            let t = s.trim();
            let (sign, rest) = match t.strip_prefix('-') {
                Some(r) => (-1.0, r),
                None => (1.0, t.strip_prefix('+').unwrap_or(t)),
            };
            match rest {
                "x" | "X" => Some([sign, 0.0, 0.0]),
                "y" | "Y" => Some([0.0, sign, 0.0]),
                "z" | "Z" => Some([0.0, 0.0, sign]),
                _ => None,
            }
        }
    }
}

/// The factor OpenSim applies to a translation function along `axis` of a joint whose
/// parent body has factors `s`: `|a|·s`.
pub(crate) fn axis_factor(axis: &AxisSpec, s: &[f64; 3]) -> f64 {
    axis_vector(axis).map_or(1.0, |a| {
        a[0].abs() * s[0] + a[1].abs() * s[1] + a[2].abs() * s[2]
    })
}

/// Whether OpenSim leaves this translation function alone (the identity: a DOF).
pub(crate) fn is_dof_function(f: &FunctionSpec) -> bool {
    matches!(f, FunctionSpec::Linear { slope, intercept } if *slope == 1.0 && *intercept == 0.0)
}

/// `scale · f`, folding into an existing multiplier as OpenSim does.
pub(crate) fn multiply(f: &FunctionSpec, scale: f64) -> FunctionSpec {
    match f {
        FunctionSpec::Multiplier { scale: s, function } => FunctionSpec::Multiplier {
            scale: s * scale,
            function: function.clone(),
        },
        other => FunctionSpec::Multiplier {
            scale,
            function: Box::new(other.clone()),
        },
    }
}

fn scale_offset(o: &mut OffsetSpec, s: &[f64; 3]) {
    for (k, slot) in [&mut o.tx, &mut o.ty, &mut o.tz].into_iter().enumerate() {
        match slot {
            ScalarSpec::Fixed(v) => *v *= s[k],
            ScalarSpec::Param(name) => *slot = ScalarSpec::param(&name.clone(), s[k]),
            ScalarSpec::Scaled { scale, .. } => *scale *= s[k],
        }
    }
}

/// Whether coordinate `name` is translational as OpenSim classifies it: a slider's, or used
/// by a custom joint's translation axis through a linear function of slope ±1 (a coordinate
/// used only through other functions is "coupled", neither rotational nor translational).
pub fn is_translational(spec: &ModelSpec, name: &str) -> bool {
    spec.joints.iter().any(|j| match &j.kind {
        JointKindSpec::Slider { .. } => j.coordinates.iter().any(|c| c.name() == name),
        JointKindSpec::Custom { axes } => axes.iter().any(|a| {
            a.motion == AxisMotion::Translation
                && a.coordinate.as_deref() == Some(name)
                && matches!(a.function, FunctionSpec::Linear { slope, .. } if slope.abs() == 1.0)
        }),
        _ => false,
    })
}

/// `spec` scaled by `factors` (module docs). Unknown body names in `factors` are ignored.
pub fn scaled_spec(spec: &ModelSpec, factors: &ScaleFactors) -> ModelSpec {
    let mut out = spec.clone();
    for j in out.joints.iter_mut() {
        if let Some(s) = factors.get(&j.parent) {
            scale_offset(&mut j.parent_offset, s);
            if let JointKindSpec::Custom { axes } = &mut j.kind {
                for a in axes.iter_mut() {
                    if a.motion == AxisMotion::Translation && !is_dof_function(&a.function) {
                        a.function = multiply(&a.function, axis_factor(&a.axis, s));
                    }
                }
            }
        }
        if let Some(s) = factors.get(&j.child) {
            scale_offset(&mut j.child_offset, s);
        }
    }
    for m in out.markers.iter_mut() {
        if let Some(s) = factors.get(&m.segment) {
            for (x, f) in m.position.iter_mut().zip(s) {
                *x *= f;
            }
        }
    }
    let parent_of_coordinate = |name: &str| {
        spec.joints
            .iter()
            .find(|j| j.coordinates.iter().any(|c| c.name() == name))
            .map(|j| j.parent.clone())
    };
    for c in out.couplers.iter_mut() {
        if !is_translational(spec, &c.dependent) {
            continue;
        }
        if let Some(s) = parent_of_coordinate(&c.dependent).and_then(|b| factors.get(&b)) {
            c.function = multiply(&c.function, s[0]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::lower_limb::{lower_limb, Side};

    fn check(a: &ScalarSpec, b: &ScalarSpec, s: f64) {
        match (a, b) {
            (ScalarSpec::Fixed(x), ScalarSpec::Fixed(y)) => assert_eq!(*y, x * s),
            _ => {
                let (na, sa) = a.as_param().unwrap();
                let (nb, sb) = b.as_param().unwrap();
                assert_eq!(na, nb);
                assert_eq!(sb, sa * s);
            }
        }
    }

    #[test]
    fn offsets_and_markers_scale_by_their_own_body() {
        let spec = lower_limb(Side::Right);
        let mut f = ScaleFactors::new();
        f.insert("thigh".into(), [1.1, 1.2, 0.9]);
        let out = scaled_spec(&spec, &f);
        let of = |body: &str| f.get(body).copied().unwrap_or([1.0; 3]);
        for (a, b) in spec.joints.iter().zip(&out.joints) {
            let (pf, cf) = (of(&a.parent), of(&a.child));
            for k in 0..3 {
                check(
                    a.parent_offset.scalars()[k],
                    b.parent_offset.scalars()[k],
                    pf[k],
                );
                check(
                    a.child_offset.scalars()[k],
                    b.child_offset.scalars()[k],
                    cf[k],
                );
            }
            assert_eq!(a.parent_offset.rx, b.parent_offset.rx);
        }
        for (a, b) in spec.markers.iter().zip(&out.markers) {
            for ((y, x), f) in b.position.iter().zip(a.position).zip(of(&a.segment)) {
                assert_eq!(*y, x * f);
            }
        }
    }

    #[test]
    fn translation_functions_take_the_parent_axis_factor() {
        assert_eq!(
            axis_factor(&AxisSpec::Named("-y".to_string()), &[2.0, 3.0, 4.0]),
            3.0
        );
        let v = AxisSpec::Vector([0.6, 0.0, 0.8]);
        assert!((axis_factor(&v, &[2.0, 3.0, 4.0]) - (1.2 + 3.2)).abs() < 1e-15);
        let f = FunctionSpec::Constant { value: 0.1 };
        let g = multiply(&multiply(&f, 2.0), 3.0);
        assert_eq!(
            g,
            FunctionSpec::Multiplier {
                scale: 6.0,
                function: Box::new(f)
            }
        );
        assert!(is_dof_function(&FunctionSpec::identity()));
    }
}
