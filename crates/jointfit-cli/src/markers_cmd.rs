//! `jointfit markers suggest STATIC [-o FILE.toml] [--up AXIS] [--motion TRIAL]`: a marker set proposed from a
//! static trial's labels and positions ([`jointfit_landmarks::suggest`]), for the user to
//! check; tried at once with `personalize` on the same trial.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Subcommand;
use jointfit::model::lower_limb::Side;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::{motion, personalize, PersonalizeOptions};

use crate::common::{load_trial, Up};

#[derive(Subcommand)]
pub enum MarkersCommand {
    /// Propose a marker-set TOML from a static trial: which markers sit on which segment,
    /// which are the epicondyles and malleoli (check it before use).
    Suggest {
        /// Static standing trial (.trc or .c3d).
        r#static: PathBuf,
        /// Write the marker set here (TOML, atomically) instead of printing it.
        #[arg(short, long, value_name = "FILE.toml")]
        output: Option<PathBuf>,
        /// The laboratory's vertical axis (default: detected from the marker layout).
        #[arg(long, value_enum)]
        up: Option<Up>,
        /// Name written into the set (default: the output file's stem, else "suggested").
        #[arg(long)]
        name: Option<String>,
        /// A motion trial of the same session: tracking markers it lacks (static-only ones,
        /// such as lateral knee and ankle markers taken off after the static trial) are left
        /// out of the tracking lists; they stay landmarks.
        #[arg(long, value_name = "TRIAL")]
        motion: Option<PathBuf>,
    },
}

