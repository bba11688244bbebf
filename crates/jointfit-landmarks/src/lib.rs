//! The anatomical-landmark method: a static trial and a marker set → a subject's leg model.
//!
//! This gives the *nominal* joint parameters that Reinbolt et al. 2005 (J Biomech 38:621–626,
//! doi:10.1016/j.jbiomech.2004.03.031) start the two-level optimization from, the bounds of
//! their search, and the tracking markers' coordinates in their segments.
//!
//! ## Steps
//! 1. **Window.** Consecutive frames in which every needed marker is present; among those of
//!    the requested length (default 1 s; shortened to the longest complete run), the one with
//!    the least marker motion ([`window`]). Markers are averaged over it.
//! 2. **Frames** (docs/architecture.md §6), from the averaged markers only, so the laboratory
//!    heading is irrelevant (the trial must be Y-up): pelvis (mid-ASIS; z left → right ASIS;
//!    x anterior in the plane of the ASIS and mid-PSIS or sacrum), thigh (hip centre; y knee
//!    centre → hip centre; z epicondyles made orthogonal), shank (knee centre; y ankle centre
//!    → knee centre; z malleoli made orthogonal), foot (heel; x heel → forefoot; z the shank's
//!    z made orthogonal). z points to the model's right on both legs.
//! 3. **Joints.** Hip centre by regression on the inter-ASIS width PW, in the pelvis frame from
//!    mid-ASIS: Bell, Pedersen & Brand 1990 (J Biomech 23:617–621): (−0.19, −0.30, ±0.36)·PW; or Harrington et al. 2007 (J Biomech 40:595–602,
//!    doi:10.1016/j.jbiomech.2006.02.003), with pelvic depth PD (mid-ASIS to mid-PSIS):
//!    (−0.24·PD − 9.9 mm, −0.30·PW − 10.9 mm, ±(0.33·PW + 7.3 mm)). Knee axis: the epicondyle
//!    line through the mid-epicondyle point (Churchill et al. 1998). Talocrural axis: the
//!    malleolus line through the mid-malleolus point. Subtalar axis: Inman 1976's means,
//!    42° elevation and 23° medial deviation in the foot frame, on the common perpendicular of
//!    the two axes at 12.4 mm from the ankle centre (Reinbolt's Table 2). The talus frame has
//!    its origin at the ankle centre, z along the talocrural axis and y along the common
//!    perpendicular, pointing away from the subtalar axis.
//! 4. **Model.** The offsets of every joint are read off these frames ([`nominal`]) and written
//!    into the template [`lower_limb`] (names, structure, left-leg mirroring); the fixed
//!    talocrural `rz` levels the foot at zero coordinates. Bounds follow Reinbolt's thesis:
//!    hip centre in a cube of side 0.75·PW, knee positions in a cube of side knee width,
//!    ankle positions in a cube of side inter-malleolar distance, every axis ±30°.
//! 5. **Check.** The static-pose coordinates are the joint motions between the frames; forward
//!    kinematics at that pose reproduces every tracking marker of the averaged frame (the
//!    report's `static_fk_error`, ~1e-15 m). The report also gives, per segment, the residual
//!    of a rigid fit of its markers to each frame of the window (how rigid the cluster stayed).
//!
//! ## Choices where the sources leave room
//! - *Talus y direction.* Along the common perpendicular, pointing away from the subtalar
//!   axis (superior-posterior), so that `subtalar_talus_superior` is −12.4 mm and
//!   `subtalar_talus_transverse` comes out at 25–42° on real data, as in Reinbolt's Table 2
//!   (−12.40 mm, 26.89°). Pointing it toward the subtalar axis would flip both.
//! - *Where the subtalar axis passes.* The template's talus origin is the talocrural joint
//!   centre, so the common perpendicular starts at the mid-malleolus point; 12.4 mm along it
//!   (inferior and anterior, at the subtalar elevation from vertical) is ~8.5 mm below and
//!   ~8.3 mm in front of the ankle centre.
//! - *Zero of the ankle.* The fixed talocrural `rz` follows the template: with every coordinate
//!   0 the foot's long axis is horizontal in the pelvis frame. Standing therefore reads the
//!   shank's forward lean relative to the pelvis as dorsiflexion (0–20° on the real trials).
//! - *Zero of the subtalar joint* is not free: the talus frame is fixed by the two axes and
//!   the foot-side offset holds Inman's angles, so standing reads 6–24° of "inversion" on the
//!   real trials. It is an offset of the coordinate, not a posture.
//! - *Hip regressions* use the skin-marker positions as the bony landmarks (no marker-radius
//!   or soft-tissue correction).
//!
//! [`lower_limb`]: jointfit::model::lower_limb::lower_limb

