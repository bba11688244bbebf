//! The `.osim` that `osim_joint_types` checks against OpenSim, written as text: a chain of
//! every OpenSim joint type and CustomJoints with every supported coordinate function (see
//! that module's docs). Generated here, not copied from any model.

use std::fmt::Write as _;

/// `<Coordinate>` with a range, default and flags.
fn coord(name: &str, lo: f64, hi: f64, default: f64, locked: bool, clamped: bool) -> String {
    format!(
        "<Coordinate name=\"{name}\"><default_value>{default}</default_value>\
         <range>{lo} {hi}</range><clamped>{clamped}</clamped><locked>{locked}</locked>\
         </Coordinate>"
    )
}

/// A free coordinate of range ±`w` around 0.
fn free(name: &str, w: f64) -> String {
    coord(name, -w, w, 0.0, false, false)
}

/// A `PhysicalOffsetFrame` on `body` (translation, body-fixed XYZ orientation).
fn frame(name: &str, body: &str, t: [f64; 3], r: [f64; 3]) -> String {
    format!(
        "<PhysicalOffsetFrame name=\"{name}\"><socket_parent>{}</socket_parent>\
         <translation>{} {} {}</translation><orientation>{} {} {}</orientation>\
         </PhysicalOffsetFrame>",
        if body == "ground" {
            "/ground".to_string()
        } else {
            format!("/bodyset/{body}")
        },
        t[0],
        t[1],
        t[2],
        r[0],
        r[1],
        r[2]
    )
}

/// One joint element between offset frames on `parent` and `child`; `k` varies the offsets.
fn joint(
    tag: &str,
    name: &str,
    parent: &str,
    child: &str,
    coords: &str,
    inner: &str,
    k: f64,
) -> String {
    let pf = format!("{parent}_offset_{name}");
    let cf = format!("{child}_offset_{name}");
    format!(
        "<{tag} name=\"{name}\"><socket_parent_frame>{pf}</socket_parent_frame>\
         <socket_child_frame>{cf}</socket_child_frame><coordinates>{coords}</coordinates>\
         {inner}<frames>{}{}</frames></{tag}>\n",
        frame(
            &pf,
            parent,
            [0.05 * k, -0.12 - 0.01 * k, 0.03],
            [0.2, -0.1 * k, 0.35]
        ),
        frame(
            &cf,
            child,
            [-0.02, 0.04 * k, -0.015],
            [-0.15 * k, 0.25, 0.1]
        ),
    )
}

fn axis(name: &str, coords: &str, v: [f64; 3], function: &str) -> String {
    format!(
        "<TransformAxis name=\"{name}\"><coordinates>{coords}</coordinates>\
         <axis>{} {} {}</axis>{function}</TransformAxis>",
        v[0], v[1], v[2]
    )
}

fn xy(tag: &str, x: &[f64], y: &[f64], extra: &str) -> String {
    let j = |v: &[f64]| {
        v.iter()
            .map(|a| a.to_string())
            .collect::<Vec<_>>()
            .join(" ")
    };
    format!("<{tag}>{extra}<x>{}</x><y>{}</y></{tag}>", j(x), j(y))
}

const X: [f64; 7] = [-1.5, -0.9, -0.4, 0.0, 0.5, 1.1, 1.6];
const Y: [f64; 7] = [0.3, -0.2, 0.1, 0.0, 0.4, 0.2, -0.3];
const YT: [f64; 7] = [0.01, -0.02, 0.015, 0.0, 0.03, 0.01, -0.01];

fn simm(y: &[f64]) -> String {
    xy("SimmSpline", &X, y, "")
}

pub(super) fn linear(a: f64, b: f64) -> String {
    format!("<LinearFunction><coefficients>{a} {b}</coefficients></LinearFunction>")
}

fn constant(v: f64) -> String {
    format!("<Constant><value>{v}</value></Constant>")
}

fn multiplier(scale: f64, f: &str) -> String {
    format!(
        "<MultiplierFunction><function>{f}</function><scale>{scale}</scale></MultiplierFunction>"
    )
}

/// The bodies, in chain order, and the joint type that moves each (what its markers test).
pub(super) const BODIES: [(&str, &str); 12] = [
    ("pelvis", "FreeJoint"),
    ("ball_b", "BallJoint"),
    ("gimbal_b", "GimbalJoint"),
    ("univ_b", "UniversalJoint"),
    ("pin_b", "PinJoint"),
    ("slider_b", "SliderJoint"),
    ("planar_b", "PlanarJoint"),
    ("weld_b", "WeldJoint"),
    ("cust1", "CustomJoint: Linear, SimmSpline, NaturalCubicSpline, GCVSpline(5), PiecewiseLinear, Constant; oblique and non-unit axes"),
    ("cust2", "CustomJoint: Polynomial, Multiplier(SimmSpline), Multiplier(GCVSpline(3)), Constant rotation, Linear with intercept"),
    ("cust3", "CustomJoint: coupled (CoordinateCouplerConstraint), locked, clamped"),
    ("cust4", "CustomJoint: Multiplier(NaturalCubicSpline), Multiplier(PiecewiseLinear) on an oblique axis, marker on a loose offset frame"),
];

