//! OpenSim function elements → [`FunctionSpec`].

use jointfit::model::functions::{Function, FunctionSpec};
use roxmltree::Node;

use super::xml::{child, elements, number, numbers};
use super::Fail;

/// The function element inside a holder (`<TransformAxis>`, `<function>`, …): the one
/// element child whose tag is a function type, or the first element after `skip` tags.
pub(crate) fn function_in(holder: Node, skip: &[&str]) -> Result<FunctionSpec, Fail> {
    let f = elements(holder)
        .find(|c| !skip.contains(&c.tag_name().name()))
        .ok_or_else(|| Fail::at(holder, "has no function".to_string()))?;
    let spec = function(f)?;
    Function::try_from(&spec).map_err(|e| Fail::at(f, format!("{}: {e}", f.tag_name().name())))?;
    Ok(spec)
}

/// One function element.
pub(crate) fn function(f: Node) -> Result<FunctionSpec, Fail> {
    let tag = f.tag_name().name();
    let xy = || -> Result<(Vec<f64>, Vec<f64>), Fail> { Ok((numbers(f, "x")?, numbers(f, "y")?)) };
    Ok(match tag {
        "Constant" => FunctionSpec::Constant {
            value: number(f, "value")?,
        },
        "LinearFunction" => {
            let c = numbers(f, "coefficients")?;
            let [slope, intercept] = c[..] else {
                return Err(Fail::at(f, "LinearFunction needs two coefficients".into()));
            };
            FunctionSpec::Linear { slope, intercept }
        }
        "PolynomialFunction" => FunctionSpec::Polynomial {
            coefficients: numbers(f, "coefficients")?,
        },
        "PiecewiseLinearFunction" => {
            let (x, y) = xy()?;
            FunctionSpec::PiecewiseLinear { x, y }
        }
        "SimmSpline" => {
            let (x, y) = xy()?;
            FunctionSpec::SimmSpline { x, y }
        }
        "NaturalCubicSpline" => {
            let (x, y) = xy()?;
            FunctionSpec::NaturalCubicSpline { x, y }
        }
        "GCVSpline" => {
            let (x, y) = xy()?;
            let half = number(f, "half_order")?;
            if half.fract() != 0.0 || !(1.0..=4.0).contains(&half) {
                return Err(Fail::at(
                    f,
                    format!("GCVSpline half_order {half} is not 1, 2, 3 or 4"),
                ));
            }
            FunctionSpec::GcvSpline {
                degree: 2 * half as usize - 1,
                x,
                y,
            }
        }
        "MultiplierFunction" => {
            let inner = child(f, "function")
                .ok_or_else(|| Fail::at(f, "MultiplierFunction has no <function>".into()))?;
            FunctionSpec::Multiplier {
                scale: number(f, "scale")?,
                function: Box::new(function_in(inner, &[])?),
            }
        }
        other => {
            return Err(Fail::at(
                f,
                format!(
                    "function type {other} is not supported (Constant, LinearFunction, \
                     PolynomialFunction, PiecewiseLinearFunction, SimmSpline, \
                     NaturalCubicSpline, GCVSpline, MultiplierFunction)"
                ),
            ))
        }
    })
}
