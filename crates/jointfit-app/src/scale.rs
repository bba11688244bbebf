//! The whole `scale` pipeline on files, shared by the CLI and Python: generic `.osim` (with a
//! marker set attached) + static trial (+ motion trials) → fitted factors and registered
//! markers → the subject's `.osim` text as OpenSim's scaling writes it.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_scale::fit::fit_scale;
use jointfit_scale::fit::ScaleFit;
use jointfit_scale::fit::ScaleGroup;
use jointfit_scale::fit::ScaleOptions as FitOptions;
use jointfit_scale::fit::SizePrior;
use jointfit_scale::geometry::ScaleFactors;
use jointfit_scale::groups::averaged_targets;
use jointfit_scale::groups::default_groups;
use jointfit_scale::groups::plausibility;
use nalgebra::Vector3;

use jointfit_io::osim_read::{parse_osim, read_osim, OsimModel};
use jointfit_io::osim_scale::record::{RecordGroup, RecordMarker, ScaleRecord};
use jointfit_io::osim_scale::setup::{read_marker_set, with_marker_set, SetupGroup};
use jointfit_io::osim_scale::{scale_osim, ScaleOptions};

/// Everything `scale` needs.
#[derive(Debug, Clone)]
pub struct ScaleRequest {
    pub generic: PathBuf,
    pub static_trial: PathBuf,
    pub trials: Vec<PathBuf>,
    pub marker_set: Option<PathBuf>,
    /// Subject mass (kg): the written model's total mass.
    pub mass: Option<f64>,
    /// Subject stature (m): the anthropometric prior's overall size.
    pub height: Option<f64>,
    /// Static trial time range (s); `None`: every frame.
    pub time_range: Option<[f64; 2]>,
    /// Body groups (a setup's measurements); `None`: [`default_groups`].
    pub groups: Option<Vec<SetupGroup>>,
    /// The anthropometric prior (false: the pure fit).
    pub prior: bool,
    pub per_axis: bool,
    pub symmetric: bool,
    /// Prior SD of marker offsets (m).
    pub marker_sd: f64,
    /// Frames taken from each motion trial (evenly spaced).
    pub frames_per_trial: usize,
    /// Bodies held at given factors `(body, [sx, sy, sz])` (a setup's manual scales); bodies
    /// the model lacks are skipped.
    pub manual_scales: Vec<(String, [f64; 3])>,
    /// Weights of markers' data rows (a setup's marker-placer tasks); unnamed: 1.
    pub marker_weights: Vec<(String, f64)>,
    /// Masses grow with the product of their body's factors (a setup's
    /// `preserve_mass_distribution` false).
    pub scale_masses: bool,
}

impl ScaleRequest {
    pub fn new(generic: PathBuf, static_trial: PathBuf) -> Self {
        ScaleRequest {
            generic,
            static_trial,
            trials: vec![],
            marker_set: None,
            mass: None,
            height: None,
            time_range: None,
            groups: None,
            prior: true,
            per_axis: false,
            symmetric: false,
            marker_sd: 0.01,
            frames_per_trial: 8,
            manual_scales: Vec::new(),
            marker_weights: Vec::new(),
            scale_masses: false,
        }
    }
}

/// Spread of a segment's factor about the overall size (log units): adult segment-length to
/// stature ratios vary by about this much (docs/scaling.md).
pub const PROPORTION_SD: f64 = 0.05;
/// Spread of the stature ratio (log units): the generic stature is estimated from its
/// markers' vertical extent at the default pose.
pub const STATURE_SD: f64 = 0.03;

#[derive(Debug, Clone)]
pub struct ScaleOutcome {
    /// The subject's `.osim` text.
    pub text: String,
    pub fit: ScaleFit,
    /// Implausible factors, in words with the numbers.
    pub flags: Vec<String>,
    pub generic_mass: f64,
    pub total_mass: f64,
    /// Frames used: the averaged static frame, then the motion frames.
    pub frames: usize,
    /// Model markers the static trial lacks.
    pub absent: Vec<String>,
    /// Wall time of the fit and the scaling (s), without reading files.
    pub seconds: f64,
}

