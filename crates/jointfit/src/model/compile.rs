//! Compilation of a validated description into a [`Model`]: each joint becomes its chain of
//! elementary steps `T(t_p) Rx Ry Rz · motion(q) · Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t_c)` (see
//! [`super::compiled`]), runs of constant steps are merged, and the forward-kinematics plan is
//! built.

use std::collections::HashMap;

use nalgebra::{Unit as UnitVec, Vector3};

use super::compiled::{
    CoordKind, Coordinate, Joint, JointId, JointKind, Marker, Model, ParamUse, Parameter, Segment,
    SegmentId, Source, Step,
};
use super::custom::{CoordRule, DependentCoordinate, MotionType, Role};
use super::spec::{CoordinateSpec, OffsetSpec, Unit, OFFSET_SCALARS};
use super::validate::{check_name, joint_kind, Compiler};
use super::ModelError;
use crate::spatial::{Motion, Pose};

impl Compiler<'_> {
    /// Compiles the description; the names were validated by [`Compiler::new`].
    pub(super) fn run(self) -> Result<Model, ModelError> {
        let spec = self.spec;
        let order = self.topological_joints()?;
        let roles = super::custom::roles(spec, &order)?;
        let mut dependents = Vec::new();
        let mut functions = Vec::new();
        // Segment i of the model is the child of the i-th joint in topological order.
        let new_seg_of: HashMap<&str, usize> = order
            .iter()
            .enumerate()
            .map(|(i, &j)| (spec.joints[j].child.as_str(), i))
            .collect();
        let seg_id = |name: &str| -> Option<SegmentId> {
            if name == "ground" {
                None
            } else {
                Some(SegmentId(new_seg_of[name]))
            }
        };

        let mut segments = Vec::new();
        let mut joints = Vec::new();
        let mut coordinates: Vec<Coordinate> = Vec::new();
        let mut steps: Vec<Step> = Vec::new();
        let mut step_ranges = Vec::new();
        let mut uses: Vec<Vec<ParamUse>> = vec![Vec::new(); spec.parameters.len()];
        let mut coord_names = HashMap::new();

        for (ji, &j) in order.iter().enumerate() {
            let js = &spec.joints[j];
            let mut kind = joint_kind(&js.kind, &js.name)?;
            let custom = matches!(kind, JointKind::Custom { .. });
            if !custom && js.coordinates.len() != kind.dof() {
                return Err(ModelError::Invalid(format!(
                    "joint {:?} is {} with {} degrees of freedom but lists {} coordinates",
                    js.name,
                    kind.type_name(),
                    kind.dof(),
                    js.coordinates.len()
                )));
            }
            let parent = seg_id(&js.parent);
            let child = SegmentId(ji);
            segments.push(Segment {
                name: js.child.clone(),
                parent,
                joint: JointId(ji),
            });
            let first_coord = coordinates.len();
            let start = steps.len();

            // Parent offset: T(t) Rx Ry Rz.
            self.offset_steps(
                &js.parent_offset,
                false,
                &js.name,
                parent,
                JointId(ji),
                &mut steps,
                &mut uses,
            )?;
            // Joint motion.
            let motions = kind.motions();
            for (k, cs) in js.coordinates.iter().enumerate() {
                let name = cs.name();
                check_name(name, "coordinate")?;
                if coord_names.insert(name.to_string(), ()).is_some() {
                    return Err(ModelError::Duplicate {
                        kind: "coordinate",
                        name: name.to_string(),
                    });
                }
                let ckind = super::custom::custom_coord_kind(&js.kind, name).unwrap_or_else(|| {
                    if motions[k].0 {
                        CoordKind::Rotational
                    } else {
                        CoordKind::Translational
                    }
                });
                let motion = super::custom::opensim_motion(&js.kind, name).unwrap_or(match ckind {
                    CoordKind::Rotational => MotionType::Rotational,
                    CoordKind::Translational => MotionType::Translational,
                });
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
                if !(range[0].is_finite()
                    && range[1].is_finite()
                    && range[0] < range[1]
                    && default.is_finite())
                {
                    return Err(ModelError::Invalid(format!(
                        "coordinate {name:?}: range {range:?} / default {default} invalid"
                    )));
                }
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
                        dependents.push(DependentCoordinate {
                            name: name.to_string(),
                            joint: JointId(ji),
                            kind: ckind,
                            motion,
                            range,
                            default,
                            rule,
                        });
                        continue;
                    }
                };
                debug_assert_eq!(index, coordinates.len());
                coordinates.push(Coordinate {
                    name: name.to_string(),
                    joint: JointId(ji),
                    kind: ckind,
                    motion,
                    range,
                    clamped,
                    default,
                });
                if !custom {
                    let (motion, sign) = motion_for(motions[k].0, &motions[k].1);
                    steps.push(Step {
                        motion,
                        source: Source::Coord { index, scale: sign },
                    });
                }
            }
            if let JointKind::Custom { axes, dof } = &mut kind {
                *dof = coordinates.len() - first_coord;
                super::custom::axis_steps(axes, js, &roles, &mut functions, &mut steps)?;
            }
            // Child offset, inverted: Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t).
            self.offset_steps(
                &js.child_offset,
                true,
                &js.name,
                Some(child),
                JointId(ji),
                &mut steps,
                &mut uses,
            )?;
            joints.push(Joint {
                name: js.name.clone(),
                parent,
                child,
                kind,
                first_coord,
            });
            let merged = merge_constants(steps.split_off(start));
            steps.extend(merged);
            step_ranges.push(start..steps.len());
        }

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

    #[allow(clippy::too_many_arguments)]
    fn offset_steps(
        &self,
        offset: &OffsetSpec,
        inverse: bool,
        joint: &str,
        segment: Option<SegmentId>,
        joint_id: JointId,
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
