//! Scalar functions of one coordinate, as OpenSim's joints and coordinate couplers use them:
//! value and exact first derivative.
//!
//! A [`FunctionSpec`] is what a model file says; [`Function::try_from`] validates it and
//! precomputes the spline coefficients once. The definitions follow OpenSim 4.x:
//!
//! * `Constant`: `f(x) = c`.
//! * `LinearFunction`, coefficients `[a, b]`: `f(x) = a·x + b`.
//! * `PolynomialFunction`, coefficients `[c₀, …, c_n]` highest power first (SimTK's
//!   `Function::Polynomial`): `f(x) = c₀ xⁿ + … + c_n`.
//! * `PiecewiseLinearFunction`: linear interpolation of the points, the end segments
//!   extended beyond the data.
//! * `SimmSpline`: the cubic spline of Forsythe, Malcolm & Moler (*Computer Methods for
//!   Mathematical Computations*, 1977, routine `spline`): its end conditions match the third
//!   derivatives of the cubics through the first and last four points (none for three
//!   points, a straight line for two); beyond the data it continues along the end tangents.
//! * `NaturalCubicSpline`: in OpenSim 4 (`NaturalCubicSpline::calcCoefficients`) the very same
//!   FMM spline as `SimmSpline`, not a natural spline; jointfit follows OpenSim.
//! * `GCVSpline` of odd degree `2m − 1` (which OpenSim fits with
//!   Woltring's GCVSPL at zero smoothing, i.e. interpolates): the *natural* interpolating
//!   spline of that degree, `C^{2m−2}` at the knots, with derivatives `m … 2m − 2` zero at
//!   both ends; beyond the data it is the degree `m − 1` Taylor polynomial of the end
//!   (Schoenberg's natural spline; for cubics the end tangent line). Its coefficients come
//!   from one linear solve over all pieces, in the scaled variable `s = (x − x_i)/h_i`.
//! * `MultiplierFunction`: `f(x) = scale · g(x)`.
//!
//! Checked against OpenSim 4.6 (`tests/it/osim_functions.rs` in `jointfit-io`) and against
//! finite differences.

use serde::{Deserialize, Serialize};

use super::splines::{check_points, fmm_spline, natural_spline};

/// A function as written in a model description (OpenSim's element names, snake case).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum FunctionSpec {
    Constant {
        value: f64,
    },
    Linear {
        slope: f64,
        intercept: f64,
    },
    Polynomial {
        /// Highest power first.
        coefficients: Vec<f64>,
    },
    PiecewiseLinear {
        x: Vec<f64>,
        y: Vec<f64>,
    },
    SimmSpline {
        x: Vec<f64>,
        y: Vec<f64>,
    },
    NaturalCubicSpline {
        x: Vec<f64>,
        y: Vec<f64>,
    },
    GcvSpline {
        degree: usize,
        x: Vec<f64>,
        y: Vec<f64>,
    },
    Multiplier {
        scale: f64,
        function: Box<FunctionSpec>,
    },
}

impl FunctionSpec {
    /// The identity `f(x) = x`.
    pub fn identity() -> Self {
        FunctionSpec::Linear {
            slope: 1.0,
            intercept: 0.0,
        }
    }
    /// The constant value, when the function is constant (used to drop fixed axes).
    pub fn constant_value(&self) -> Option<f64> {
        match self {
            FunctionSpec::Constant { value } => Some(*value),
            FunctionSpec::Multiplier { scale, function } => {
                function.constant_value().map(|v| scale * v)
            }
            _ => None,
        }
    }
}

/// A validated function with precomputed coefficients, built by [`Function::try_from`] and
/// evaluated with its derivative by [`Function::eval`].
#[derive(Debug, Clone, PartialEq)]
pub struct Function(Kind);

#[derive(Debug, Clone, PartialEq)]
enum Kind {
    Constant(f64),
    Linear { slope: f64, intercept: f64 },
    Polynomial(Vec<f64>),
    Pieces(Pieces),
    Scaled { scale: f64, inner: Box<Function> },
}

/// A piecewise polynomial: on `[x_i, x_{i+1}]`, `Σ_k coef[i][k] s^k` with
/// `s = (x − x_i)/(x_{i+1} − x_i)`; outside, Taylor polynomials `Σ_k c_k (x − x_end)^k`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Pieces {
    pub(super) x: Vec<f64>,
    pub(super) coef: Vec<Vec<f64>>,
    pub(super) left: Vec<f64>,
    pub(super) right: Vec<f64>,
    /// At a knot use the piece that starts there (GCVSPL's choice) instead of the one that
    /// ends there (OpenSim's piecewise linear function); only a kink's derivative differs.
    pub(super) right_at_knots: bool,
}