/// The generated model's text.
pub(super) fn model_text() -> String {
    let bodies = body_set();
    let joints = [
        standard_joints(),
        custom_joints_of_functions(),
        custom_joints_of_coordinate_kinds(),
    ]
    .concat();
    let markers = marker_set();
    let coupler = format!(
        "<CoordinateCouplerConstraint name=\"couple_dep\"><isEnforced>true</isEnforced>\
         <coupled_coordinates_function>{}</coupled_coordinates_function>\
         <independent_coordinate_names>c2_k</independent_coordinate_names>\
         <dependent_coordinate_name>c3_dep</dependent_coordinate_name>\
         <scale_factor>1.3</scale_factor></CoordinateCouplerConstraint>",
        simm(&Y)
    );
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40000\">\n\
         <Model name=\"all_joint_types\">\n<components>{}</components>\n\
         <Ground name=\"ground\" />\n<gravity>0 -9.80665 0</gravity>\n\
         <BodySet name=\"bodyset\"><objects>\n{bodies}</objects><groups /></BodySet>\n\
         <JointSet name=\"jointset\"><objects>\n{joints}</objects><groups /></JointSet>\n\
         <ConstraintSet name=\"constraintset\"><objects>{coupler}</objects><groups /></ConstraintSet>\n\
         <MarkerSet name=\"markerset\"><objects>\n{markers}</objects><groups /></MarkerSet>\n\
         </Model>\n</OpenSimDocument>\n",
        frame("cust4_tip", "cust4", [0.05, -0.2, 0.01], [0.3, 0.1, -0.4]),
    )
}

/// A body per entry of `BODIES`, with mass and inertia.
fn body_set() -> String {
    let mut bodies = String::new();
    for (b, _) in BODIES {
        writeln!(
            bodies,
            "<Body name=\"{b}\"><mass>2</mass><mass_center>0.01 -0.02 0.005</mass_center>\
             <inertia>0.1 0.12 0.09 0 0 0</inertia></Body>"
        )
        .unwrap();
    }
    bodies
}

/// One joint of each of OpenSim's fixed kinds, in a chain from the ground.
fn standard_joints() -> String {
    let j = joint;
    let mut joints = String::new();
    joints += &j(
        "FreeJoint",
        "free",
        "ground",
        "pelvis",
        &[
            free("f_rx", 1.2),
            free("f_ry", 1.2),
            free("f_rz", 1.2),
            free("f_tx", 1.0),
            free("f_ty", 1.0),
            free("f_tz", 1.0),
        ]
        .concat(),
        "",
        1.0,
    );
    joints += &j(
        "BallJoint",
        "ball",
        "pelvis",
        "ball_b",
        &[free("b_rx", 1.2), free("b_ry", 1.2), free("b_rz", 1.2)].concat(),
        "",
        2.0,
    );
    joints += &j(
        "GimbalJoint",
        "gimbal",
        "ball_b",
        "gimbal_b",
        &[free("g_rx", 1.2), free("g_ry", 1.2), free("g_rz", 1.2)].concat(),
        "",
        -1.0,
    );
    joints += &j(
        "UniversalJoint",
        "univ",
        "gimbal_b",
        "univ_b",
        &[free("u_rx", 1.2), free("u_ry", 1.2)].concat(),
        "",
        0.5,
    );
    joints += &j(
        "PinJoint",
        "pin",
        "univ_b",
        "pin_b",
        &coord("pin_q", -1.0, 1.5, 0.2, false, true),
        "",
        1.5,
    );
    joints += &j(
        "SliderJoint",
        "slider",
        "pin_b",
        "slider_b",
        &free("s_d", 0.2),
        "",
        -0.5,
    );
    joints += &j(
        "PlanarJoint",
        "planar",
        "slider_b",
        "planar_b",
        &[free("p_rz", 1.2), free("p_tx", 0.3), free("p_ty", 0.3)].concat(),
        "",
        0.8,
    );
    joints += &j("WeldJoint", "weld", "planar_b", "weld_b", "", "", -2.0);
    joints
}

/// A `SpatialTransform` of six axes.
fn spatial_transform(axes: [String; 6]) -> String {
    format!("<SpatialTransform>{}</SpatialTransform>", axes.concat())
}

