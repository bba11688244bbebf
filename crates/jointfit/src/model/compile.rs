//! Compilation of a validated description into a [`Model`]: each joint becomes its chain of
//! elementary steps `T(t_p) Rx Ry Rz · motion(q) · Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t_c)` (see
//! [`super::compiled`]), runs of constant steps are merged, and the forward-kinematics plan is
//! built.

use std::collections::HashMap;

use nalgebra::{Unit as UnitVec, Vector3};

use super::compiled::{
    CoordKind, Coordinate, Joint, JointKind, Marker, Model, ParamUse, Parameter, Segment,
    SegmentId, Source, Step,
};
use super::custom::{CoordRule, DependentCoordinate, MotionType, Role};
use super::spec::{CoordinateSpec, OffsetSpec, Unit, OFFSET_SCALARS};
use super::validate::{check_name, joint_kind, Compiler};
use super::ModelError;
use crate::spatial::{Motion, Pose};

/// What the joints' chains build up, joint after joint in topological order.
#[derive(Default)]
struct Chains {
    segments: Vec<Segment>,
    joints: Vec<Joint>,
    coordinates: Vec<Coordinate>,
    dependents: Vec<DependentCoordinate>,
    functions: Vec<super::custom::AxisFn>,
    steps: Vec<Step>,
    step_ranges: Vec<std::ops::Range<usize>>,
    /// Per parameter of the description, the steps that read it.
    uses: Vec<Vec<ParamUse>>,
    coord_names: HashMap<String, ()>,
}

/// Segment i of the model is the child of the i-th joint in topological order (`None`: ground).
fn seg_id(new_seg_of: &HashMap<&str, usize>, name: &str) -> Option<SegmentId> {
    if name == "ground" {
        None
    } else {
        Some(SegmentId(new_seg_of[name]))
    }
}

