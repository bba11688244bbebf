//! Small models used by several tests.

use jointfit::model::spec::ModelSpec;

/// A planar-ish two-link chain with parameters in both offsets.
pub fn two_link() -> ModelSpec {
    ModelSpec::from_toml(
        r#"
name = "two-link"
segments = [{ name = "upper" }, { name = "lower" }]

[[joints]]
name = "shoulder"
parent = "ground"
child = "upper"
kind = { type = "pin", axis = "z" }
coordinates = ["shoulder_angle"]
parent_offset = { ty = 1.2, rx = "shoulder_tilt" }

[[joints]]
name = "elbow"
parent = "upper"
child = "lower"
kind = { type = "pin", axis = "-z" }
coordinates = [{ name = "elbow_angle", range = [0.0, 2.5] }]
parent_offset = { ty = "upper_length", tz = 0.01, ry = "elbow_twist" }
child_offset = { tx = "elbow_in_lower", rz = 0.2 }

[[parameters]]
name = "shoulder_tilt"
group = "shoulder"
unit = "rad"
nominal = 0.1
lower = -0.5
upper = 0.5

[[parameters]]
name = "upper_length"
group = "elbow"
unit = "m"
nominal = -0.3
lower = -0.35
upper = -0.25

[[parameters]]
name = "elbow_twist"
group = "elbow"
unit = "rad"
nominal = 0.05
lower = -0.5
upper = 0.5

[[parameters]]
name = "elbow_in_lower"
group = "elbow"
unit = "m"
nominal = 0.01
lower = -0.05
upper = 0.05

[[markers]]
name = "elbow_lat"
segment = "upper"
position = [0.0, -0.3, 0.04]

[[markers]]
name = "forearm"
segment = "lower"
position = [0.02, -0.12, 0.03]

[[markers]]
name = "wrist"
segment = "lower"
position = [0.0, -0.25, 0.0]
weight = 2.0
"#,
    )
    .expect("two-link spec parses")
}

/// Every joint kind, general axes, a parameter shared by two scalars and a scaled one.
pub fn kitchen_sink() -> ModelSpec {
    ModelSpec::from_toml(
        r#"
name = "kitchen-sink"
segments = [{ name = "base" }, { name = "a" }, { name = "b" }, { name = "c" }, { name = "d" }]

[[joints]]
name = "j0"
parent = "ground"
child = "base"
kind = { type = "free", rotation_axes = ["y", [1.0, 1.0, 0.0], "-z"] }
coordinates = ["tx", "ty", "tz", "r1", "r2", "r3"]

[[joints]]
name = "j1"
parent = "base"
child = "a"
kind = { type = "gimbal", axes = ["x", "z", [0.3, -0.2, 0.9]] }
coordinates = ["g1", "g2", "g3"]
parent_offset = { tx = "s", ty = { param = "s", scale = -2.0 }, rx = "ang", rz = 0.3 }
child_offset = { tz = "len", ry = { param = "ang", scale = 0.5 } }

[[joints]]
name = "j2"
parent = "a"
child = "b"
kind = { type = "slider", axis = [0.0, 0.6, 0.8] }
coordinates = ["slide"]
parent_offset = { ty = -0.2, rz = "ang2" }

[[joints]]
name = "j3"
parent = "b"
child = "c"
kind = { type = "universal", axes = ["-x", "y"] }
coordinates = ["u1", "u2"]
child_offset = { tx = 0.05, rx = "ang2" }

[[joints]]
name = "j4"
parent = "a"
child = "d"
kind = { type = "weld" }
parent_offset = { tx = "len", ry = 0.4 }

[[parameters]]
name = "s"
group = "g1"
unit = "m"
nominal = 0.05
lower = -0.1
upper = 0.1

[[parameters]]
name = "ang"
group = "g1"
unit = "rad"
nominal = 0.2
lower = -1.0
upper = 1.0

[[parameters]]
name = "len"
group = "g2"
unit = "m"
nominal = -0.3
lower = -0.4
upper = -0.2

[[parameters]]
name = "ang2"
group = "g2"
unit = "rad"
nominal = -0.3
lower = -1.0
upper = 1.0

[[markers]]
name = "m_base"
segment = "base"
position = [0.1, 0.0, 0.05]

[[markers]]
name = "m_a"
segment = "a"
position = [0.0, -0.1, 0.07]

[[markers]]
name = "m_b"
segment = "b"
position = [0.03, -0.05, -0.02]

[[markers]]
name = "m_c"
segment = "c"
position = [0.0, -0.15, 0.01]

[[markers]]
name = "m_d"
segment = "d"
position = [0.02, 0.02, 0.02]
"#,
    )
    .expect("kitchen-sink spec parses")
}

