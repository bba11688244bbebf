//! General joints through coordinate functions (OpenSim's `CustomJoint`), locked
//! coordinates and coordinate couplers.
//!
//! A custom joint is a list of transform axes applied in order, each intrinsic (about or
//! along an axis of the frame the axes before it produced):
//!
//! `motion(q) = E_1(f_1(c_1)) · E_2(f_2(c_2)) · …`,
//!
//! where `c_k` is one coordinate of the joint and `f_k` a [`Function`]. OpenSim's
//! `SpatialTransform` (translations along the parent joint frame's axes, then the three
//! rotations, each about the frame produced by the previous ones) is the list
//! `translation1..3, rotation1..3`; its other joints are written the same way by the reader.
//!
//! A coordinate is *independent* (an entry of `q`), *locked* (held at its default, so every
//! axis it drives is a constant), or *coupled*: `c = g(q_i)` for a coupler function `g`.
//! An axis driven by a coupled coordinate reads `s = f(g(q_i))`, so by the chain rule
//! `∂s/∂q_i = f′(g(q_i)) · g′(q_i)`. Inverse kinematics and calibration only see `q`.
//!
//! The step scalar's derivative `σ = ∂s/∂q_i` enters the geometric Jacobian
//! ([`crate::kinematics`]) by scaling the step's world axis: forward kinematics stores
//! `σ ω_k` for such steps, so `σ ω_k × (x − o_k)` and `σ ω_k` are the exact columns.

use std::collections::HashMap;

use nalgebra::Vector3;

use super::compiled::CoordKind;
use super::functions::Function;
use super::spec::{AxisMotion, CoordinateSpec, FunctionSpec, JointKindSpec, ModelSpec};
use super::ModelError;

/// One transform axis of a compiled custom joint.
#[derive(Debug, Clone, PartialEq)]
pub struct TransformAxis {
    pub rotation: bool,
    /// Unit axis in the frame the axes before it produced.
    pub axis: Vector3<f64>,
    /// The joint coordinate that drives it (`None`: constant).
    pub coordinate: Option<String>,
    pub function: Function,
}

/// The scalar of a step driven through functions: `f(g(q_i))` (`g` absent: `f(q_i)`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AxisFn {
    pub outer: Function,
    pub inner: Option<Function>,
}

impl AxisFn {
    /// `(s, ∂s/∂q_i)`.
    #[inline]
    pub(crate) fn eval(&self, q: f64) -> (f64, f64) {
        match &self.inner {
            None => self.outer.eval(q),
            Some(g) => {
                let (c, dc) = g.eval(q);
                let (s, ds) = self.outer.eval(c);
                (s, ds * dc)
            }
        }
    }
}

/// How a coordinate that is not in `q` gets its value.
#[derive(Debug, Clone, PartialEq)]
pub enum CoordRule {
    /// Held at this value.
    Locked(f64),
    /// `value = function(q[independent])`.
    Coupled {
        independent: usize,
        function: Function,
    },
}

/// A coordinate outside `q`: locked or coupled.
#[derive(Debug, Clone, PartialEq)]
pub struct DependentCoordinate {
    pub name: String,
    /// Index in [`super::Model::joints`] of the joint whose motion reads this coordinate.
    pub joint: usize,
    pub kind: CoordKind,
    /// OpenSim's motion type (the unit in `.mot` files).
    pub motion: MotionType,
    pub range: [f64; 2],
    pub default: f64,
    pub rule: CoordRule,
}

impl DependentCoordinate {
    pub fn value(&self, q: &[f64]) -> f64 {
        match &self.rule {
            CoordRule::Locked(v) => *v,
            CoordRule::Coupled {
                independent,
                function,
            } => function.eval(q[*independent]).0,
        }
    }
}

/// OpenSim's classification of a coordinate, which decides its unit in `.mot` files
/// (degrees only for `Rotational`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionType {
    Rotational,
    Translational,
    /// Drives its axes only through scaled or nonlinear functions.
    Coupled,
}