pub mod auto;
pub mod bilateral;
mod error;
pub(crate) mod frames;
pub mod functional;
pub mod keypoints;
pub mod markerset;
use markerset::{LegMarkers, MarkerSet};
pub mod motion;
pub(crate) mod nominal;
pub(crate) mod plugin_gait;
pub mod subject;
pub mod suggest;
pub(crate) mod window;

use nalgebra::Vector3;

pub use error::LandmarkError;
pub use frames::SegmentFrames;
pub(crate) use markerset::MedialLandmark;
pub(crate) use markerset::TRACKED_SEGMENTS;
use subject::SubjectMeasurements;
pub use window::StaticWindow;

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::population::fill_landmark_priors;
pub use jointfit::model::population::HipCentreMethod;
use jointfit::model::spec::{MarkerSpec, ModelSpec};
use jointfit::model::Model;
use jointfit::spatial::Pose;
use jointfit::trial::Trial;

/// Settings of [`personalize`] (SI units).
#[derive(Debug, Clone, PartialEq)]
pub struct PersonalizeOptions {
    pub hip_centre: HipCentreMethod,
    /// Length of the averaged window (s); shortened to the longest run of complete frames.
    pub window_seconds: f64,
    /// Distance of the subtalar axis from the ankle centre along the common perpendicular (m).
    pub subtalar_offset: f64,
    /// Subtalar axis elevation above the foot's long axis (rad; Inman: 42°).
    pub subtalar_elevation: f64,
    /// Subtalar axis medial deviation from the foot's long axis (rad; Inman: 23°).
    pub subtalar_deviation: f64,
    /// Tracking markers of a segment all within this distance of one line are refused (m).
    pub min_marker_spread: f64,
    /// Name of the model written into the description.
    pub name: String,
    /// The subject's measurements: what [`HipCentreMethod::Davis`] and Plug-in Gait's chord
    /// function (a marker set's `chord:WAND` medial landmark) need.
    pub subject: SubjectMeasurements,
}

impl Default for PersonalizeOptions {
    fn default() -> Self {
        PersonalizeOptions {
            hip_centre: HipCentreMethod::Bell,
            window_seconds: 1.0,
            subtalar_offset: 0.0124,
            subtalar_elevation: 42f64.to_radians(),
            subtalar_deviation: 23f64.to_radians(),
            min_marker_spread: 0.005,
            name: "subject".into(),
            subject: SubjectMeasurements::default(),
        }
    }
}

/// Residual of the rigid fit of one segment's tracking markers over the window.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentResidual {
    pub segment: String,
    pub markers: Vec<String>,
    /// RMS over markers and window frames of the distance to the rigidly fitted markers (m).
    pub rms: f64,
    /// Largest such distance (m).
    pub max: f64,
}

/// What [`personalize`] measured and used. Lengths in m; points in the trial frame.
#[derive(Debug, Clone, PartialEq)]
pub struct PersonalizeReport {
    pub window: StaticWindow,
    /// The regression of the hip centre; unused when `hip_from_keypoint`.
    pub hip_method: HipCentreMethod,
    /// Whether the hip centre is a video keypoint ([`keypoints`]) rather than a regression.
    pub hip_from_keypoint: bool,
    /// Inter-ASIS distance PW.
    pub pelvis_width: f64,
    /// Mid-ASIS to mid-PSIS (or sacrum) distance PD.
    pub pelvis_depth: f64,
    /// Distance between the epicondyle markers.
    pub knee_width: f64,
    /// Distance between the malleolus markers.
    pub ankle_width: f64,
    /// Hip centre to knee centre.
    pub thigh_length: f64,
    /// Knee centre to ankle centre.
    pub shank_length: f64,
    pub hip_centre: Vector3<f64>,
    pub knee_centre: Vector3<f64>,
    pub ankle_centre: Vector3<f64>,
    /// Pelvis, thigh, shank, foot.
    pub segments: Vec<SegmentResidual>,
    /// Largest distance between a tracking marker of the averaged frame and the model's
    /// marker at the static pose (m): ~1e-15 unless something is wrong.
    pub static_fk_error: f64,
    /// Functional hip centre / knee axis, when functional trials were given.
    pub functional: Option<functional::apply::FunctionalReport>,
}

