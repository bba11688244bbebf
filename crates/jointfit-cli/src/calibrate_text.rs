//! The text output of `calibrate` (and `demo`): the parameter table, the summary of where
//! the information came from (with a prior) or the identifiability notes (without), the
//! anatomical checks and the marker errors.

use jointfit::calibrate::uncertainty::Identifiability;
use jointfit::calibrate::uncertainty::Uncertainty;
use jointfit::solver::Termination;
use jointfit::workflow::calibration::Calibration;
use jointfit_app::present::{mm, mm2, CalibrationShown};

/// The calibration's header line, parameter table and notes, in mm, degrees and mm².
pub fn print_report(report: &Calibration, seconds: f64, verbose: bool) {
    let shown = CalibrationShown::of(report);
    println!(
        "{}: {} free parameters, {} frames ({} skipped), {} iterations, {} evaluations, {:.3} s{}",
        report.method,
        report.free_parameters,
        report.frames,
        report.skipped_frames,
        report.iterations,
        report.evaluations,
        seconds,
        match report.termination {
            Termination::Converged => String::new(),
            t => format!(" (not converged: {t})"),
        }
    );
    if let Some(ms) = &shown.multistart {
        let lo = ms
            .objective_mm2
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let hi = ms
            .objective_mm2
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        println!(
            "{} starts: {} reached the best objective (to 1e-9); objectives {:.3} to {:.3} mm²; \
             kept start {}",
            ms.starts,
            ms.reached_best,
            lo,
            hi,
            report.best_start + 1
        );
        let mut wide: Vec<&(&str, f64)> = ms.spread.iter().filter(|(_, r)| *r > 0.1).collect();
        wide.sort_by(|a, b| b.1.total_cmp(&a.1));
        if !wide.is_empty() {
            let list: Vec<String> = wide
                .iter()
                .take(6)
                .map(|(n, r)| format!("{n} {r:.1}"))
                .collect();
            println!(
                "  largest spread of the optima over the starts (mm or deg): {}",
                list.join(", ")
            );
        }
    }
    if let Some(g) = &report.global {
        println!("{}", global_line(g));
    }
    // One vocabulary: with a prior, the last column says where the information came from
    // (the summary's "determined by the trial" / "partly" / "held by the prior"); without
    // one, whether the interval is within the thresholds (the paper's identifiability).
    let with_prior = report.prior_noise.is_some();
    let mut t = crate::table::Table::new(&[
        "group",
        "parameter",
        "unit",
        "start",
        "fitted",
        "change",
        "±95%",
        "95% CI",
        if with_prior {
            "information from"
        } else {
            "determined"
        },
    ]);
    for p in &shown.parameters {
        let hw = p.ci95.map(|c| 0.5 * (c[1] - c[0]));
        t.row(vec![
            p.group.to_string(),
            p.name.to_string(),
            p.unit.to_string(),
            format!("{:.2}", p.start),
            format!("{:.2}", p.fitted),
            format!("{:.2}", p.change),
            match (hw, &p.identifiability) {
                (Some(h), _) => format!("{h:.2}"),
                (None, Some(_)) => "∞".to_string(),
                (None, None) => "-".to_string(),
            },
            p.ci95
                .map_or("-".to_string(), |c| format!("[{:.2}, {:.2}]", c[0], c[1])),
            match (with_prior, p.source, p.identifiability) {
                (true, Some(src), _) => source_short(src).to_string(),
                (_, _, ident) => ident_short(ident).to_string(),
            },
        ]);
    }
    print!("{}", t.render());
    print_notes(report, &shown, verbose);
}

/// The verdict, last and plainly: `verdict: ok`, or the level and one reason per line.
pub fn print_verdict(verdict: &jointfit::workflow::verdict::Verdict) {
    println!("verdict: {}", verdict.level);
    for r in &verdict.reasons {
        println!("  - {r}");
    }
}