pub fn run(cmd: MarkersCommand) -> Result<()> {
    let MarkersCommand::Suggest {
        r#static,
        output,
        up,
        name,
        motion,
    } = cmd;
    let mut files = crate::output::Files::new().input("static trial", &r#static);
    if let Some(m) = &motion {
        files = files.input("--motion", m);
    }
    if let Some(o) = &output {
        files = files.output("output", o);
    }
    files.check()?;
    let path = r#static.display().to_string();
    let (up, trial) = load_static(&r#static, up)?;
    let name = name.unwrap_or_else(|| {
        output
            .as_ref()
            .and_then(|o| o.file_stem())
            .map_or("suggested".into(), |s| s.to_string_lossy().into_owned())
    });
    let mut suggestion = match jointfit_landmarks::suggest::suggest(&trial, &name) {
        Ok(s) => s,
        Err(e) => {
            preset_hint(&path, &trial);
            return Err(
                anyhow::Error::new(e).context(format!("{path}: cannot suggest a marker set"))
            );
        }
    };
    with_motion(&mut suggestion, motion.as_deref())?;
    let mut text = format!(
        "# Suggested by `jointfit markers suggest` from {path} (up axis {}).\n\
         # Check every role before use: see docs/markersets.md.\n",
        jointfit::spatial::UpAxis::from(up)
    );
    for note in &suggestion.notes {
        text.push_str(&format!("# note: {note}\n"));
        eprintln!("jointfit: {path}: {note}");
    }
    text.push_str(&suggestion.set.to_toml());
    print_roles(&suggestion.roles);
    preset_hint(&path, &trial);
    try_personalize(&path, &trial, &suggestion.set)?;
    match &output {
        Some(o) => {
            jointfit_io::atomic::write_atomic(o, text.as_bytes())
                .with_context(|| format!("{}: cannot write", o.display()))?;
            println!("wrote {}", o.display());
        }
        None => print!("{text}"),
    }
    Ok(())
}

/// The static trial in the model's frame, without Plug-in Gait's virtual segment axes; the
/// vertical given or detected (said on stderr).
fn load_static(path: &std::path::Path, up: Option<Up>) -> Result<(Up, jointfit::trial::Trial)> {
    let name = path.display().to_string();
    let (up, detected) = crate::common::up_or_detected(path, up)?;
    if let Some(d) = detected {
        eprintln!("jointfit: {name}: up axis detected: {d}");
    }
    let trial = load_trial(path, up, None)?;
    let virtual_points = plug_in_gait_axes(trial.labels());
    if virtual_points.is_empty() {
        return Ok((up, trial));
    }
    eprintln!(
        "jointfit: {name}: left out {} points that are Plug-in Gait's segment axes (origin, \
         anterior, lateral, proximal: {}{}), not skin markers",
        virtual_points.len(),
        virtual_points[..virtual_points.len().min(4)].join(", "),
        if virtual_points.len() > 4 {
            ", …"
        } else {
            ""
        }
    );
    let kept: Vec<&str> = trial
        .labels()
        .iter()
        .map(String::as_str)
        .filter(|l| !virtual_points.iter().any(|v| v == l))
        .collect();
    Ok((up, trial.select(&kept)?))
}

/// With `--motion`: tracking markers the motion trial lacks are left out of the tracking
/// lists, and each role's motion coherence with its segment is measured; without it, a hint
/// on static-only landmarks.
fn with_motion(
    suggestion: &mut jointfit_landmarks::suggest::Suggestion,
    motion: Option<&std::path::Path>,
) -> Result<()> {
    let Some(m) = motion else {
        if let Some(note) = static_only_hint(&suggestion.set) {
            suggestion.notes.push(note);
        }
        return Ok(());
    };
    let (moving, _) = jointfit_io::trial_file::read_trial_noted(m)?;
    let present = |l: &str| motion::has_samples(&moving, l);
    for note in motion::keep_tracked_in(&mut suggestion.set, &present) {
        suggestion.notes.push(note);
    }
    jointfit_landmarks::suggest::coherence(&moving, &suggestion.set, &mut suggestion.roles);
    Ok(())
}

/// Every role with its confidence and what it is based on (stderr).
fn print_roles(roles: &[jointfit_landmarks::suggest::Role]) {
    let mut t = crate::table::Table::new(&["role", "marker", "confidence", "based on"]);
    for r in roles {
        t.row(vec![
            r.role.clone(),
            r.marker.clone(),
            r.confidence().name().to_string(),
            r.basis(),
        ]);
    }
    eprint!("{}", t.render());
    let low: Vec<&str> = roles
        .iter()
        .filter(|r| r.confidence() == jointfit_landmarks::suggest::Confidence::Low)
        .map(|r| r.marker.as_str())
        .collect();
    if !low.is_empty() {
        eprintln!(
            "jointfit: warning: low confidence in the roles of {}: check them first",
            low.join(", ")
        );
    }
}

/// A preset that covers the labels is the better choice than a guess (stderr).
fn preset_hint(path: &str, trial: &jointfit::trial::Trial) {
    if let Some(best) = jointfit_landmarks::auto::rank_presets(trial.labels())
        .into_iter()
        .find(|f| f.legs_fitted > 0)
    {
        eprintln!(
            "jointfit: {path}: the labels fit preset {} ({} of 2 legs complete): --markers {} \
             instead of this suggestion",
            best.name, best.legs_fitted, best.name
        );
    }
}

/// Tries the set: personalizes each leg it describes; a leg no adult has refuses the set
/// (the roles were given to the wrong markers).
fn try_personalize(path: &str, trial: &jointfit::trial::Trial, set: &MarkerSet) -> Result<()> {
    let mut implausible = Vec::new();
    for (side, present) in [
        (Side::Right, set.right.is_some()),
        (Side::Left, set.left.is_some()),
    ] {
        if !present {
            continue;
        }
        match personalize(trial, set, side, &PersonalizeOptions::default()) {
            Err(e) => eprintln!(
                "jointfit: warning: {path}: personalize with this set fails for the {side:?} leg: {e}"
            ),
            Ok(leg) => {
                let model = jointfit::model::Model::compile(&leg.spec)?;
                implausible.extend(
                    jointfit::plausibility::anthropometry(&model, &model.nominal_params())
                        .iter()
                        .filter(|m| !m.ok())
                        .map(|m| {
                            let line = jointfit_app::present::implausible_measure(m);
                            format!("{side:?} leg: {line}")
                        }),
                );
            }
        }
    }
    if implausible.is_empty() {
        return Ok(());
    }
    Err(crate::output::Rejected(format!(
        "{path}: the suggested roles give no adult's leg ({}); some roles went to the wrong \
         markers: name them in a marker-set file",
        implausible.join("; ")
    ))
    .into())
}

/// Without `--motion`: the landmarks that also track a segment (lateral knee and ankle
/// markers), which laboratories often take off after the static trial.
fn static_only_hint(set: &MarkerSet) -> Option<String> {
    let mut both: Vec<&str> = Vec::new();
    for leg in [&set.right, &set.left].into_iter().flatten() {
        for l in [
            &leg.lateral_epicondyle,
            &leg.medial_epicondyle,
            &leg.lateral_malleolus,
            &leg.medial_malleolus,
        ] {
            if leg.thigh.contains(l) || leg.shank.contains(l) || leg.foot.contains(l) {
                both.push(l);
            }
        }
    }
    (!both.is_empty()).then(|| {
        format!(
            "{} are landmarks that also track here; if the motion trials lack them (markers \
             often taken off after the static trial), pass --motion TRIAL to leave out of the \
             tracking lists what a motion trial lacks",
            both.join(", ")
        )
    })
}

/// The labels of Plug-in Gait's virtual segment axes: for each segment a computed origin,
/// anterior, lateral and proximal point (`RFEO`, `RFEA`, `RFEL`, `RFEP` for the right femur;
/// `PELO`… for the pelvis), written beside the markers as 3D points. A prefix (`RFE`, after
/// any `Subject:` part) counts only when all four of its points are present, so a lab's own
/// `RTIA`/`RTIP` tibia markers stay. Vicon, "Plug-in Gait Reference Guide" (output points).
fn plug_in_gait_axes(labels: &[String]) -> Vec<String> {
    let bare = |l: &str| l.rsplit(':').next().unwrap_or(l).to_string();
    let has = |name: &str| labels.iter().any(|l| bare(l) == name);
    let mut out = Vec::new();
    for l in labels {
        let b = bare(l);
        if !(b.len() == 4 && b.is_ascii() && b.ends_with('O')) {
            continue;
        }
        let stem = &b[..3];
        let all = ["O", "A", "L", "P"]
            .iter()
            .all(|s| has(&format!("{stem}{s}")));
        if all {
            for s in ["O", "A", "L", "P"] {
                let name = format!("{stem}{s}");
                out.extend(labels.iter().filter(|x| bare(x) == name).cloned());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::plug_in_gait_axes;

    #[test]
    fn segment_axes_only_as_complete_quadruples() {
        let labels: Vec<String> = [
            "A:RKNE", "A:RFEO", "A:RFEA", "A:RFEL", "A:RFEP", "A:RTIA", "A:RTIP", "A:PELO",
            "A:PELA", "A:PELL", "A:PELP",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        assert_eq!(
            plug_in_gait_axes(&labels),
            ["A:RFEO", "A:RFEA", "A:RFEL", "A:RFEP", "A:PELO", "A:PELA", "A:PELL", "A:PELP"]
        );
        // jointfit's synthetic tibia markers RTIA/RTIP without RTIO/RTIL are markers.
        let synth: Vec<String> = ["RTIB", "RTIA", "RTIP"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert!(plug_in_gait_axes(&synth).is_empty());
    }
}