impl Compiler<'_> {
    /// Compiles the description; the names were validated by [`Compiler::new`].
    pub(super) fn run(self) -> Result<Model, ModelError> {
        let spec = self.spec;
        let order = self.topological_joints()?;
        let roles = super::custom::roles(spec, &order)?;
        let new_seg_of: HashMap<&str, usize> = order
            .iter()
            .enumerate()
            .map(|(i, &j)| (spec.joints[j].child.as_str(), i))
            .collect();
        let mut chains = Chains {
            uses: vec![Vec::new(); spec.parameters.len()],
            ..Chains::default()
        };
        for (ji, &j) in order.iter().enumerate() {
            self.joint_chain(ji, j, &roles, &new_seg_of, &mut chains)?;
        }
        let parameters = self.parameters(std::mem::take(&mut chains.uses))?;
        let markers = self.markers(&new_seg_of)?;
        let Chains {
            segments,
            joints,
            coordinates,
            dependents,
            functions,
            steps,
            step_ranges,
            ..
        } = chains;
        let plan = super::plan::Plan::new(
            &steps,
            &step_ranges,
            &segments
                .iter()
                .map(|s| s.parent.map(|p| p.0))
                .collect::<Vec<_>>(),
            &markers.iter().map(|m| m.segment.0).collect::<Vec<_>>(),
        );
        Ok(Model {
            name: spec.name.clone(),
            description: spec.description.clone(),
            segments,
            joints,
            coordinates,
            parameters,
            markers,
            dependents,
            functions,
            steps,
            plan,
            spec: spec.clone(),
        })
    }

    /// Joint `j` of the description, the `ji`-th in topological order: its child segment,
    /// its coordinates and its chain `T(t_p) Rx Ry Rz · motion(q) · Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t_c)`
    /// with runs of constant steps merged.
    fn joint_chain(
        &self,
        ji: usize,
        j: usize,
        roles: &HashMap<String, Role>,
        new_seg_of: &HashMap<&str, usize>,
        c: &mut Chains,
    ) -> Result<(), ModelError> {
        let js = &self.spec.joints[j];
        let mut kind = joint_kind(&js.kind, &js.name)?;
        let custom = matches!(kind, JointKind::Custom { .. });
        if !custom && js.coordinates.len() != kind.dof() {
            return Err(ModelError::Invalid(format!(
                "joint {:?} is {} with {} degrees of freedom but lists {} coordinates",
                js.name,
                kind,
                kind.dof(),
                js.coordinates.len()
            )));
        }
        let parent = seg_id(new_seg_of, &js.parent);
        let child = SegmentId(ji);
        c.segments.push(Segment {
            name: js.child.clone(),
            parent,
        });
        let first_coord = c.coordinates.len();
        let start = c.steps.len();
        // Parent offset: T(t) Rx Ry Rz.
        let (id, offset) = (ji, &js.parent_offset);
        self.offset_steps(
            offset,
            false,
            &js.name,
            parent,
            id,
            &mut c.steps,
            &mut c.uses,
        )?;
        // Joint motion.
        let motions = kind.motions();
        for (k, cs) in js.coordinates.iter().enumerate() {
            coordinate(js, id, cs, motions.get(k), custom, roles, c)?;
        }
        if let JointKind::Custom { axes, dof } = &mut kind {
            *dof = c.coordinates.len() - first_coord;
            super::custom::axis_steps(axes, js, roles, &mut c.functions, &mut c.steps)?;
        }
        // Child offset, inverted: Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t).
        let offset = &js.child_offset;
        self.offset_steps(
            offset,
            true,
            &js.name,
            Some(child),
            id,
            &mut c.steps,
            &mut c.uses,
        )?;
        c.joints.push(Joint {
            name: js.name.clone(),
            parent,
            child,
            coords: first_coord..first_coord + kind.dof(),
            kind,
        });
        let merged = merge_constants(c.steps.split_off(start));
        c.steps.extend(merged);
        c.step_ranges.push(start..c.steps.len());
        Ok(())
    }

    /// The parameters with the steps that read them (each must be read by some offset).
    fn parameters(&self, uses: Vec<Vec<ParamUse>>) -> Result<Vec<Parameter>, ModelError> {
        let spec = self.spec;
        let mut parameters = Vec::with_capacity(spec.parameters.len());
        for (ps, u) in spec.parameters.iter().zip(uses) {
            if u.is_empty() {
                return Err(ModelError::Invalid(format!(
                    "parameter {:?} is not used by any joint offset",
                    ps.name
                )));
            }
            parameters.push(Parameter {
                name: ps.name.clone(),
                group: ps.group.clone(),
                unit: ps.unit,
                nominal: ps.nominal,
                lower: ps.lower,
                upper: ps.upper,
                description: ps.description.clone(),
                prior_sd: ps.prior_sd,
                prior_mean: ps.prior_mean.unwrap_or(ps.nominal),
                uses: u,
            });
        }
        Ok(parameters)
    }

    /// The markers, each on a segment of the model with a finite position and weight ≥ 0.
    fn markers(&self, new_seg_of: &HashMap<&str, usize>) -> Result<Vec<Marker>, ModelError> {
        let spec = self.spec;
        let mut markers = Vec::with_capacity(spec.markers.len());
        let mut marker_names = HashMap::new();
        for m in &spec.markers {
            check_name(&m.name, "marker")?;
            if marker_names.insert(m.name.as_str(), ()).is_some() {
                return Err(ModelError::Duplicate {
                    kind: "marker",
                    name: m.name.clone(),
                });
            }
            if m.segment == "ground" || !new_seg_of.contains_key(m.segment.as_str()) {
                return Err(ModelError::UnknownSegment {
                    segment: m.segment.clone(),
                    used_by: format!("marker {:?}", m.name),
                });
            }
            if m.position.iter().any(|v| !v.is_finite())
                || !(m.weight.is_finite() && m.weight >= 0.0)
            {
                return Err(ModelError::Invalid(format!(
                    "marker {:?}: position and weight must be finite, weight ≥ 0",
                    m.name
                )));
            }
            markers.push(Marker {
                name: m.name.clone(),
                segment: SegmentId(new_seg_of[m.segment.as_str()]),
                local: Vector3::from(m.position),
                weight: m.weight,
            });
        }
        Ok(markers)
    }

    #[allow(clippy::too_many_arguments)]
    fn offset_steps(
        &self,
        offset: &OffsetSpec,
        inverse: bool,
        joint: &str,
        segment: Option<SegmentId>,
        joint_id: usize,
        steps: &mut Vec<Step>,
        uses: &mut [Vec<ParamUse>],
    ) -> Result<(), ModelError> {
        let scalars = offset.scalars();
        let which = if inverse {
            "child_offset"
        } else {
            "parent_offset"
        };
        // Forward order tx ty tz rx ry rz; inverse order rz ry rx tx ty tz with negated values.
        let order: [usize; 6] = if inverse {
            [5, 4, 3, 0, 1, 2]
        } else {
            [0, 1, 2, 3, 4, 5]
        };
        let sign = if inverse { -1.0 } else { 1.0 };
        for k in order {
            let unit = if k < 3 { Unit::Metre } else { Unit::Radian };
            let what = format!("joint {joint:?} {which}.{}", OFFSET_SCALARS[k]);
            let source = self.scalar_source(scalars[k], sign, unit, &what)?;
            if let Source::Param { index, scale } = source {
                uses[index].push(ParamUse {
                    joint: joint_id,
                    segment,
                    in_parent_offset: !inverse,
                    scalar: OFFSET_SCALARS[k],
                    scale: scale * sign,
                });
            }
            if source != Source::Const(0.0) {
                steps.push(Step {
                    motion: offset_motion(k),
                    source,
                });
            }
        }
        Ok(())
    }
}