/// `(value, derivative)` of `Σ c_k t^k` by Horner's rule.
fn horner(c: &[f64], t: f64) -> (f64, f64) {
    let mut v = 0.0;
    let mut d = 0.0;
    for &ck in c.iter().rev() {
        d = d * t + v;
        v = v * t + ck;
    }
    (v, d)
}

impl Pieces {
    fn eval(&self, u: f64) -> (f64, f64) {
        let n = self.x.len();
        if u < self.x[0] {
            return horner(&self.left, u - self.x[0]);
        }
        if u > self.x[n - 1] || (self.right_at_knots && u == self.x[n - 1]) {
            return horner(&self.right, u - self.x[n - 1]);
        }
        // Interval i with x_i < u ≤ x_{i+1} (or x_i ≤ u < x_{i+1}), as OpenSim picks it.
        let after = if self.right_at_knots {
            self.x.partition_point(|&k| k <= u)
        } else {
            self.x.partition_point(|&k| k < u)
        };
        let i = (after.max(1) - 1).min(n - 2);
        let h = self.x[i + 1] - self.x[i];
        let (v, d) = horner(&self.coef[i], (u - self.x[i]) / h);
        (v, d / h)
    }
}

/// Validates a description; the error says what is wrong (the caller names the item).
impl TryFrom<&FunctionSpec> for Function {
    type Error = String;
    fn try_from(spec: &FunctionSpec) -> Result<Function, String> {
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        Ok(Function(match spec {
            FunctionSpec::Constant { value } => {
                if !value.is_finite() {
                    return Err(format!("constant {value} is not finite"));
                }
                Kind::Constant(*value)
            }
            FunctionSpec::Linear { slope, intercept } => {
                if !finite(&[*slope, *intercept]) {
                    return Err("linear function coefficients must be finite".into());
                }
                Kind::Linear {
                    slope: *slope,
                    intercept: *intercept,
                }
            }
            FunctionSpec::Polynomial { coefficients } => {
                if coefficients.is_empty() || !finite(coefficients) {
                    return Err("polynomial needs finite coefficients".into());
                }
                Kind::Polynomial(coefficients.clone())
            }
            FunctionSpec::PiecewiseLinear { x, y } => {
                check_points(x, y, 2)?;
                let coef = (0..x.len() - 1).map(|i| vec![y[i], y[i + 1] - y[i]]);
                let n = x.len();
                let slope0 = (y[1] - y[0]) / (x[1] - x[0]);
                let slope1 = (y[n - 1] - y[n - 2]) / (x[n - 1] - x[n - 2]);
                Kind::Pieces(Pieces {
                    x: x.clone(),
                    coef: coef.collect(),
                    left: vec![y[0], slope0],
                    right: vec![y[n - 1], slope1],
                    right_at_knots: false,
                })
            }
            // OpenSim's NaturalCubicSpline is, despite its name, the same FMM spline
            // (its end conditions fit cubics through the end points, not zero curvature).
            FunctionSpec::SimmSpline { x, y } | FunctionSpec::NaturalCubicSpline { x, y } => {
                check_points(x, y, 2)?;
                Kind::Pieces(fmm_spline(x, y))
            }
            FunctionSpec::GcvSpline { degree, x, y } => {
                if degree % 2 == 0 || *degree > 7 {
                    return Err(format!(
                        "GCVSpline degree {degree} is not supported (1, 3, 5 or 7)"
                    ));
                }
                let m = degree.div_ceil(2);
                check_points(x, y, 2 * m)?;
                Kind::Pieces(natural_spline(x, y, m)?)
            }
            FunctionSpec::Multiplier { scale, function } => {
                if !scale.is_finite() {
                    return Err(format!("multiplier scale {scale} is not finite"));
                }
                Kind::Scaled {
                    scale: *scale,
                    inner: Box::new(Function::try_from(function.as_ref())?),
                }
            }
        }))
    }
}

impl Function {
    /// `(f(x), f′(x))`.
    pub fn eval(&self, x: f64) -> (f64, f64) {
        match &self.0 {
            Kind::Constant(c) => (*c, 0.0),
            Kind::Linear { slope, intercept } => (slope * x + intercept, *slope),
            Kind::Polynomial(c) => {
                let mut v = 0.0;
                let mut d = 0.0;
                for &ck in c {
                    d = d * x + v;
                    v = v * x + ck;
                }
                (v, d)
            }
            Kind::Pieces(p) => p.eval(x),
            Kind::Scaled { scale, inner } => {
                let (v, d) = inner.eval(x);
                (scale * v, scale * d)
            }
        }
    }

