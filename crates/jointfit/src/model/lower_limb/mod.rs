//! The paper's sample model: one leg, 12 coordinates, 27 joint parameters; and both legs
//! with the pelvis, 18 coordinates and 54 parameters ([`bilateral`]).
//!
//! Reinbolt et al. 2005 (J Biomech 38:621–626), Figs. 1–3 and Table 2; `docs/architecture.md`
//! §6.
//!
//! | joint | kind | coordinates | parameters |
//! |---|---|---|---|
//! | ground–pelvis | free | tx, ty, tz, tilt (z), list (x), rotation (y) | – |
//! | hip | gimbal z-x-y | flexion, adduction, internal rotation | 6 positions |
//! | knee | pin about −z | flexion | 4 orientations, 5 positions |
//! | talocrural | pin about z | dorsiflexion | 2 orientations, 3 positions |
//! | subtalar | pin about x | inversion | 3 orientations, 4 positions |
//!
//! Frames: x anterior, y superior, z to the right. Offsets use `T(t)·Rx·Ry·Rz`; a pin about
//! z tilted by `rx` (frontal plane) and `ry` (transverse plane) gives the axis direction
//! `(sin ry, −sin rx cos ry, cos rx cos ry)`. The subtalar pin acts about the joint frame's x
//! axis: in the talus it is turned medially by `ry` (transverse); in the foot it is turned
//! medially by `ry` and elevated by `rz` (sagittal), Inman's 23° and 42°.
//!
//! The left leg is the mirror image through the sagittal plane (z ↦ −z) with z still to the
//! right: every parameter keeps its anatomical meaning ("lateral" is −z; positive frontal and
//! transverse angles mean the same anatomical tilt), so those scalars read `−p`, and the
//! rotation axes about x and y flip so that flexion, adduction, internal rotation, dorsiflexion
//! and inversion are positive on both sides.
//!
//! Nominal geometry is generic: the anatomical-landmark column of the paper's Table 2 for the
//! joints and typical adult marker placements. A subject's own values come from a static
//! trial (the landmark method).

use std::f64::consts::PI;

pub mod bilateral;
mod params;

use params::{nominal, par, param_spec, PARAMS};

use super::offset_rotation;
use super::spec::{
    AxisSpec, CoordinateSpec, JointKindSpec, JointSpec, MarkerSpec, ModelSpec, OffsetSpec,
    ScalarSpec, SegmentSpec,
};
use super::ModelError;

/// Which leg.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Right,
    Left,
}

impl Side {
    /// +1 for the right leg, −1 for the left: the sign of "lateral" along z.
    pub fn sign(self) -> f64 {
        match self {
            Side::Right => 1.0,
            Side::Left => -1.0,
        }
    }
    /// Suffix of this leg's names in the bilateral model: `_r` or `_l`.
    pub(crate) fn suffix(self) -> &'static str {
        match self {
            Side::Right => "_r",
            Side::Left => "_l",
        }
    }
    /// Marker-name prefix of the built-in markers: `R` or `L`.
    pub(crate) fn prefix(self) -> &'static str {
        match self {
            Side::Right => "R",
            Side::Left => "L",
        }
    }
}

/// `right` or `left`.
impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Side::Right => "right",
            Side::Left => "left",
        })
    }
}

/// Names of the built-in models: both legs ([`bilateral`]), then each leg alone.
pub const BUILTIN_NAMES: [&str; 3] = ["lower-limb", "lower-limb-right", "lower-limb-left"];

/// A built-in model description by name.
pub fn builtin(name: &str) -> Result<ModelSpec, ModelError> {
    match name {
        "lower-limb" => Ok(bilateral::bilateral()),
        "lower-limb-right" => Ok(lower_limb(Side::Right)),
        "lower-limb-left" => Ok(lower_limb(Side::Left)),
        _ => Err(ModelError::UnknownBuiltin {
            name: name.to_string(),
            available: BUILTIN_NAMES.join(", "),
        }),
    }
}

const DEG: f64 = PI / 180.0;

fn coord(name: &str, lo_deg: f64, hi_deg: f64) -> CoordinateSpec {
    CoordinateSpec::Full {
        name: name.to_string(),
        range: Some([lo_deg * DEG, hi_deg * DEG]),
        default: 0.0,
        locked: false,
        clamped: false,
    }
}

fn joint(
    name: &str,
    parent: &str,
    child: &str,
    kind: JointKindSpec,
    coordinates: Vec<CoordinateSpec>,
    parent_offset: OffsetSpec,
    child_offset: OffsetSpec,
) -> JointSpec {
    JointSpec {
        name: name.to_string(),
        parent: parent.to_string(),
        child: child.to_string(),
        kind,
        coordinates,
        parent_offset,
        child_offset,
    }
}