/// A `reject` verdict stops the command (exit status 5, nothing written) unless `accept`.
pub fn gate(verdict: &jointfit::workflow::verdict::Verdict, accept: bool) -> anyhow::Result<()> {
    match (verdict.level, accept) {
        (jointfit::workflow::verdict::Level::Reject, false) => Err(crate::output::Rejected(
            verdict.reasons.first().cloned().unwrap_or_default(),
        )
        .into()),
        _ => Ok(()),
    }
}

/// A calibration error as the command reports it: a trial refused as not belonging with the
/// model becomes [`crate::output::Rejected`] naming the trial's file.
pub fn refusal(e: jointfit_app::Error, trials: &[std::path::PathBuf]) -> anyhow::Error {
    let names: Vec<String> = trials.iter().map(|p| p.display().to_string()).collect();
    match jointfit_app::name_trial(e, &names) {
        jointfit_app::Error::Rejected(cause) => crate::output::Rejected(cause).into(),
        jointfit_app::Error::Calibrate(w) => {
            match jointfit_app::present::hint(&w, jointfit_app::present::Front::Cli) {
                Some(hint) => anyhow::anyhow!("{w} ({hint})"),
                None => w.into(),
            }
        }
        e => e.into(),
    }
}

/// The default marker policy's decisions and the anatomical envelope, one line each (before
/// the report: the RMS it prints is over the markers the fit used).
pub fn print_policy(
    decisions: &[jointfit::workflow::marker_policy::MarkerDecision],
    envelope: &[jointfit::workflow::envelope::EnvelopeBound],
) {
    for d in decisions {
        println!(
            "marker policy: {}",
            jointfit_app::present::marker_decision(d)
        );
    }
    if !decisions.is_empty() {
        println!(
            "marker policy: the marker RMS below is over the markers the fit used \
             (--keep-markers NAMES or --no-marker-policy to override)"
        );
    }
    for b in envelope.iter().filter(|b| !b.active) {
        if let Some(x) = b.unbounded_fit {
            println!(
                "{}: the fit without the anatomical envelope ended at {:.1} mm, lateral of the \
                 bound {:.1} mm (hip centre medial to the ASIS); refitted with the bound, it \
                 ends inside",
                b.parameter,
                mm(x),
                mm(b.limit)
            );
        }
    }
    for b in envelope.iter().filter(|b| b.active) {
        println!(
            "{}: {} (bound {:.1} mm = 0.9 × half the inter-ASIS width − 1 mm; --no-envelope \
             to lift it)",
            b.parameter,
            jointfit_app::present::held_at_limit(b),
            mm(b.limit)
        );
    }
}

/// The data-share class in the table's words.
fn source_short(s: jointfit::calibrate::prior::Source) -> &'static str {
    use jointfit::calibrate::prior::Source;
    match s {
        Source::DeterminedByTrial => "trial",
        Source::Partly => "trial + prior",
        Source::HeldByPrior => "prior",
        Source::HeldAtLimit => "anatomical limit",
    }
}

/// The identifiability class (no prior) in the table's words.
fn ident_short(i: Option<Identifiability>) -> &'static str {
    match i {
        Some(Identifiability::Determined) => "yes",
        Some(Identifiability::Poor) => "POOR",
        Some(Identifiability::Undetermined) => "NO",
        None => "-",
    }
}