/// The result of [`personalize`].
#[derive(Debug, Clone)]
pub struct Personalized {
    /// The subject's model: the template's structure with this subject's nominal parameters,
    /// bounds, fixed talus levelling and tracking markers.
    pub spec: ModelSpec,
    /// Coordinates of the averaged static pose (model order, rad and m).
    pub static_q: Vec<f64>,
    /// Segment frames at the averaged static pose.
    pub frames: SegmentFrames,
    pub report: PersonalizeReport,
}

fn check_options(o: &PersonalizeOptions) -> Result<(), LandmarkError> {
    let bad = |what: &str, v: f64| Err(LandmarkError::InvalidOption(format!("{what} = {v}")));
    if !(o.window_seconds.is_finite() && o.window_seconds > 0.0) {
        return bad("window_seconds", o.window_seconds);
    }
    if !(o.subtalar_offset.is_finite() && o.subtalar_offset >= 0.0) {
        return bad("subtalar_offset", o.subtalar_offset);
    }
    for (w, v) in [
        ("subtalar_elevation", o.subtalar_elevation),
        ("subtalar_deviation", o.subtalar_deviation),
    ] {
        if !(v.is_finite() && v.abs() < std::f64::consts::FRAC_PI_2) {
            return bad(w, v);
        }
    }
    if !(o.min_marker_spread.is_finite() && o.min_marker_spread >= 0.0) {
        return bad("min_marker_spread", o.min_marker_spread);
    }
    Ok(())
}

/// Builds a subject's leg model from a static trial (see the module docs). The trial must be
/// in metres and Y-up ([`jointfit::spatial::up_axis_rotation`]); its heading does not matter.
pub fn personalize(
    trial: &Trial,
    set: &MarkerSet,
    side: Side,
    opts: &PersonalizeOptions,
) -> Result<Personalized, LandmarkError> {
    personalize_with(
        trial,
        set,
        side,
        opts,
        &functional::apply::FunctionalTrials::default(),
    )
}

/// [`personalize`] with the hip centre (SCoRE) and/or knee axis (SARA) taken from
/// functional trials ([`functional`]); their bootstrap spread sets those parameters' prior
/// SDs, the landmark table the others' ([`priors`]).
pub(crate) fn personalize_with(
    trial: &Trial,
    set: &MarkerSet,
    side: Side,
    opts: &PersonalizeOptions,
    func: &functional::apply::FunctionalTrials,
) -> Result<Personalized, LandmarkError> {
    personalize_in(trial, set, side, opts, func, None)
}

/// [`personalize_with`] averaging the landmarks over `window` (every marker of the leg must be
/// present in all its frames) instead of the leg's own stillest window: how
/// [`personalize_sides`](bilateral::personalize_sides) gives both legs one pelvis.
pub fn personalize_in(
    trial: &Trial,
    set: &MarkerSet,
    side: Side,
    opts: &PersonalizeOptions,
    func: &functional::apply::FunctionalTrials,
    window: Option<&StaticWindow>,
) -> Result<Personalized, LandmarkError> {
    check_options(opts)?;
    set.validate()?;
    let set = &set.resolve(trial.labels());
    let leg = set.leg(side)?;
    let mut tracking: Vec<(&'static str, Vec<String>)> = Vec::new();
    for seg in TRACKED_SEGMENTS {
        tracking.push((seg, set.tracking(side, seg)?.to_vec()));
    }
    let plan = Plan {
        set_name: &set.name,
        roles: set.roles(side)?,
        tracking,
        weights: Vec::new(),
    };
    personalize_plan(trial, &plan, side, opts, func, window, |at| {
        landmarks_of(set, leg, side, opts, at)
    })
}

/// What a marker set or keypoint set gives the shared personalization: the labels with
/// their roles, the tracking markers per segment, and (through a closure) the landmarks.
pub(crate) struct Plan<'a> {
    pub set_name: &'a str,
    /// (role, label) pairs, landmarks first.
    pub roles: Vec<(String, String)>,
    /// Tracking markers of each of [`TRACKED_SEGMENTS`], in that order.
    pub tracking: Vec<(&'static str, Vec<String>)>,
    /// Weights of model markers other than 1 (label, weight).
    pub weights: Vec<(String, f64)>,
}

impl Plan<'_> {
    fn tracking(&self, seg: &str) -> &[String] {
        self.tracking
            .iter()
            .find(|(s, _)| *s == seg)
            .map_or(&[], |(_, l)| l.as_slice())
    }
}