    /// The value when the function is constant.
    pub(crate) fn constant(&self) -> Option<f64> {
        match &self.0 {
            Kind::Constant(c) => Some(*c),
            Kind::Scaled { scale, inner } => inner.constant().map(|v| scale * v),
            _ => None,
        }
    }

    /// The slope `a` when the function is `a·x` (linear through the origin).
    pub(crate) fn slope_through_origin(&self) -> Option<f64> {
        match self.0 {
            Kind::Linear {
                slope,
                intercept: 0.0,
            } => Some(slope),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts() -> (Vec<f64>, Vec<f64>) {
        (
            vec![0.0, 1.0, 2.5, 3.0, 4.2, 5.0, 6.1],
            vec![0.0, 0.5, -1.0, 2.0, 1.0, 0.3, 0.9],
        )
    }

    fn fd(f: &Function, x: f64) -> f64 {
        let h = 1e-6;
        (f.eval(x + h).0 - f.eval(x - h).0) / (2.0 * h)
    }

    #[test]
    fn splines_interpolate_and_derivatives_match_differences() {
        let (x, y) = pts();
        for spec in [
            FunctionSpec::SimmSpline {
                x: x.clone(),
                y: y.clone(),
            },
            FunctionSpec::NaturalCubicSpline {
                x: x.clone(),
                y: y.clone(),
            },
            FunctionSpec::GcvSpline {
                degree: 5,
                x: x.clone(),
                y: y.clone(),
            },
            FunctionSpec::PiecewiseLinear {
                x: x.clone(),
                y: y.clone(),
            },
        ] {
            let f = Function::try_from(&spec).unwrap();
            for (xi, yi) in x.iter().zip(&y) {
                assert!((f.eval(*xi).0 - yi).abs() < 1e-12, "{spec:?} at {xi}");
            }
            for u in [-1.3, 0.4, 1.7, 2.7, 3.9, 5.5, 6.0, 7.2] {
                let (_, d) = f.eval(u);
                assert!((d - fd(&f, u)).abs() < 1e-6, "{spec:?} at {u}: {d}");
            }
        }
    }

    #[test]
    fn natural_spline_is_smooth_and_natural() {
        let (x, y) = pts();
        // Quintic: third derivative zero beyond the end (checked by differences of the first
        // derivative); continuity at the knots is checked against OpenSim.
        let f = Function::try_from(&FunctionSpec::GcvSpline { degree: 5, x, y }).unwrap();
        let d1 = |u: f64| f.eval(u).1;
        let d2 = |u: f64| (d1(u + 1e-5) - d1(u - 1e-5)) / 2e-5;
        let d3 = |u: f64| (d2(u + 1e-3) - d2(u - 1e-3)) / 2e-3;
        assert!(d3(-0.5).abs() < 1e-3, "{}", d3(-0.5));
    }

    /// OpenSim's NaturalCubicSpline is the FMM spline (checked against OpenSim 4.6 through a
    /// CustomJoint in jointfit-io's `osim_joint_types` test).
    #[test]
    fn natural_cubic_spline_is_opensims_fmm_spline() {
        let (x, y) = pts();
        let a = Function::try_from(&FunctionSpec::SimmSpline {
            x: x.clone(),
            y: y.clone(),
        });
        let b = Function::try_from(&FunctionSpec::NaturalCubicSpline { x, y });
        assert_eq!(a.unwrap(), b.unwrap());
    }

    #[test]
    fn polynomial_and_multiplier() {
        let p = Function::try_from(&FunctionSpec::Multiplier {
            scale: 2.0,
            function: Box::new(FunctionSpec::Polynomial {
                coefficients: vec![1.0, -2.0, 3.0],
            }),
        })
        .unwrap();
        assert_eq!(p.eval(2.0), (2.0 * (4.0 - 4.0 + 3.0), 2.0 * (4.0 - 2.0)));
    }

    #[test]
    fn bad_input_is_named() {
        let e = Function::try_from(&FunctionSpec::SimmSpline {
            x: vec![0.0, 1.0, 1.0],
            y: vec![0.0; 3],
        })
        .unwrap_err();
        assert!(e.contains("x[2] = 1 after 1"), "{e}");
        let e = Function::try_from(&FunctionSpec::GcvSpline {
            degree: 4,
            x: vec![0.0, 1.0],
            y: vec![0.0; 2],
        })
        .unwrap_err();
        assert!(e.contains("degree 4"), "{e}");
    }
}