/// Two custom joints whose axes follow every function kind (linear, SIMM spline, natural
/// cubic, GCV, piecewise linear, constant, polynomial, multiplier).
fn custom_joints_of_functions() -> String {
    let (j, st) = (joint, spatial_transform);
    let mut joints = String::new();
    joints += &j(
        "CustomJoint",
        "custom1",
        "pelvis",
        "cust1",
        &[free("c1_a", 2.0), free("c1_b", 2.0), free("c1_c", 2.0)].concat(),
        &st([
            axis("rotation1", "c1_a", [0.0, 0.0, 1.0], &linear(1.0, 0.0)),
            axis("rotation2", "c1_b", [0.3, 0.9, -0.2], &simm(&Y)),
            axis(
                "rotation3",
                "c1_c",
                [1.0, 0.1, 0.2],
                &xy("NaturalCubicSpline", &X, &Y, ""),
            ),
            axis(
                "translation1",
                "c1_a",
                [1.0, 0.0, 0.0],
                &xy("GCVSpline", &X, &YT, "<half_order>3</half_order>"),
            ),
            axis(
                "translation2",
                "c1_b",
                [0.0, 2.0, 0.0],
                &xy("PiecewiseLinearFunction", &X, &YT, ""),
            ),
            axis("translation3", "", [0.0, 0.0, 1.0], &constant(0.02)),
        ]),
        3.0,
    );
    joints += &j(
        "CustomJoint",
        "custom2",
        "cust1",
        "cust2",
        &free("c2_k", 1.4),
        &st([
            axis("rotation1", "c2_k", [1.0, 0.0, 0.0], "<PolynomialFunction><coefficients>0.2 -0.3 0.9 0.05</coefficients></PolynomialFunction>"),
            axis("rotation2", "c2_k", [0.0, 1.0, 0.0], &multiplier(1.7, &simm(&Y))),
            axis("rotation3", "", [0.0, 0.0, 1.0], &constant(0.4)),
            axis("translation1", "c2_k", [1.0, 0.0, 0.0], &linear(0.05, 0.01)),
            axis("translation2", "c2_k", [0.0, 1.0, 0.0], &multiplier(-2.0, &xy("GCVSpline", &X, &YT, "<half_order>2</half_order>"))),
            axis("translation3", "", [0.0, 0.0, 1.0], &constant(0.0)),
        ]),
        -1.5,
    );
    joints
}

/// Two custom joints with a dependent, a locked and a clamped coordinate, and a chain of
/// multiplied splines.
fn custom_joints_of_coordinate_kinds() -> String {
    let (j, st) = (joint, spatial_transform);
    let mut joints = String::new();
    joints += &j(
        "CustomJoint",
        "custom3",
        "cust2",
        "cust3",
        &[
            coord("c3_dep", -2.0, 2.0, 0.0, false, false),
            coord("c3_lock", -1.0, 1.0, 0.3, true, false),
            coord("c3_clamp", -0.5, 0.8, 0.1, false, true),
        ]
        .concat(),
        &st([
            axis("rotation1", "c3_dep", [0.0, 0.0, 1.0], &linear(1.0, 0.0)),
            axis("rotation2", "c3_lock", [1.0, 0.0, 0.0], &linear(1.0, 0.0)),
            axis("rotation3", "c3_clamp", [0.0, 1.0, 0.0], &linear(1.0, 0.0)),
            axis("translation1", "c3_dep", [1.0, 0.0, 0.0], &simm(&YT)),
            axis(
                "translation2",
                "c3_lock",
                [0.0, 1.0, 0.0],
                &linear(0.1, 0.0),
            ),
            axis("translation3", "", [0.0, 0.0, 1.0], &constant(0.0)),
        ]),
        0.7,
    );
    joints += &j(
        "CustomJoint",
        "custom4",
        "cust3",
        "cust4",
        &coord("c4_q", -2.0, 2.0, 0.0, false, false),
        &st([
            axis(
                "rotation1",
                "c4_q",
                [0.0, 0.0, 1.0],
                &multiplier(0.8, &xy("NaturalCubicSpline", &X, &Y, "")),
            ),
            axis("rotation2", "", [1.0, 0.0, 0.0], &constant(0.0)),
            axis("rotation3", "", [0.0, 1.0, 0.0], &constant(0.0)),
            axis(
                "translation1",
                "c4_q",
                [0.6, 0.8, 0.0],
                &multiplier(1.5, &xy("PiecewiseLinearFunction", &X, &YT, "")),
            ),
            axis("translation2", "", [0.0, 1.0, 0.0], &constant(0.0)),
            axis("translation3", "", [0.0, 0.0, 1.0], &constant(0.0)),
        ]),
        -0.3,
    );
    joints
}

/// Two markers on each body, and one on a frame of the last body.
fn marker_set() -> String {
    let mut markers = String::new();
    for (i, (b, _)) in BODIES.iter().enumerate() {
        let s = i as f64;
        for (k, loc) in [[0.1, 0.02 * s, -0.03], [-0.04, 0.08, 0.06 - 0.01 * s]]
            .iter()
            .enumerate()
        {
            writeln!(
                markers,
                "<Marker name=\"{b}_m{k}\"><socket_parent_frame>/bodyset/{b}</socket_parent_frame>\
                 <location>{} {} {}</location><fixed>false</fixed></Marker>",
                loc[0], loc[1], loc[2]
            )
            .unwrap();
        }
    }
    markers +=
        "<Marker name=\"cust4_on_frame\"><socket_parent_frame>/cust4_tip</socket_parent_frame>\
                <location>0.03 -0.01 0.02</location><fixed>false</fixed></Marker>\n";
    markers
}
