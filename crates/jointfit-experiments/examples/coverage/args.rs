//! Command-line options of the coverage example, and the seeded truths it draws.

use jointfit::calibrate::uncertainty::UncertaintyOptions;
use jointfit::model::spec::ModelSpec;
use jointfit::workflow::Method;
use jointfit_experiments::synth::Motion;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub struct Args {
    pub seeds: u64,
    pub frames: usize,
    pub motion: Motion,
    pub noise_mm: f64,
    pub replicates: usize,
    pub first_seed: u64,
    pub bandwidth: Option<f64>,
    pub blocks: usize,
    /// `Some((mm, deg))`: truth = nominal moved by up to these (the hard cases).
    pub perturb: Option<(f64, f64)>,
    pub joints: String,
    /// Per (seed, parameter) rows as CSV for offline analysis.
    pub dump: Option<String>,
    /// Landmark priors on the parameters, truth drawn from them.
    pub prior: bool,
    /// The command's default entry point: landmark priors in the model (as `personalize`
    /// writes them) and `workflow::refine::calibrate_refined` with the default settings
    /// (marker policy and anatomical envelope).
    pub default: bool,
    /// Also fit each trial with `--prior none` (the unregularized fit, no uncertainty
    /// analysis) and print both fits' RMS parameter errors per joint.
    pub compare_none: bool,
    /// One thigh or shank marker (seeded) moved this far (mm, seeded direction) since the
    /// static trial: the trial is synthesized with it moved, the model keeps its place.
    pub misplace_mm: f64,
    /// With `--default`: the marker policy and the anatomical envelope off (`--no-policy`,
    /// `--no-envelope`).
    pub no_policy: bool,
    pub no_envelope: bool,
    /// With `--default`: the prior–data conflict step off (`--no-conflict`).
    pub no_conflict: bool,
    /// The solver (`joint`, `varpro`, `pso`).
    pub method: Method,
    /// `--landmark-error`: the fit starts from the subject's landmark model, whose prior means
    /// are the truth moved by the landmark method's published error (`N(truth, sd²)`, seeded,
    /// clipped to the bounds), instead of from the nominal model with the nominal as the prior
    /// mean.
    pub landmark_error: bool,
}

pub fn parse() -> Result<Args, String> {
    let mut a = Args {
        seeds: 50,
        frames: 100,
        motion: Motion::All,
        noise_mm: 10.0,
        replicates: 0,
        first_seed: 1,
        bandwidth: None,
        blocks: UncertaintyOptions::default().jackknife_blocks,
        perturb: None,
        joints: "all".to_string(),
        dump: None,
        prior: false,
        default: false,
        compare_none: false,
        misplace_mm: 0.0,
        method: Method::Joint,
        no_policy: false,
        no_envelope: false,
        no_conflict: false,
        landmark_error: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        match flag.as_str() {
            "--prior" => a.prior = true,
            "--default" => a.default = true,
            "--compare-none" => a.compare_none = true,
            "--no-policy" => a.no_policy = true,
            "--no-envelope" => a.no_envelope = true,
            "--no-conflict" => a.no_conflict = true,
            "--landmark-error" => a.landmark_error = true,
            _ => {}
        }
        let switches = [
            "--prior",
            "--default",
            "--compare-none",
            "--no-policy",
            "--no-envelope",
            "--no-conflict",
            "--landmark-error",
        ];
        if switches.contains(&flag.as_str()) {
            continue;
        }
        let v = it.next().ok_or(format!("{flag} needs a value"))?;
        let bad = |e: &dyn std::fmt::Display| format!("{flag} {v}: {e}");
        match flag.as_str() {
            "--seeds" => a.seeds = v.parse().map_err(|e| bad(&e))?,
            "--frames" => a.frames = v.parse().map_err(|e| bad(&e))?,
            "--motion" => a.motion = v.parse().map_err(|e| bad(&e))?,
            "--noise-mm" => a.noise_mm = v.parse().map_err(|e| bad(&e))?,
            "--replicates" => a.replicates = v.parse().map_err(|e| bad(&e))?,
            "--blocks" => a.blocks = v.parse().map_err(|e| bad(&e))?,
            "--bandwidth" => a.bandwidth = Some(v.parse().map_err(|e| bad(&e))?),
            "--first-seed" => a.first_seed = v.parse().map_err(|e| bad(&e))?,
            "--joints" => a.joints = v.clone(),
            "--dump" => a.dump = Some(v.clone()),
            "--method" => a.method = v.parse().map_err(|e| bad(&e))?,
            "--misplace-mm" => a.misplace_mm = v.parse().map_err(|e| bad(&e))?,
            "--perturb" => {
                let (mm, deg) = v.split_once(',').ok_or(format!("{flag} MM,DEG"))?;
                a.perturb = Some((
                    mm.parse().map_err(|e| bad(&e))?,
                    deg.parse().map_err(|e| bad(&e))?,
                ));
            }
            _ => return Err(format!("unknown option {flag}")),
        }
    }
    Ok(a)
}

/// The model the trial of seed `seed` is synthesized from: `spec` with one thigh or shank
/// marker (seeded) moved `mm` in a seeded direction of its segment frame (the marker's name
/// returned), or `spec` unchanged when `mm` is 0.
pub fn misplaced(spec: &ModelSpec, mm: f64, seed: u64) -> (ModelSpec, Option<String>) {
    let mut t = spec.clone();
    if mm <= 0.0 {
        return (t, None);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(50_000 + seed);
    let candidates: Vec<usize> = (0..t.markers.len())
        .filter(|&j| ["thigh", "shank"].contains(&t.markers[j].segment.as_str()))
        .collect();
    let j = candidates[rng.gen_range(0..candidates.len())];
    let u: [f64; 3] = [(); 3].map(|_| rng.gen_range(-1.0..1.0));
    let norm = u.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
    for (x, uk) in t.markers[j].position.iter_mut().zip(u) {
        *x += mm / 1e3 * uk / norm;
    }
    let name = t.markers[j].name.clone();
    (t, Some(name))
}
