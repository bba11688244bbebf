//! Tallies of the default entry point's extra steps (marker policy, anatomical envelope) and
//! of the RMS parameter errors per joint and unit, for the coverage example.

use std::collections::BTreeMap;

use jointfit::model::spec::Unit;
use jointfit::model::{Model, ParamId};
use jointfit::workflow::envelope::EnvelopeBound;
use jointfit::workflow::marker_policy::{MarkerAction, MarkerDecision};

pub const GROUPS: [&str; 3] = ["hip", "knee", "ankle"];

/// Squared errors per joint (hip, knee, ankle) and unit (mm, deg).
#[derive(Default, Clone)]
pub struct Errors {
    sq: [[f64; 2]; 3],
    n: [[usize; 2]; 3],
}

impl Errors {
    /// Adds the errors of the free parameters of one fit (`p` may be longer than the model's
    /// parameters: refined markers follow them).
    pub fn add(&mut self, model: &Model, free: &[ParamId], p: &[f64], truth: &[f64]) {
        for id in free {
            let par = &model.parameters()[id.0];
            let Some(g) = GROUPS.iter().position(|g| *g == par.group) else {
                continue;
            };
            let u = (par.unit == Unit::Radian) as usize;
            let e = jointfit_experiments::units::shown(p[id.0] - truth[id.0], par.unit);
            self.sq[g][u] += e * e;
            self.n[g][u] += 1;
        }
    }

    /// `RMS mm / RMS deg` of joint `g` ("-" where it has no such parameter).
    pub fn cell(&self, g: usize) -> String {
        let one = |u: usize| match self.n[g][u] {
            0 => "-".to_string(),
            n => format!("{:.2}", (self.sq[g][u] / n as f64).sqrt()),
        };
        format!("{} mm / {} deg", one(0), one(1))
    }
}

/// What the marker policy and the envelope did over the seeds.
#[derive(Default)]
pub struct Policy {
    pub trials: usize,
    trials_acted: usize,
    refined: usize,
    excluded: usize,
    /// Trials with a deliberately misplaced marker, and those in which it was refined.
    misplaced: usize,
    caught: usize,
    /// Refine/exclude decisions on markers that were not misplaced.
    false_decisions: usize,
    envelope_refits: usize,
    envelope_active: usize,
    /// Refits whose truth lies inside the envelope (the bound was not needed).
    envelope_truth_inside: usize,
    names: BTreeMap<String, usize>,
    /// `seed: decision` lines.
    lines: Vec<String>,
}

impl Policy {
    pub fn add(
        &mut self,
        seed: u64,
        decisions: &[MarkerDecision],
        envelope: &[EnvelopeBound],
        moved: Option<&str>,
        truth_mm: impl Fn(&str) -> f64,
    ) {
        self.trials += 1;
        self.trials_acted += !decisions.is_empty() as usize;
        for d in decisions {
            match d.action {
                MarkerAction::Refine => self.refined += 1,
                MarkerAction::Exclude => self.excluded += 1,
            }
            let right = moved == Some(d.marker.as_str()) && d.action == MarkerAction::Refine;
            self.false_decisions += !right as usize;
            self.lines.push(format!(
                "  seed {seed}: {} {:?} ({}) from trial {}: {} (offset {:.1} mm, spread {:.1} mm)",
                d.marker,
                d.action,
                d.segment,
                d.trial + 1,
                d.reason,
                d.offset * 1e3,
                d.spread * 1e3
            ));
            let key = format!("{} {:?}", d.marker, d.action).to_lowercase();
            *self.names.entry(key).or_default() += 1;
        }
        if let Some(m) = moved {
            self.misplaced += 1;
            self.caught += decisions
                .iter()
                .any(|d| d.marker == m && d.action == MarkerAction::Refine)
                as usize;
        }
        let refit = envelope.iter().any(|b| b.unbounded_fit.is_some());
        self.envelope_refits += refit as usize;
        self.envelope_truth_inside += (refit
            && envelope
                .iter()
                .all(|b| truth_mm(&b.parameter) <= b.limit * 1e3))
            as usize;
        self.envelope_active += envelope.iter().any(|b| b.active) as usize;
    }

    pub fn print(&self) {
        let names: Vec<String> = self.names.iter().map(|(k, n)| format!("{k} {n}")).collect();
        println!(
            "marker policy: {} of {} trials with a decision; {} refined, {} excluded; decisions on markers not misplaced: {} ({})",
            self.trials_acted,
            self.trials,
            self.refined,
            self.excluded,
            self.false_decisions,
            if names.is_empty() { "none".to_string() } else { names.join(", ") }
        );
        for l in &self.lines {
            println!("{l}");
        }
        if self.misplaced > 0 {
            println!(
                "misplaced marker refined in {} of {} trials",
                self.caught, self.misplaced
            );
        }
        println!(
            "anatomical envelope: refitted with the bound in {} of {} trials (truth inside the bound in {}), held on it in {}",
            self.envelope_refits, self.trials, self.envelope_truth_inside, self.envelope_active
        );
    }
}

/// One joint's tally: (joint, χ²/dof per trial, largest dof, τ̂ per trial, trials flagged).
type ConflictRow = (String, Vec<f64>, usize, Vec<f64>, usize);

/// The prior–data conflict statistics of the first fit (`workflow::conflict`), per joint.
#[derive(Default)]
pub struct Conflicts {
    rows: Vec<ConflictRow>,
}

impl Conflicts {
    pub fn add(&mut self, seed: u64, cs: &[jointfit::workflow::conflict::JointConflict]) {
        for c in cs {
            if std::env::var_os("COVERAGE_CONFLICT_TRACE").is_some() {
                eprintln!(
                    "conflict seed {seed} {} chi2 {:.2} dof {} p {:.2e} tau {:.3} flagged {}",
                    c.joint, c.chi2, c.dof, c.p_value, c.tau, c.flagged
                );
            }
            let row = match self.rows.iter().position(|r| r.0 == c.joint) {
                Some(i) => &mut self.rows[i],
                None => {
                    self.rows
                        .push((c.joint.clone(), Vec::new(), 0, Vec::new(), 0));
                    self.rows.last_mut().expect("pushed")
                }
            };
            row.1.push(c.chi2 / c.dof.max(1) as f64);
            row.2 = row.2.max(c.dof);
            row.3.push(c.tau);
            row.4 += c.flagged as usize;
        }
    }

    pub fn print(&self) {
        if self.rows.is_empty() {
            return;
        }
        println!("prior-data conflict (first fit), per joint: χ²/dof median [90th pct], max dof, τ median [90th pct], flagged");
        for (j, chi, dof, tau, w) in &self.rows {
            let q = |v: &[f64], f: f64| {
                let mut v = v.to_vec();
                v.sort_by(f64::total_cmp);
                v[((v.len() - 1) as f64 * f).round() as usize]
            };
            println!(
                "  {j:<11} {:>6.2} [{:>6.2}]  {dof}  {:>5.2} [{:>5.2}]  {w} of {}",
                q(chi, 0.5),
                q(chi, 0.9),
                q(tau, 0.5),
                q(tau, 0.9),
                chi.len()
            );
        }
    }
}