/// The landmarks of a marker set's leg from the averaged markers `at`.
fn landmarks_of(
    set: &MarkerSet,
    leg: &LegMarkers,
    side: Side,
    opts: &PersonalizeOptions,
    at: &dyn Fn(&str) -> Vector3<f64>,
) -> Result<frames::Landmarks, LandmarkError> {
    let side_name = markerset::side_name(side);
    let p = &set.pelvis;
    let back = match (&p.right_psis, &p.left_psis, &p.sacrum) {
        (Some(r), Some(l), _) => 0.5 * (at(r) + at(l)),
        (_, _, Some(s)) => at(s),
        _ => unreachable!("validated marker set"),
    };
    let forefoot: Vector3<f64> =
        leg.forefoot.iter().map(|l| at(l)).sum::<Vector3<f64>>() / leg.forefoot.len() as f64;
    let radius = 0.5 * opts.subject.marker_diameter_or_default();
    let medial = |label: &str, width: Option<f64>, what: &str| {
        Ok::<_, LandmarkError>(match MedialLandmark::parse(label) {
            MedialLandmark::Marker(l) => frames::Medial::Marker(at(l)),
            MedialLandmark::Chord { wand } => {
                let width = width.ok_or_else(|| LandmarkError::MissingMeasurement {
                    what: format!("{side_name} {what} width"),
                    why: format!(
                        "the {side_name} {what} centre by Plug-in Gait's chord function \
                         (marker set {:?} has no medial {what} marker)",
                        set.name
                    ),
                })?;
                frames::Medial::Chord {
                    wand: at(wand),
                    delta: 0.5 * width + radius,
                }
            }
        })
    };
    let lm = frames::Landmarks {
        r_asis: at(&p.right_asis),
        l_asis: at(&p.left_asis),
        back,
        lat_epicondyle: at(&leg.lateral_epicondyle),
        med_epicondyle: medial(
            &leg.medial_epicondyle,
            opts.subject.knee_width(side),
            "knee",
        )?,
        lat_malleolus: at(&leg.lateral_malleolus),
        med_malleolus: medial(
            &leg.medial_malleolus,
            opts.subject.ankle_width(side),
            "ankle",
        )?,
        heel: at(&leg.heel),
        forefoot,
        hip_centre: None,
    };
    Ok(lm)
}