/// OpenSim 4's rule (`CustomJoint`): visiting rotation1..3 then translation1..3, an axis that
/// reads the coordinate through a `LinearFunction` of slope ±1 makes it rotational or
/// translational (the last such axis wins); any other function makes it coupled unless a
/// pure axis decides.
pub(crate) fn opensim_motion(kind: &JointKindSpec, name: &str) -> Option<MotionType> {
    let JointKindSpec::Custom { axes } = kind else {
        return None;
    };
    let mut mt = None;
    for motion in [AxisMotion::Rotation, AxisMotion::Translation] {
        for a in axes
            .iter()
            .filter(|a| a.motion == motion && a.coordinate.as_deref() == Some(name))
        {
            match a.function {
                FunctionSpec::Linear { slope, .. } if slope == 1.0 || slope == -1.0 => {
                    mt = Some(match motion {
                        AxisMotion::Rotation => MotionType::Rotational,
                        AxisMotion::Translation => MotionType::Translational,
                    })
                }
                _ => {
                    mt.get_or_insert(MotionType::Coupled);
                }
            }
        }
    }
    // A coordinate that drives nothing is what OpenSim leaves undefined; call it coupled.
    Some(mt.unwrap_or(MotionType::Coupled))
}

/// What the compiler needs to know about a coordinate before it emits steps.
#[derive(Debug, Clone)]
pub(crate) enum Role {
    /// Index in `q`.
    Free(usize),
    Locked(f64),
    Coupled {
        independent: usize,
        g: Function,
    },
}

/// The motion type of a custom joint's coordinate: rotational when it drives a rotation
/// through a non-constant function, else translational.
pub(crate) fn custom_coord_kind(kind: &JointKindSpec, name: &str) -> Option<CoordKind> {
    let JointKindSpec::Custom { axes } = kind else {
        return None;
    };
    let drives = |m: AxisMotion| {
        axes.iter().any(|a| {
            a.motion == m
                && a.coordinate.as_deref() == Some(name)
                && a.function.constant_value().is_none()
        })
    };
    Some(if drives(AxisMotion::Rotation) {
        CoordKind::Rotational
    } else {
        CoordKind::Translational
    })
}

/// Decides every coordinate's role, joints in topological order: free coordinates get
/// consecutive indices in `q`, in joint order.
pub(crate) fn roles(
    spec: &ModelSpec,
    order: &[usize],
) -> Result<HashMap<String, Role>, ModelError> {
    let mut couplers: HashMap<&str, (&str, Function)> = HashMap::new();
    for c in &spec.couplers {
        let g = Function::try_from(&c.function)
            .map_err(|e| ModelError::Invalid(format!("coupler {:?}: {e}", c.name)))?;
        if couplers
            .insert(c.dependent.as_str(), (c.independent.as_str(), g))
            .is_some()
        {
            return Err(ModelError::Invalid(format!(
                "coordinate {:?} is the dependent of two couplers",
                c.dependent
            )));
        }
    }
    let mut known: HashMap<&str, (bool, f64)> = HashMap::new(); // name → (locked, default)
    for js in &spec.joints {
        for cs in &js.coordinates {
            let (locked, default) = match cs {
                CoordinateSpec::Name(_) => (false, 0.0),
                CoordinateSpec::Full {
                    locked, default, ..
                } => (*locked, *default),
            };
            let custom = matches!(js.kind, JointKindSpec::Custom { .. });
            if !custom && (locked || couplers.contains_key(cs.name())) {
                return Err(ModelError::Invalid(format!(
                    "coordinate {:?} of joint {:?}: only custom joints may have locked or \
                     coupled coordinates",
                    cs.name(),
                    js.name
                )));
            }
            known.insert(cs.name(), (locked, default));
        }
    }
    let mut roles = HashMap::new();
    let mut next = 0;
    for &j in order {
        for cs in &spec.joints[j].coordinates {
            let name = cs.name();
            let (locked, default) = known[name];
            if locked {
                roles.insert(name.to_string(), Role::Locked(default));
            } else if !couplers.contains_key(name) {
                roles.insert(name.to_string(), Role::Free(next));
                next += 1;
            }
        }
    }
    for c in &spec.couplers {
        if !known.contains_key(c.dependent.as_str()) {
            return Err(ModelError::Invalid(format!(
                "coupler {:?}: dependent coordinate {:?} is not defined",
                c.name, c.dependent
            )));
        }
        let (_, g) = &couplers[c.dependent.as_str()];
        let role = match roles.get(&c.independent) {
            Some(Role::Free(i)) => Role::Coupled {
                independent: *i,
                g: g.clone(),
            },
            Some(Role::Locked(v)) => Role::Locked(g.eval(*v).0),
            _ => {
                return Err(ModelError::Invalid(format!(
                    "coupler {:?}: independent coordinate {:?} is {}",
                    c.name,
                    c.independent,
                    if known.contains_key(c.independent.as_str()) {
                        "itself coupled (chains of couplers are not supported)"
                    } else {
                        "not defined"
                    }
                )))
            }
        };
        // A locked dependent stays locked at its own default, as OpenSim holds it.
        if !matches!(roles.get(&c.dependent), Some(Role::Locked(_))) {
            roles.insert(c.dependent.clone(), role);
        }
    }
    Ok(roles)
}