/// Motion-trial frames: `n` evenly spaced frames, each holding at least half of the `needed`
/// markers (those the static trial holds; a frame with fewer says little the static does
/// not). A trial none of whose spaced frames qualifies is an error naming it: a motion trial
/// asked for is never dropped silently.
fn motion_frames(
    path: &Path,
    trial: &jointfit::trial::Trial,
    n: usize,
    spec: &jointfit::model::spec::ModelSpec,
    needed: usize,
) -> Result<Vec<Vec<Vector3<f64>>>, String> {
    let nf = trial.n_frames();
    let mut out = Vec::new();
    if nf == 0 || n == 0 {
        return Ok(out);
    }
    let mut most = 0;
    for k in 0..n {
        let f = (k * nf + nf / 2) / n;
        let t = averaged_targets(spec, trial, f..f + 1);
        let held = t.iter().filter(|m| m.x.is_finite()).count();
        most = most.max(held);
        if held * 2 >= needed {
            out.push(t);
        }
    }
    if out.is_empty() {
        return Err(format!(
            "{}: none of its {n} evenly spaced frames holds half of the {needed} model markers \
             the static trial holds (the most: {most}); check its labels against the model's \
             markers",
            path.display()
        ));
    }
    Ok(out)
}

/// The generic model with the request's marker set attached, and the markers it keeps
/// fixed.
fn with_markers(req: &ScaleRequest) -> Result<(OsimModel, Vec<String>), String> {
    let osim = read_osim(&req.generic).map_err(|e| e.to_string())?;
    let Some(ms) = &req.marker_set else {
        return Ok((osim, Vec::new()));
    };
    let defs = read_marker_set(ms).map_err(|e| e.to_string())?;
    for d in &defs {
        if !osim.spec.segments.iter().any(|s| s.name == d.body) {
            return Err(format!(
                "{}: marker {:?} sits on body {:?}, which {} does not have",
                ms.display(),
                d.name,
                d.body,
                req.generic.display()
            ));
        }
    }
    let fixed = defs
        .iter()
        .filter(|d| d.fixed)
        .map(|d| d.name.clone())
        .collect();
    let text = with_marker_set(&osim.text, &defs)
        .map_err(|e| format!("{}: {e}", req.generic.display()))?;
    let osim = parse_osim(text, &req.generic).map_err(|e| e.to_string())?;
    Ok((osim, fixed))
}

/// The static trial's frames in the request's time range.
fn static_range(req: &ScaleRequest, stat: &Trial) -> Result<Range<usize>, String> {
    let Some([a, b]) = req.time_range else {
        return Ok(0..stat.n_frames());
    };
    let idx: Vec<usize> = (0..stat.n_frames())
        .filter(|&f| stat.time(f) >= a - 1e-9 && stat.time(f) <= b + 1e-9)
        .collect();
    match (idx.first(), idx.last()) {
        (Some(&s), Some(&e)) => Ok(s..e + 1),
        _ => Err(format!(
            "{}: no frame in the time range {a}–{b} s",
            req.static_trial.display()
        )),
    }
}

/// Per frame, per model marker: the measured position (m; NaN: absent).
type Targets = Vec<Vec<Vector3<f64>>>;

/// The fit's targets: the averaged static frame, then the motion frames; and the model
/// markers the static trial lacks.
fn read_targets(req: &ScaleRequest, spec: &ModelSpec) -> Result<(Targets, Vec<String>), String> {
    let stat = jointfit_io::trial_file::read_trial(&req.static_trial).map_err(|e| e.to_string())?;
    let mut targets = vec![averaged_targets(spec, &stat, static_range(req, &stat)?)];
    let absent: Vec<String> = spec
        .markers
        .iter()
        .zip(&targets[0])
        .filter(|(_, t)| !t.x.is_finite())
        .map(|(m, _)| m.name.clone())
        .collect();
    let needed = spec.markers.len() - absent.len();
    for path in &req.trials {
        let t = jointfit_io::trial_file::read_trial(path).map_err(|e| e.to_string())?;
        targets.extend(motion_frames(path, &t, req.frames_per_trial, spec, needed)?);
    }
    Ok((targets, absent))
}

/// The fit's options: groups (a setup's measurements, or one per marked body) without the
/// bodies held at manual scales, priors, fixed markers, weights.
fn fit_options(
    req: &ScaleRequest,
    spec: &ModelSpec,
    generic: &Model,
    fixed: Vec<String>,
) -> FitOptions {
    let has = |b: &str| spec.segments.iter().any(|s| s.name == b);
    let mut held = ScaleFactors::new();
    for (b, f) in req.manual_scales.iter().filter(|(b, _)| has(b)) {
        held.insert(b.clone(), *f);
    }
    let groups: Vec<ScaleGroup> = match &req.groups {
        // A setup may name bodies the model lacks (OpenSim skips them too).
        Some(gs) => gs
            .iter()
            .map(|g| ScaleGroup {
                name: g.name.clone(),
                bodies: g.bodies.iter().filter(|b| has(b)).cloned().collect(),
                per_axis: req.per_axis,
            })
            .collect(),
        None => default_groups(spec, req.per_axis, req.symmetric),
    };
    let groups = groups
        .into_iter()
        .map(|mut g| {
            g.bodies.retain(|b| !held.contains_key(b));
            g
        })
        .filter(|g| !g.bodies.is_empty())
        .collect();
    let mut opts = FitOptions::new(groups);
    opts.fixed_markers = fixed;
    opts.marker_sd = req.marker_sd;
    opts.marker_weights = req.marker_weights.clone();
    opts.fixed_factors = held;
    opts.prior = req.prior.then(|| SizePrior {
        proportion_sd: PROPORTION_SD,
        stature: req.height.map(|h| (h / marker_extent(generic), STATURE_SD)),
    });
    opts
}