/// What follows the table: the uncertainty notes or the prior's summary, plausibility, RMS.
fn print_notes(report: &Calibration, shown: &CalibrationShown, verbose: bool) {
    match (&report.uncertainty, shown.prior_noise_mm) {
        (Some(u), None) => print_uncertainty_notes(u, &report.fixed_unidentifiable, verbose),
        (_, Some(noise)) => print_prior_summary(report, noise),
        (None, None) => {}
    }
    // The anatomical checks that failed are reasons of the verdict, printed last.
    println!(
        "RMS marker distance: {:.2} mm before, {:.2} mm after ({:.0}% lower)",
        shown.rms_before_mm,
        shown.rms_after_mm,
        100.0 * (1.0 - shown.rms_after_mm / shown.rms_before_mm)
    );
    let mut t = crate::table::Table::new(&["marker", "before mm", "after mm"]);
    for ((name, b), (_, a)) in shown
        .marker_rms_before_mm
        .iter()
        .zip(&shown.marker_rms_after_mm)
    {
        // A marker with no sample in any solved frame (e.g. absent from the trial) has no RMS.
        let cell = |v: &f64| {
            if v.is_finite() {
                format!("{v:.2}")
            } else {
                "no data".to_string()
            }
        };
        t.row(vec![name.to_string(), cell(b), cell(a)]);
    }
    print!("{}", t.render());
}

/// With a prior: which parameters the trial determined, and the weighting noise.
fn print_prior_summary(report: &Calibration, noise_mm: f64) {
    println!(
        "maximum a posteriori fit: priors from the model file, marker noise σ = {noise_mm:.2} \
         mm ({}); intervals include the prior",
        if report.prior_noise_estimated {
            // σ carries the correlation factor κ (`workflow::map`): far above the marker RMS
            // on long, smooth trials, which the wording must not leave unexplained.
            "estimated from the residuals, inflated for their correlation over time"
        } else {
            "given"
        }
    );
    for line in information_summary(report) {
        println!("  {line}");
    }
}

/// The short summary of where the information came from (empty without a prior).
pub fn information_summary(report: &Calibration) -> Vec<String> {
    if report.prior_noise.is_none() {
        return Vec::new();
    }
    let rows: Vec<(String, String, Option<jointfit::calibrate::prior::Source>)> = report
        .parameters
        .iter()
        .map(|p| (p.group.clone(), p.name.clone(), p.source))
        .collect();
    crate::prior_args::summary(&rows)
}

/// How the intervals were made, the warnings for flagged parameters, the weak combinations.
fn print_uncertainty_notes(u: &Uncertainty, fixed: &[String], verbose: bool) {
    let mut methods: Vec<String> = Vec::new();
    for p in &u.params {
        let m = format!("{:?}", p.method).to_lowercase();
        if !methods.contains(&m) {
            methods.push(m);
        }
    }
    println!(
        "95% intervals: the widest of white-noise (σ = {:.2} mm, {} dof), Newey-West HAC (bandwidth {}){}{}; widest came from: {}",
        mm(u.sigma),
        u.dof,
        u.hac_bandwidth.map_or("-".into(), |b| format!("{b:.1} frames")),
        u.jackknife_blocks
            .map_or(String::new(), |k| format!(", {k}-block jackknife (t, {} dof)", k - 1)),
        u.bootstrap.as_ref().map_or(String::new(), |b| format!(
            ", block bootstrap ({} replicates of {}-frame blocks, seed {})",
            b.replicates, b.block_length, b.seed
        )),
        methods.join(", ")
    );
    if !verbose {
        print_flagged_by_joint(u);
    }
    for p in u.flagged().filter(|_| verbose) {
        // The status is judged by what the trial alone determines (pooled noise and time
        // correlation, `ParamUncertainty::status_half_width`), the interval is the robust one.
        let hw = match (p.status_half_width, p.half_width) {
            (Some(s), Some(h)) => {
                format!("trial alone ±{s:.1} {u}, interval ±{h:.1} {u}", u = p.unit)
            }
            (None, Some(h)) => format!("trial alone unbounded, interval ±{h:.1} {}", p.unit),
            (_, None) => "unbounded".to_string(),
        };
        println!(
            "{} {} by this trial ({hw}; threshold {} {}): {}",
            p.name,
            if p.status == Identifiability::Undetermined {
                "not determined"
            } else {
                "poorly determined"
            },
            if p.unit == "mm" {
                mm(u.threshold_m)
            } else {
                u.threshold_rad.to_degrees()
            },
            p.unit,
            p.reason.as_deref().unwrap_or("")
        );
    }
    for w in u.weak_directions.iter().filter(|_| verbose) {
        println!("weak combination: {}", w.description);
    }
    if !fixed.is_empty() {
        println!(
            "held at their starting values (--fix-unidentifiable): {}",
            fixed.join(", ")
        );
    } else if u.flagged().next().is_some() {
        println!("(rerun with --fix-unidentifiable to hold the flagged parameters at their starting values)");
    }
}