/// The shared personalization of one leg (see the module docs): the window, the averaged
/// labels, the landmarks `landmarks` builds from them, and the model.
pub(crate) fn personalize_plan(
    trial: &Trial,
    plan: &Plan,
    side: Side,
    opts: &PersonalizeOptions,
    func: &functional::apply::FunctionalTrials,
    window: Option<&StaticWindow>,
    landmarks: impl Fn(&dyn Fn(&str) -> Vector3<f64>) -> Result<frames::Landmarks, LandmarkError>,
) -> Result<Personalized, LandmarkError> {
    let (names, columns) = plan_columns(trial, plan, side)?;
    let wanted = (opts.window_seconds * trial.rate()).round().max(1.0) as usize;
    let win = match window {
        Some(w) => window::check_window(trial, &columns, &names, w)?,
        None => window::select_window(trial, &columns, &names, wanted)?,
    };
    let means = window::window_means(trial, &columns, &win);
    let idx = |label: &str| {
        names
            .iter()
            .position(|n| n == label)
            .expect("resolved label")
    };
    let at = |label: &str| means[idx(label)];
    let lm = landmarks(&at)?;
    let lm_hip_given = lm.hip_centre.is_some();
    check_spreads(plan, &at, opts)?;
    let mut an = frames::anatomy(&lm, side, opts)?;
    let cluster = |seg: &str| -> Result<functional::Cluster, LandmarkError> {
        let labels = plan.tracking(seg).to_vec();
        let reference = labels.iter().map(|l| at(l)).collect();
        Ok(functional::Cluster {
            segment: seg.to_string(),
            labels,
            reference,
        })
    };
    let (functional_report, functional_sds) = if func.hip.is_some() || func.knee.is_some() {
        let (r, sds) = functional::apply::apply(&mut an, &cluster, func)?;
        (Some(r), sds)
    } else {
        (None, Vec::new())
    };
    let offsets = nominal::offsets(&an, side)?;
    let poses = named_poses(&an.frames);
    let mut spec = leg_spec(
        plan,
        side,
        opts,
        &an,
        &offsets,
        &functional_sds,
        &poses,
        &at,
    );
    let hip = if lm_hip_given {
        "the hip keypoint"
    } else {
        opts.hip_centre.citation()
    };
    spec.description = describe(trial, plan, side, &win, hip, an.pelvis_width);
    let model = Model::compile(&spec).map_err(LandmarkError::Model)?;
    let static_q = nominal::static_coordinates(&model, &offsets, &poses)?;
    let static_fk_error = static_fk_error(&model, &static_q, &at);
    let cols =
        |seg: &str| -> Vec<usize> { plan.tracking(seg).iter().map(|l| columns[idx(l)]).collect() };
    let segments = tracking_residuals(trial, plan, &spec, &cols, &win);
    let report = PersonalizeReport {
        window: win,
        hip_method: opts.hip_centre,
        hip_from_keypoint: lm_hip_given,
        pelvis_width: an.pelvis_width,
        pelvis_depth: an.pelvis_depth,
        knee_width: an.knee_width,
        ankle_width: an.ankle_width,
        thigh_length: (an.hip_centre - an.knee_centre).norm(),
        shank_length: (an.knee_centre - an.ankle_centre).norm(),
        hip_centre: functional_report
            .as_ref()
            .and_then(|r| r.hip.as_ref())
            .map_or(an.hip_centre, |h| h.centre),
        knee_centre: an.knee_centre,
        ankle_centre: an.ankle_centre,
        segments,
        static_fk_error,
        functional: functional_report,
    };
    Ok(Personalized {
        spec,
        static_q,
        frames: an.frames,
        report,
    })
}

/// Refuses a segment whose (at least three) tracking markers lie near one line; two markers
/// always do, and the joint fixes the rotation about it.
fn check_spreads(
    plan: &Plan,
    at: &dyn Fn(&str) -> Vector3<f64>,
    opts: &PersonalizeOptions,
) -> Result<(), LandmarkError> {
    for seg in TRACKED_SEGMENTS {
        let list = plan.tracking(seg);
        let pts: Vec<_> = list.iter().map(|l| at(l)).collect();
        if list.len() >= 3 {
            frames::check_spread(seg, list, &pts, opts.min_marker_spread)?;
        }
    }
    Ok(())
}