/// Runs the pipeline (module docs). Errors are one-line messages naming the file.
pub fn scale_subject(req: &ScaleRequest) -> Result<ScaleOutcome, String> {
    let (osim, fixed) = with_markers(req)?;
    let spec = osim.spec.clone();
    if spec.markers.is_empty() {
        return Err(format!(
            "{}: the model has no markers; give a marker set (--markerset)",
            req.generic.display()
        ));
    }
    let generic = Model::compile(&spec).map_err(|e| format!("{}: {e}", req.generic.display()))?;
    let (targets, absent) = read_targets(req, &spec)?;

    let clock = Instant::now();
    let opts = fit_options(req, &spec, &generic, fixed);
    let fit = fit_scale(&spec, &targets, &opts).map_err(|e| {
        format!(
            "{} on {}: {e}",
            req.generic.display(),
            req.static_trial.display()
        )
    })?;
    let markers: Vec<(String, [f64; 3])> = fit
        .markers
        .iter()
        .filter(|m| osim.markers.iter().any(|s| s.name == m.name))
        .map(|m| (m.name.clone(), m.position))
        .collect();
    let scaled = scale_osim(
        &osim,
        &req.generic,
        &fit.factors,
        &ScaleOptions {
            total_mass: req.mass,
            markers,
            scale_masses: req.scale_masses,
        },
    )
    .map_err(|e| e.to_string())?;
    let mut flags = plausibility(&fit.groups, 0.05, 3.0 * PROPORTION_SD);
    if !fit.converged {
        flags.push(format!(
            "the fit stopped at its iteration limit ({} per round, {} in all) before its \
             convergence test: the factors are the best found, not a verified optimum",
            opts.max_iterations, fit.iterations
        ));
    }
    Ok(ScaleOutcome {
        text: scaled.text,
        fit,
        flags,
        generic_mass: scaled.generic_mass,
        total_mass: scaled.total_mass,
        frames: targets.len(),
        absent,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// The generic model's stature proxy (m): the vertical (y) extent of its markers at the
/// default pose.
pub fn marker_extent(model: &Model) -> f64 {
    let mut data = KinData::new(model);
    forward_kinematics(
        model,
        &model.nominal_params(),
        &model.default_coords(),
        Want::Positions,
        &mut data,
    );
    let ys = data.markers.iter().map(|m| m.y);
    let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
        (a.min(y), b.max(y))
    });
    (hi - lo).max(1e-3)
}

/// Output path next to the setup, when `path` is relative.
pub fn resolve(base: &Path, path: &Path) -> PathBuf {
    if path.is_absolute() {
        path.to_path_buf()
    } else {
        base.join(path)
    }
}

/// What the scaling did, for the record written beside the subject model.
pub fn record(req: &ScaleRequest, out: &ScaleOutcome) -> ScaleRecord {
    let show = |p: &Path| p.display().to_string();
    ScaleRecord {
        generic: show(&req.generic),
        static_trial: show(&req.static_trial),
        trials: req.trials.iter().map(|p| show(p)).collect(),
        groups: out
            .fit
            .groups
            .iter()
            .map(|g| RecordGroup {
                name: g.name.clone(),
                bodies: g.bodies.clone(),
                factors: g.factors,
                sd: g.sd,
            })
            .collect(),
        markers: out
            .fit
            .markers
            .iter()
            .map(|m| RecordMarker {
                name: m.name.clone(),
                body: m.body.clone(),
                moved_mm: m.moved.map(|d| d * 1000.0),
                rms_mm: m.rms.is_finite().then_some(m.rms * 1000.0),
            })
            .collect(),
        rms_mm: out.fit.rms * 1000.0,
        frames: out.frames,
        generic_mass: out.generic_mass,
        total_mass: out.total_mass,
        flags: out.flags.clone(),
    }
}