/// The flagged parameters, one line per joint (group): how many, and each one's interval
/// half-width; `--verbose` says why each one is flagged.
fn print_flagged_by_joint(u: &Uncertainty) {
    let mut groups: Vec<(String, Vec<String>, usize)> = Vec::new();
    for p in u.flagged() {
        let group = p.group.clone();
        let hw = p
            .half_width
            .map_or("unbounded".to_string(), |h| format!("±{h:.1} {}", p.unit));
        let item = format!("{} {hw}", p.name);
        let undetermined = usize::from(p.status == Identifiability::Undetermined);
        match groups.iter_mut().find(|g| g.0 == group) {
            Some(g) => {
                g.1.push(item);
                g.2 += undetermined;
            }
            None => groups.push((group, vec![item], undetermined)),
        }
    }
    for (group, items, undetermined) in &groups {
        println!(
            "{group}: {} parameter{} {} by this trial: {} (--verbose: why)",
            items.len(),
            if items.len() == 1 { "" } else { "s" },
            match *undetermined {
                0 => "poorly determined",
                n if n == items.len() => "not determined",
                _ => "poorly or not determined",
            },
            items.join(", ")
        );
    }
}

/// The global phase in words (`docs/global.md`): how many starts were tried and on what, which
/// were finished on every frame, their objectives, and whether they agree.
pub fn global_line(g: &jointfit::workflow::GlobalSearch) -> String {
    let name = |k: usize| {
        if k == 0 {
            "the given start".to_string()
        } else {
            format!("start {k}")
        }
    };
    let list: Vec<String> = g
        .finished
        .iter()
        .zip(&g.finished_objective)
        .map(|(&k, &c)| format!("{} {:.3} mm²", name(k), mm2(c)))
        .collect();
    let verdict = match (g.finished.len(), g.agree) {
        (1, _) => "the runner-up's short run ended within 1e-4 of it, so only it was finished",
        (_, true) => "they reached the same optimum",
        (_, false) => "they ended at different optima",
    };
    format!(
        "global search: {} starts (the given one and {} seeded random ones) each ran {} \
         iterations on {} frames; finished on every frame: {}; {verdict}",
        g.starts,
        g.starts.saturating_sub(1),
        g.probe_iterations,
        g.probe_frames,
        list.join(", "),
    )
}

#[cfg(test)]
mod tests {
    use jointfit::workflow::GlobalSearch;

    /// The line names the starts, the frames and the finished starts by role, and says
    /// whether they agree, in each of its three cases.
    #[test]
    fn global_line_reads_as_a_sentence() {
        let mut g = GlobalSearch {
            starts: 6,
            probe_iterations: 6,
            probe_frames: 25,
            probe_objective: vec![1e-6; 6],
            finished: vec![0],
            finished_objective: vec![0.059385843],
            agree: true,
        };
        assert_eq!(
            super::global_line(&g),
            "global search: 6 starts (the given one and 5 seeded random ones) each ran 6 \
             iterations on 25 frames; finished on every frame: the given start 59385.843 mm²; \
             the runner-up's short run ended within 1e-4 of it, so only it was finished"
        );
        g.finished = vec![3, 0];
        g.finished_objective = vec![1e-4, 1e-4];
        let line = super::global_line(&g);
        assert!(
            line.contains("start 3 100.000 mm², the given start 100.000 mm²; they reached"),
            "{line}"
        );
        g.agree = false;
        assert!(super::global_line(&g).ends_with("different optima"));
    }
}
