//! Command-line handling of the parameter priors of `calibrate` (see
//! `jointfit::calibrate::prior` and `docs/priors.md`): `--prior model|none`,
//! `--prior-sd NAME=VALUE,...`, and the short summary of where each parameter's information
//! came from.

use anyhow::{bail, Result};
use clap::ValueEnum;
use jointfit::calibrate::prior::Source;
use jointfit::model::spec::{ModelSpec, Unit};
use serde::Serialize;

/// Which prior the fit uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PriorArg {
    /// The model file's `prior_sd` / `prior_mean` (written by `personalize`): a maximum a
    /// posteriori fit.
    Model,
    /// No prior: the unregularized least squares of Reinbolt et al. 2005.
    None,
}

/// Applies `--prior` and `--prior-sd` to a model description. Each override is
/// `NAME=VALUE` with NAME a group (`hip`, `knee`, `ankle`, `all`) or a parameter and VALUE a
/// number with unit `mm` or `deg` (a group override sets the parameters of that unit).
pub fn apply(spec: &mut ModelSpec, prior: PriorArg, overrides: &[String]) -> Result<()> {
    if prior == PriorArg::None {
        if !overrides.is_empty() {
            bail!("--prior-sd cannot be combined with --prior none");
        }
        for p in &mut spec.parameters {
            p.prior_sd = None;
        }
        return Ok(());
    }
    for o in overrides {
        let Some((name, value)) = o.split_once('=') else {
            bail!("--prior-sd {o:?}: expected NAME=VALUE, e.g. knee=5mm or hip_pelvis_lateral=8mm");
        };
        let (name, value) = (name.trim(), value.trim());
        let (num, unit) = if let Some(v) = value.strip_suffix("mm") {
            (v, Unit::Metre)
        } else if let Some(v) = value.strip_suffix("deg") {
            (v, Unit::Radian)
        } else {
            bail!("--prior-sd {o:?}: the value needs a unit, mm or deg (e.g. {name}=5mm)");
        };
        let v: f64 = num
            .trim()
            .parse()
            .map_err(|_| anyhow::anyhow!("--prior-sd {o:?}: {num:?} is not a number"))?;
        if !(v.is_finite() && v > 0.0) {
            bail!("--prior-sd {o:?}: the SD must be a positive number");
        }
        let si = match unit {
            Unit::Metre => v * 1e-3,
            Unit::Radian => v.to_radians(),
        };
        let mut hit = 0;
        for p in &mut spec.parameters {
            let named = p.name == name;
            let grouped = (name == "all" || p.group == name) && p.unit == unit;
            if named && p.unit != unit {
                bail!("--prior-sd {o:?}: {name} is {:?}, not {value}", p.unit);
            }
            if named || grouped {
                p.prior_sd = Some(si);
                hit += 1;
            }
        }
        if hit == 0 {
            bail!(
                "--prior-sd {o:?}: no parameter or group {name:?} with that unit; groups: {}",
                groups(spec).join(", ")
            );
        }
    }
    Ok(())
}

fn groups(spec: &ModelSpec) -> Vec<String> {
    let mut g: Vec<String> = Vec::new();
    for p in &spec.parameters {
        if !g.contains(&p.group) {
            g.push(p.group.clone());
        }
    }
    g
}

/// One line per source class ([`jointfit_app::present::information_summary`]).
pub fn summary(rows: &[(String, String, Option<Source>)]) -> Vec<String> {
    jointfit_app::present::information_summary(rows)
}

/// `--refine-markers`: the markers that moved most and the strongest trade-offs.
pub fn print_refinement(
    markers: &[jointfit::workflow::refine::RefinedMarker],
    trade_offs: &[jointfit::workflow::refine::TradeOff],
) {
    if markers.is_empty() {
        return;
    }
    let mut by_shift: Vec<_> = markers.iter().collect();
    by_shift.sort_by(|a, b| b.shift.total_cmp(&a.shift));
    let list: Vec<String> = by_shift
        .iter()
        .take(6)
        .map(|m| format!("{} {:.1} mm", m.name, jointfit_app::present::mm(m.shift)))
        .collect();
    println!(
        "refined {} marker positions; moved most: {}",
        markers.len(),
        list.join(", ")
    );
    if !trade_offs.is_empty() {
        let list: Vec<String> = trade_offs
            .iter()
            .take(6)
            .map(|t| {
                format!(
                    "{} ~ {} (r = {:+.2})",
                    t.marker_parameter, t.joint_parameter, t.correlation
                )
            })
            .collect();
        println!(
            "marker offsets that trade off with joint parameters: {}",
            list.join(", ")
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::lower_limb::{lower_limb, Side};

    #[test]
    fn overrides_by_group_unit_and_name() {
        let mut spec = lower_limb(Side::Right);
        apply(
            &mut spec,
            PriorArg::Model,
            &[
                "knee=5mm".into(),
                "knee=3deg".into(),
                "hip_pelvis_lateral=8mm".into(),
            ],
        )
        .unwrap();
        let sd = |n: &str| {
            spec.parameters
                .iter()
                .find(|p| p.name == n)
                .unwrap()
                .prior_sd
        };
        assert_eq!(sd("knee_thigh_superior"), Some(0.005));
        assert!((sd("knee_thigh_frontal").unwrap() - 3f64.to_radians()).abs() < 1e-15);
        assert_eq!(sd("hip_pelvis_lateral"), Some(0.008));
        assert_eq!(sd("hip_pelvis_anterior"), None);
        for bad in [
            "knee",
            "knee=5",
            "knee=-1mm",
            "elbow=5mm",
            "hip_pelvis_lateral=3deg",
        ] {
            assert!(
                apply(&mut spec, PriorArg::Model, &[bad.into()]).is_err(),
                "{bad}"
            );
        }
        apply(&mut spec, PriorArg::None, &[]).unwrap();
        assert!(spec.parameters.iter().all(|p| p.prior_sd.is_none()));
    }
}