/// The fixed rotation about the talocrural axis between the talocrural joint frame and the
/// talus frame that makes the foot's long axis (x) horizontal in the pelvis (and world) frame
/// at q = 0 with nominal parameters, so that standing upright reads 0° of dorsiflexion.
fn talus_levelling_angle() -> f64 {
    let rot = |a: &str, b: &str, c: &str| {
        let v = |n: &str| if n.is_empty() { 0.0 } else { nominal(n) };
        offset_rotation(v(a), v(b), v(c))
    };
    // At q = 0 the thigh is aligned with the pelvis; the shank is turned by the knee offsets.
    let thigh_from_shank = rot("knee_thigh_frontal", "knee_thigh_transverse", "")
        * rot("knee_shank_frontal", "knee_shank_transverse", "").transpose();
    let shank_from_j1 = rot(
        "talocrural_shank_frontal",
        "talocrural_shank_transverse",
        "",
    );
    let talus_from_j2 = rot("", "subtalar_talus_transverse", "");
    let foot_from_j2 = rot("", "subtalar_foot_transverse", "subtalar_foot_sagittal");
    // thigh_from_foot = thigh_from_shank · shank_from_j1 · Rz(−c) · talus_from_j2 ·
    // foot_from_j2ᵀ; its x column must have no superior (y) component. Bisection on a
    // bracket with a sign change.
    let f = |c: f64| {
        let r = thigh_from_shank
            * shank_from_j1
            * offset_rotation(0.0, 0.0, -c)
            * talus_from_j2
            * foot_from_j2.transpose();
        r[(1, 0)]
    };
    let (mut lo, mut hi) = (-PI / 2.0, PI / 2.0);
    assert!(f(lo) * f(hi) < 0.0, "levelling angle bracket");
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(lo) * f(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The 27-parameter, 12-coordinate leg model for one side.
pub fn lower_limb(side: Side) -> ModelSpec {
    let segments = ["pelvis", "thigh", "shank", "talus", "foot"]
        .iter()
        .map(|n| SegmentSpec {
            name: n.to_string(),
            description: String::new(),
        })
        .collect();
    let side_name = match side {
        Side::Right => "right",
        Side::Left => "left",
    };
    ModelSpec {
        name: format!("lower-limb-{side_name}"),
        description: format!(
            "Reinbolt et al. 2005 sample model, {side_name} leg: 12 coordinates, 27 joint \
             parameters (hip 6, knee 9, ankle 12); generic adult nominal geometry"
        ),
        segments,
        joints: vec![
            pelvis_joint(),
            hip_joint(side),
            knee_joint(side),
            talocrural_joint(side),
            subtalar_joint(side),
        ],
        parameters: PARAMS.iter().map(param_spec).collect(),
        markers: markers(side),
        couplers: vec![],
        lab_up: None,
    }
}

/// An axis of the right leg, mirrored (negated) for the left.
fn flip(side: Side, a: &str) -> AxisSpec {
    if side == Side::Right {
        AxisSpec::named(a)
    } else {
        AxisSpec::named(&format!("-{a}"))
    }
}

/// The pelvis in the world: a free joint, 3 translations and 3 rotations.
fn pelvis_joint() -> JointSpec {
    let named = |a: &str| AxisSpec::named(a);
    joint(
        "ground_pelvis",
        "ground",
        "pelvis",
        JointKindSpec::Free {
            rotation_axes: [named("z"), named("x"), named("y")],
        },
        vec![
            CoordinateSpec::Full {
                name: "pelvis_tx".into(),
                range: Some([-5.0, 5.0]),
                default: 0.0,
                locked: false,
                clamped: false,
            },
            CoordinateSpec::Full {
                name: "pelvis_ty".into(),
                range: Some([-1.0, 3.0]),
                default: 0.95,
                locked: false,
                clamped: false,
            },
            CoordinateSpec::Full {
                name: "pelvis_tz".into(),
                range: Some([-5.0, 5.0]),
                default: 0.0,
                locked: false,
                clamped: false,
            },
            coord("pelvis_tilt", -90.0, 90.0),
            coord("pelvis_list", -90.0, 90.0),
            coord("pelvis_rotation", -180.0, 180.0),
        ],
        OffsetSpec::default(),
        OffsetSpec::default(),
    )
}

/// The hip: a gimbal (flexion, adduction, rotation) with the hip centre in pelvis and thigh.
fn hip_joint(side: Side) -> JointSpec {
    let named = |a: &str| AxisSpec::named(a);
    let flip = |a: &str| flip(side, a);
    joint(
        "hip",
        "pelvis",
        "thigh",
        JointKindSpec::Gimbal {
            axes: [named("z"), flip("x"), flip("y")],
        },
        vec![
            coord("hip_flexion", -40.0, 130.0),
            coord("hip_adduction", -50.0, 40.0),
            coord("hip_rotation", -50.0, 50.0),
        ],
        OffsetSpec {
            tx: par("hip_pelvis_anterior", side),
            ty: par("hip_pelvis_superior", side),
            tz: par("hip_pelvis_lateral", side),
            ..OffsetSpec::default()
        },
        OffsetSpec {
            tx: par("hip_thigh_anterior", side),
            ty: par("hip_thigh_superior", side),
            tz: par("hip_thigh_lateral", side),
            ..OffsetSpec::default()
        },
    )
}

/// The knee: a pin, its axis placed and oriented in thigh and shank (9 parameters).
fn knee_joint(side: Side) -> JointSpec {
    let named = |a: &str| AxisSpec::named(a);
    joint(
        "knee",
        "thigh",
        "shank",
        JointKindSpec::Pin { axis: named("-z") },
        vec![coord("knee_flexion", -15.0, 150.0)],
        OffsetSpec {
            tx: par("knee_thigh_anterior", side),
            ty: par("knee_thigh_superior", side),
            rx: par("knee_thigh_frontal", side),
            ry: par("knee_thigh_transverse", side),
            ..OffsetSpec::default()
        },
        OffsetSpec {
            tx: par("knee_shank_anterior", side),
            ty: par("knee_shank_superior", side),
            tz: par("knee_shank_lateral", side),
            rx: par("knee_shank_frontal", side),
            ry: par("knee_shank_transverse", side),
            ..OffsetSpec::default()
        },
    )
}

/// The talocrural joint: a pin placed and oriented in the shank, the talus levelled.
fn talocrural_joint(side: Side) -> JointSpec {
    let named = |a: &str| AxisSpec::named(a);
    joint(
        "talocrural",
        "shank",
        "talus",
        JointKindSpec::Pin { axis: named("z") },
        vec![coord("ankle_dorsiflexion", -60.0, 45.0)],
        OffsetSpec {
            tx: par("talocrural_shank_anterior", side),
            ty: par("talocrural_shank_superior", side),
            tz: par("talocrural_shank_lateral", side),
            rx: par("talocrural_shank_frontal", side),
            ry: par("talocrural_shank_transverse", side),
            ..OffsetSpec::default()
        },
        OffsetSpec {
            rz: ScalarSpec::Fixed(talus_levelling_angle()),
            ..OffsetSpec::default()
        },
    )
}

/// The subtalar joint: a pin placed and oriented in talus and foot.
fn subtalar_joint(side: Side) -> JointSpec {
    let flip = |a: &str| flip(side, a);
    joint(
        "subtalar",
        "talus",
        "foot",
        JointKindSpec::Pin { axis: flip("x") },
        vec![coord("subtalar_inversion", -40.0, 40.0)],
        OffsetSpec {
            ty: par("subtalar_talus_superior", side),
            ry: par("subtalar_talus_transverse", side),
            ..OffsetSpec::default()
        },
        OffsetSpec {
            tx: par("subtalar_foot_anterior", side),
            ty: par("subtalar_foot_superior", side),
            tz: par("subtalar_foot_lateral", side),
            ry: par("subtalar_foot_transverse", side),
            rz: par("subtalar_foot_sagittal", side),
            ..OffsetSpec::default()
        },
    )
}

/// The generic marker placements (m, segment frames, right side; z mirrored for the left).
fn markers(side: Side) -> Vec<MarkerSpec> {
    let s = side.sign();
    let r = side.prefix();
    let mk = |name: String, segment: &str, x: f64, y: f64, z: f64| MarkerSpec {
        name,
        segment: segment.to_string(),
        position: [x, y, s * z],
        weight: 1.0,
    };
    let leg = |n: &str| format!("{r}{n}");
    vec![
        MarkerSpec {
            name: "RASI".into(),
            segment: "pelvis".into(),
            position: [0.0, 0.0, 0.12],
            weight: 1.0,
        },
        MarkerSpec {
            name: "LASI".into(),
            segment: "pelvis".into(),
            position: [0.0, 0.0, -0.12],
            weight: 1.0,
        },
        MarkerSpec {
            name: "RPSI".into(),
            segment: "pelvis".into(),
            position: [-0.155, 0.03, 0.045],
            weight: 1.0,
        },
        MarkerSpec {
            name: "LPSI".into(),
            segment: "pelvis".into(),
            position: [-0.155, 0.03, -0.045],
            weight: 1.0,
        },
        mk(leg("THI"), "thigh", 0.01, -0.22, 0.085),
        mk(leg("THA"), "thigh", 0.07, -0.18, 0.03),
        mk(leg("THP"), "thigh", -0.04, -0.30, 0.06),
        mk(leg("KNE"), "thigh", 0.0, -0.392, 0.05),
        mk(leg("TIB"), "shank", 0.01, -0.20, 0.06),
        mk(leg("TIA"), "shank", 0.05, -0.12, 0.01),
        mk(leg("TIP"), "shank", -0.03, -0.28, 0.045),
        mk(leg("ANK"), "shank", 0.0, -0.411, 0.035),
        mk(leg("HEE"), "foot", 0.0, 0.0, 0.0),
        mk(leg("TOE"), "foot", 0.18, 0.01, -0.01),
        mk(leg("MT5"), "foot", 0.14, -0.005, 0.04),
    ]
}