/// Compiles a custom joint's axes (`what` names the joint in errors).
pub(crate) fn compile_axes(
    axes: &[super::spec::TransformAxisSpec],
    joint: &str,
) -> Result<Vec<TransformAxis>, ModelError> {
    axes.iter()
        .enumerate()
        .map(|(k, a)| {
            let what = format!("joint {joint:?} transform axis {}", k + 1);
            let function = Function::try_from(&a.function)
                .map_err(|e| ModelError::Invalid(format!("{what}: {e}")))?;
            Ok(TransformAxis {
                rotation: a.motion == AxisMotion::Rotation,
                axis: super::validate::parse_axis(&a.axis, &what)?,
                coordinate: a.coordinate.clone(),
                function,
            })
        })
        .collect()
}

/// The elementary steps of a custom joint's motion.
pub(crate) fn axis_steps(
    axes: &[TransformAxis],
    joint: &super::spec::JointSpec,
    roles: &HashMap<String, Role>,
    functions: &mut Vec<AxisFn>,
    steps: &mut Vec<super::compiled::Step>,
) -> Result<(), ModelError> {
    use super::compile::motion_for;
    use super::compiled::{Source, Step};
    for (k, a) in axes.iter().enumerate() {
        let (motion, sign) = motion_for(a.rotation, &a.axis);
        let source = match (&a.coordinate, a.function.constant()) {
            (None, Some(c)) => Source::Const(sign * c),
            (None, None) => {
                return Err(ModelError::Invalid(format!(
                    "joint {:?} transform axis {}: a non-constant function needs a coordinate",
                    joint.name,
                    k + 1
                )))
            }
            (Some(name), _) => {
                if !joint.coordinates.iter().any(|c| c.name() == name) {
                    return Err(ModelError::Invalid(format!(
                        "joint {:?} transform axis {}: coordinate {name:?} is not a coordinate \
                         of this joint",
                        joint.name,
                        k + 1
                    )));
                }
                match &roles[name] {
                    Role::Locked(v) => Source::Const(sign * a.function.eval(*v).0),
                    Role::Free(i) => match a.function.slope_through_origin() {
                        Some(slope) => Source::Coord {
                            index: *i,
                            scale: sign * slope,
                        },
                        None => func_source(functions, *i, a.function.clone(), None, sign),
                    },
                    Role::Coupled { independent, g } => func_source(
                        functions,
                        *independent,
                        a.function.clone(),
                        Some(g.clone()),
                        sign,
                    ),
                }
            }
        };
        steps.push(Step { motion, source });
    }
    Ok(())
}

fn func_source(
    functions: &mut Vec<AxisFn>,
    index: usize,
    outer: Function,
    inner: Option<Function>,
    scale: f64,
) -> super::compiled::Source {
    functions.push(AxisFn { outer, inner });
    super::compiled::Source::Func {
        index,
        fun: functions.len() - 1,
        scale,
    }
}