/// One coordinate of joint `js` (`axis`: its motion, rotation or not, and its axis): a
/// coordinate of `q` with its step (none for a `custom` joint, whose axes come later), or a
/// dependent coordinate (locked or coupled, [`Role`]).
fn coordinate(
    js: &super::spec::JointSpec,
    joint: usize,
    cs: &CoordinateSpec,
    axis: Option<&(bool, Vector3<f64>)>,
    custom: bool,
    roles: &HashMap<String, Role>,
    c: &mut Chains,
) -> Result<(), ModelError> {
    let axis = || axis.expect("a joint's motions cover its coordinates");
    let name = cs.name();
    check_name(name, "coordinate")?;
    if c.coord_names.insert(name.to_string(), ()).is_some() {
        return Err(ModelError::Duplicate {
            kind: "coordinate",
            name: name.to_string(),
        });
    }
    let ckind = super::custom::custom_coord_kind(&js.kind, name).unwrap_or_else(|| {
        if axis().0 {
            CoordKind::Rotational
        } else {
            CoordKind::Translational
        }
    });
    let motion = super::custom::opensim_motion(&js.kind, name).unwrap_or(match ckind {
        CoordKind::Rotational => MotionType::Rotational,
        CoordKind::Translational => MotionType::Translational,
    });
    let (range, default, clamped) = coordinate_range(cs, ckind)?;
    let index = match &roles[name] {
        Role::Free(i) => *i,
        other => {
            let rule = match other {
                Role::Locked(v) => CoordRule::Locked(*v),
                Role::Coupled { independent, g } => CoordRule::Coupled {
                    independent: *independent,
                    function: g.clone(),
                },
                Role::Free(_) => unreachable!("handled above"),
            };
            c.dependents.push(DependentCoordinate {
                name: name.to_string(),
                joint,
                kind: ckind,
                motion,
                range,
                default,
                rule,
            });
            return Ok(());
        }
    };
    debug_assert_eq!(index, c.coordinates.len());
    c.coordinates.push(Coordinate {
        name: name.to_string(),
        joint,
        kind: ckind,
        motion,
        range,
        clamped,
        default,
    });
    if !custom {
        let (rotation, axis) = axis();
        let (motion, sign) = motion_for(*rotation, axis);
        c.steps.push(Step {
            motion,
            source: Source::Coord { index, scale: sign },
        });
    }
    Ok(())
}

/// A coordinate's range (±π or ±10 m when not given), default and clamping, checked.
fn coordinate_range(
    cs: &CoordinateSpec,
    ckind: CoordKind,
) -> Result<([f64; 2], f64, bool), ModelError> {
    let (range, default, clamped) = match cs {
        CoordinateSpec::Name(_) => (None, 0.0, false),
        CoordinateSpec::Full {
            range,
            default,
            clamped,
            ..
        } => (*range, *default, *clamped),
    };
    let range = range.unwrap_or(match ckind {
        CoordKind::Rotational => [-std::f64::consts::PI, std::f64::consts::PI],
        CoordKind::Translational => [-10.0, 10.0],
    });
    if !(range[0].is_finite() && range[1].is_finite() && range[0] < range[1] && default.is_finite())
    {
        return Err(ModelError::Invalid(format!(
            "coordinate {:?}: range {range:?} / default {default} invalid",
            cs.name()
        )));
    }
    Ok((range, default, clamped))
}

/// The elementary motion for a unit axis; principal axes get the fast specialised form and a
/// negative principal axis flips the sign of the scalar instead.
pub(crate) fn motion_for(rotation: bool, axis: &Vector3<f64>) -> (Motion, f64) {
    let principal = [
        (Vector3::x(), Motion::RotX, Motion::TransX),
        (Vector3::y(), Motion::RotY, Motion::TransY),
        (Vector3::z(), Motion::RotZ, Motion::TransZ),
    ];
    for (a, r, t) in principal {
        for sign in [1.0f64, -1.0] {
            if (axis - a * sign).norm() < 1e-15 {
                return (if rotation { r } else { t }, sign);
            }
        }
    }
    let u = UnitVec::new_normalize(*axis);
    (
        if rotation {
            Motion::Rot(u)
        } else {
            Motion::Trans(u)
        },
        1.0,
    )
}

fn offset_motion(k: usize) -> Motion {
    [
        Motion::TransX,
        Motion::TransY,
        Motion::TransZ,
        Motion::RotX,
        Motion::RotY,
        Motion::RotZ,
    ][k]
        .clone()
}

/// Replaces runs of constant steps by one fixed transform (dropped when it is the identity).
fn merge_constants(steps: Vec<Step>) -> Vec<Step> {
    let mut out: Vec<Step> = Vec::with_capacity(steps.len());
    let mut acc: Option<Pose> = None;
    let flush = |acc: &mut Option<Pose>, out: &mut Vec<Step>| {
        if let Some(p) = acc.take() {
            if !p.is_identity() {
                out.push(Step {
                    motion: Motion::Fixed(p),
                    source: Source::Const(0.0),
                });
            }
        }
    };
    for s in steps {
        match s.source {
            Source::Const(v) => {
                let mut p = acc.take().unwrap_or_else(Pose::identity);
                p.apply(&s.motion, v);
                acc = Some(p);
            }
            _ => {
                flush(&mut acc, &mut out);
                out.push(s);
            }
        }
    }
    flush(&mut acc, &mut out);
    out
}