/// Custom joints through every function type: splines and polynomials of a coordinate, a
/// locked coordinate, a coordinate coupled to another joint's, an oblique axis, and
/// parameters on the offsets around them. Coordinates: q1, q2, q4 (q3 locked, qd coupled).
pub fn custom_joints() -> ModelSpec {
    ModelSpec::from_toml(
        r#"
name = "custom-joints"
segments = [{ name = "a" }, { name = "b" }]

[[joints]]
name = "j1"
parent = "ground"
child = "a"
coordinates = ["q1", "q2", { name = "q3", default = 0.3, locked = true }]
[joints.kind]
type = "custom"
[[joints.kind.axes]]
motion = "translation"
axis = "x"
coordinate = "q1"
function = { type = "simm_spline", x = [-4.0, -1.0, 0.0, 0.7, 2.0, 4.0], y = [0.1, -0.05, 0.0, 0.02, 0.08, -0.1] }
[[joints.kind.axes]]
motion = "translation"
axis = "-y"
coordinate = "q1"
function = { type = "polynomial", coefficients = [0.01, -0.02, 0.03, 0.5] }
[[joints.kind.axes]]
motion = "rotation"
axis = "z"
coordinate = "q1"
[[joints.kind.axes]]
motion = "rotation"
axis = [1.0, 1.0, 0.2]
coordinate = "q2"
function = { type = "gcv_spline", degree = 5, x = [-4.0, -2.0, -0.5, 0.0, 1.0, 2.5, 4.0], y = [-1.0, -0.6, -0.2, 0.0, 0.3, 0.5, 0.9] }
[[joints.kind.axes]]
motion = "rotation"
axis = "x"
coordinate = "q3"
function = { type = "multiplier", scale = 2.0, function = { type = "linear", slope = 1.0, intercept = 0.1 } }

[[joints]]
name = "j2"
parent = "a"
child = "b"
coordinates = ["q4", "qd"]
parent_offset = { ty = "len", rx = "tilt" }
[joints.kind]
type = "custom"
[[joints.kind.axes]]
motion = "translation"
axis = [0.0, 1.0, 1.0]
coordinate = "qd"
function = { type = "multiplier", scale = 0.5, function = { type = "natural_cubic_spline", x = [-5.0, -1.0, 0.5, 5.0], y = [0.0, 0.05, 0.02, -0.03] } }
[[joints.kind.axes]]
motion = "rotation"
axis = "z"
coordinate = "qd"
function = { type = "gcv_spline", degree = 3, x = [-5.0, -2.0, 0.0, 1.5, 5.0], y = [-2.0, -1.1, 0.0, 0.8, 2.5] }
[[joints.kind.axes]]
motion = "rotation"
axis = "y"
coordinate = "q4"
function = { type = "linear", slope = -1.5, intercept = 0.2 }

[[couplers]]
name = "follow"
dependent = "qd"
independent = "q1"
function = { type = "polynomial", coefficients = [0.1, 0.9, 0.05] }

[[parameters]]
name = "len"
group = "j2"
unit = "m"
nominal = -0.4
lower = -0.5
upper = -0.3

[[parameters]]
name = "tilt"
group = "j2"
unit = "rad"
nominal = 0.1
lower = -0.5
upper = 0.5

[[markers]]
name = "m_a"
segment = "a"
position = [0.05, -0.1, 0.07]

[[markers]]
name = "m_b1"
segment = "b"
position = [0.03, -0.05, -0.02]

[[markers]]
name = "m_b2"
segment = "b"
position = [-0.1, -0.2, 0.04]
"#,
    )
    .expect("custom-joints spec parses")
}