/// The segment frames at the static pose, by segment name.
fn named_poses(f: &SegmentFrames) -> [(&'static str, Pose); 5] {
    [
        ("pelvis", f.pelvis),
        ("thigh", f.thigh),
        ("shank", f.shank),
        ("talus", f.talus),
        ("foot", f.foot),
    ]
}

/// The plan's labels in first-use order and their columns in `trial`; an error naming every
/// label the trial lacks, with its roles.
fn plan_columns(
    trial: &Trial,
    plan: &Plan,
    side: Side,
) -> Result<(Vec<String>, Vec<usize>), LandmarkError> {
    // Labels in first-use order, each with its roles.
    let mut labels: Vec<(String, Vec<String>)> = Vec::new();
    for (role, label) in plan.roles.iter().cloned() {
        match labels.iter_mut().find(|(l, _)| *l == label) {
            Some((_, roles)) => roles.push(role),
            None => labels.push((label, vec![role])),
        }
    }
    let mut columns = Vec::with_capacity(labels.len());
    let mut missing = Vec::new();
    for (label, roles) in &labels {
        match trial.labels().iter().position(|l| l == label) {
            Some(c) => columns.push(c),
            None => missing.push(format!("{} {label:?}", roles.join(" and "))),
        }
    }
    if !missing.is_empty() {
        return Err(LandmarkError::MissingMarkers {
            set: plan.set_name.to_string(),
            side: markerset::side_name(side),
            missing,
            available: trial.labels().join(", "),
        });
    }
    Ok((labels.into_iter().map(|(l, _)| l).collect(), columns))
}

/// The leg's description: the sample leg with the subject's offsets, bounds and priors
/// (functional SDs where a functional trial gave them) and the tracking markers in their
/// segments' frames at the static pose (`at`: a label's mean position in the window).
#[allow(clippy::too_many_arguments)]
fn leg_spec(
    plan: &Plan,
    side: Side,
    opts: &PersonalizeOptions,
    an: &frames::Anatomy,
    offsets: &nominal::Offsets,
    functional_sds: &[(&str, f64)],
    poses: &[(&str, Pose); 5],
    at: &dyn Fn(&str) -> Vector3<f64>,
) -> ModelSpec {
    let mut spec = lower_limb(side);
    nominal::fill_offsets(&mut spec, offsets);
    nominal::set_bounds(&mut spec, an);
    for (name, sd) in functional_sds {
        if let Some(p) = spec.parameters.iter_mut().find(|p| p.name == *name) {
            p.prior_sd = Some(*sd);
        }
    }
    fill_landmark_priors(&mut spec, opts.hip_centre);
    let pose_of = |seg: &str| poses.iter().find(|(n, _)| *n == seg).expect("segment").1;
    spec.markers.clear();
    for seg in TRACKED_SEGMENTS {
        let inv = pose_of(seg).inverse();
        for l in plan.tracking(seg) {
            let x = inv.transform_point(&at(l));
            spec.markers.push(MarkerSpec {
                name: l.clone(),
                segment: seg.into(),
                position: [x.x, x.y, x.z],
                weight: plan
                    .weights
                    .iter()
                    .find(|(n, _)| n == l)
                    .map_or(1.0, |(_, w)| *w),
            });
        }
    }
    spec.name = opts.name.clone();
    spec
}

/// The description of a personalized leg: marker set, static window, hip centre method
/// (`hip`) and pelvis width.
fn describe(
    trial: &Trial,
    plan: &Plan,
    side: Side,
    win: &StaticWindow,
    hip: &str,
    pelvis_width: f64,
) -> String {
    format!(
        "{} leg personalized by the anatomical-landmark method (marker set {:?}; static frames \
         {}–{} of {}, t = {:.3}–{:.3} s; hip centre {}; PW {:.1} mm)",
        markerset::side_name(side),
        plan.set_name,
        win.first,
        win.end() - 1,
        win.total_frames,
        trial.time(win.first),
        trial.time(win.end() - 1),
        hip,
        pelvis_width * 1e3
    )
}

/// The largest distance between a model marker at the static pose and its mean position in
/// the window (`at`).
fn static_fk_error(model: &Model, static_q: &[f64], at: &dyn Fn(&str) -> Vector3<f64>) -> f64 {
    let mut kin = KinData::new(model);
    forward_kinematics(
        model,
        &model.nominal_params(),
        static_q,
        Want::Positions,
        &mut kin,
    );
    model
        .markers()
        .iter()
        .zip(&kin.markers)
        .map(|(m, x)| (x - at(&m.name)).norm())
        .fold(0.0, f64::max)
}

/// Per tracked segment, how rigidly its markers (`cols`: their trial columns) moved in the
/// window: RMS and largest distance of each frame's markers from their rigid fit.
fn tracking_residuals(
    trial: &Trial,
    plan: &Plan,
    spec: &ModelSpec,
    cols: &dyn Fn(&str) -> Vec<usize>,
    win: &StaticWindow,
) -> Vec<SegmentResidual> {
    let mut segments = Vec::new();
    for seg in TRACKED_SEGMENTS {
        let local: Vec<Vector3<f64>> = spec
            .markers
            .iter()
            .filter(|m| m.segment == seg)
            .map(|m| Vector3::from(m.position))
            .collect();
        let cols = cols(seg);
        let (mut sum2, mut max, mut n) = (0.0, 0.0f64, 0usize);
        for fr in win.first..win.end() {
            let world: Vec<_> = cols
                .iter()
                .map(|&c| trial.get(fr, c).expect("complete frame"))
                .collect();
            let fit = jointfit::spatial::rigid_fit(&local, &world);
            for (l, w) in local.iter().zip(&world) {
                let d = (fit.transform_point(l) - w).norm();
                sum2 += d * d;
                max = max.max(d);
                n += 1;
            }
        }
        segments.push(SegmentResidual {
            segment: seg.into(),
            markers: plan.tracking(seg).to_vec(),
            rms: (sum2 / n as f64).sqrt(),
            max,
        });
    }
    segments
}
