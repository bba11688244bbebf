//! The cluster and swap checks of one segment's markers (see the module docs of
//! [`crate::checks`]).

use nalgebra::Vector3;

use super::{runs, CheckKind, Ctx, Finding, Severity, CLUSTER_TOLERANCE, SWAP_MIN_ASYMMETRY};

/// The distances of one segment's `m` markers in each of `n` frames against the subject
/// model's, computed once for the cluster and swap checks.
struct Distances {
    m: usize,
    n: usize,
    /// Every marker pair in every frame (NaN when one is missing): `d[(f * m + i) * m + k]`.
    d: Vec<f64>,
    /// The model's distances: `r[i * m + k]`.
    r: Vec<f64>,
    /// Frames in which every marker of the segment is present.
    complete: Vec<bool>,
    /// Per complete frame and marker, its distance misfit to the segment's other markers,
    /// `E_i = Σ_{c ≠ i} |d_ic − r_ic|` (for the swap test's bound): `misfit[f * m + i]`.
    misfit: Vec<f64>,
}

impl Distances {
    fn d(&self, f: usize, i: usize, k: usize) -> f64 {
        self.d[(f * self.m + i) * self.m + k]
    }

    fn r(&self, i: usize, k: usize) -> f64 {
        self.r[i * self.m + k]
    }

    /// The swap test of markers `i` and `k` in frame `f` against the markers not
    /// `excluded`: `Some(crossed / plain)` when it reads as a swap.
    fn test(&self, i: usize, k: usize, f: usize, excluded: &[bool]) -> Option<f64> {
        if !self.d(f, i, k).is_finite() {
            return None;
        }
        let (mut plain, mut crossed, mut asymmetry, mut count) = (0.0, 0.0, 0.0, 0usize);
        for c in (0..self.m).filter(|&c| c != i && c != k && !excluded[c]) {
            let (dac, dbc) = (self.d(f, i, c), self.d(f, k, c));
            if !dac.is_finite() {
                continue;
            }
            let (rac, rbc) = (self.r(i, c), self.r(k, c));
            plain += (dac - rac).abs() + (dbc - rbc).abs();
            crossed += (dbc - rac).abs() + (dac - rbc).abs();
            asymmetry += (rac - rbc).abs();
            count += 1;
        }
        (count > 0
            && asymmetry >= SWAP_MIN_ASYMMETRY * count as f64
            && plain > 0.02 * count as f64
            && crossed < 0.3 * plain)
            .then_some(crossed / plain)
    }

    /// Every pair's swap test in every frame, alone.
    fn swap_flags(&self, pairs: &[(usize, usize)]) -> Vec<Vec<Option<f64>>> {
        let (m, n) = (self.m, self.n);
        let none = vec![false; m];
        let mut flagged: Vec<Vec<Option<f64>>> = Vec::with_capacity(pairs.len());
        for &(i, k) in pairs {
            // The asymmetry test depends on the frame only through which markers are
            // present: in a complete frame its sum runs over every other marker, in the
            // same order as in `test`, so it is taken once for all of them.
            // In a complete frame the test can hold only when the bound of the module
            // docs' swap passes (see `swap_bound_passes`); the sums of the bound are taken
            // once per pair and once per frame and marker instead of once per pair and
            // frame. Its margin covers their rounding, so the test runs, as written, on
            // every frame it could accept.
            let complete_asymmetry = (0..m)
                .filter(|&c| c != i && c != k)
                .map(|c| (self.r(i, c) - self.r(k, c)).abs())
                .sum::<f64>();
            flagged.push(
                (0..n)
                    .map(|f| {
                        if self.complete[f] && self.d(f, i, k).is_finite() {
                            let eik = (self.d(f, i, k) - self.r(i, k)).abs();
                            let plain = self.misfit[f * m + i] + self.misfit[f * m + k] - 2.0 * eik;
                            if !swap_bound_passes(plain, complete_asymmetry, m - 2) {
                                return None;
                            }
                        }
                        self.test(i, k, f, &none)
                    })
                    .collect(),
            );
        }
        flagged
    }

    /// One swap corrupts the references of the others: with a and b exchanged, a pair
    /// (c, e) whose distances to a and b mirror each other also reads as a swap. In a
    /// frame where several pairs read as swaps, they are taken strongest first (smallest
    /// crossed/plain), and each later one is kept only when it shares no marker with a
    /// kept one and still reads as a swap against the markers no kept swap moved.
    fn keep_independent_swaps(&self, pairs: &[(usize, usize)], flagged: &mut [Vec<Option<f64>>]) {
        let mut excluded = vec![false; self.m];
        let mut order: Vec<(f64, usize)> = Vec::new();
        for f in 0..self.n {
            order.clear();
            order.extend(
                flagged
                    .iter()
                    .enumerate()
                    .filter_map(|(p, v)| v[f].map(|x| (x, p))),
            );
            if order.len() < 2 {
                continue;
            }
            order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            excluded.fill(false);
            for &(_, p) in &order {
                let (i, k) = pairs[p];
                let keep = !excluded[i] && !excluded[k] && self.test(i, k, f, &excluded).is_some();
                if keep {
                    excluded[i] = true;
                    excluded[k] = true;
                } else {
                    flagged[p][f] = None;
                }
            }
        }
    }
}

impl Ctx<'_> {
    /// The cluster and swap findings of one segment's present model markers (at least two).
    pub(super) fn segment_findings(&self, markers: &[usize], reference: &str) -> Vec<Finding> {
        let model = self.model;
        let dist = self.distances(markers);
        let seg = &model.segments()[model.markers()[markers[0]].segment.0].name;
        let mut out = self.cluster_findings(markers, &dist, seg, reference);
        // Swaps: runs of frames where exchanging two labels fits the other markers far better.
        let m = markers.len();
        if m < 3 {
            return out;
        }
        let pairs: Vec<(usize, usize)> = (0..m)
            .flat_map(|i| (i + 1..m).map(move |k| (i, k)))
            .collect();
        let mut flagged = dist.swap_flags(&pairs);
        dist.keep_independent_swaps(&pairs, &mut flagged);
        self.swap_findings(markers, &pairs, &flagged, seg, &mut out);
        out
    }

    /// The distances of the segment's markers in every frame and in the subject model.
    fn distances(&self, markers: &[usize]) -> Distances {
        let (model, n) = (self.model, self.trial.n_frames());
        let model_distance =
            |a: usize, b: usize| (model.markers()[a].local - model.markers()[b].local).norm();
        let m = markers.len();
        let mut d = vec![f64::NAN; n * m * m];
        let mut at: Vec<Option<Vector3<f64>>> = vec![None; m];
        let mut complete = vec![false; n];
        for f in 0..n {
            for (i, &j) in markers.iter().enumerate() {
                at[i] = self.pos(f, j);
            }
            complete[f] = at.iter().all(Option::is_some);
            for i in 0..m {
                for k in i + 1..m {
                    if let (Some(p), Some(q)) = (at[i], at[k]) {
                        let v = (p - q).norm();
                        d[(f * m + i) * m + k] = v;
                        d[(f * m + k) * m + i] = v;
                    }
                }
            }
        }
        let r: Vec<f64> = (0..m * m)
            .map(|x| model_distance(markers[x / m], markers[x % m]))
            .collect();
        let mut misfit = vec![0.0; n * m];
        for f in (0..n).filter(|&f| complete[f]) {
            for i in 0..m {
                misfit[f * m + i] = (0..m)
                    .filter(|&c| c != i)
                    .map(|c| (d[(f * m + i) * m + c] - r[i * m + c]).abs())
                    .sum();
            }
        }
        Distances {
            m,
            n,
            d,
            r,
            complete,
            misfit,
        }
    }

    /// A finding per marker pair whose median distance in the trial differs from the model's
    /// by more than [`CLUSTER_TOLERANCE`].
    fn cluster_findings(
        &self,
        markers: &[usize],
        dist: &Distances,
        seg: &str,
        reference: &str,
    ) -> Vec<Finding> {
        let (m, n) = (dist.m, dist.n);
        let mut out = Vec::new();
        let mut v: Vec<f64> = Vec::with_capacity(n);
        for i in 0..m {
            for k in i + 1..m {
                let (a, b) = (markers[i], markers[k]);
                v.clear();
                v.extend((0..n).map(|f| dist.d(f, i, k)).filter(|x| x.is_finite()));
                if v.is_empty() {
                    continue;
                }
                let mid = v.len() / 2;
                let median = *v.select_nth_unstable_by(mid, f64::total_cmp).1;
                let rr = dist.r(i, k);
                if (median - rr).abs() > CLUSTER_TOLERANCE {
                    out.push(Finding {
                        kind: CheckKind::Cluster,
                        severity: Severity::Warning,
                        message: format!(
                            "{seg}: {} to {} is {:.1} mm in this trial (median) but {:.1} mm in \
                             {reference}: a marker moved or was re-attached",
                            self.name(a),
                            self.name(b),
                            median * 1e3,
                            rr * 1e3,
                        ),
                        fix: Some(format!(
                            "--exclude-marker {} or --exclude-marker {} (the one that moved)",
                            self.name(a),
                            self.name(b)
                        )),
                    });
                }
            }
        }
        out
    }

    /// A finding per run of frames in which a pair reads as swapped.
    fn swap_findings(
        &self,
        markers: &[usize],
        pairs: &[(usize, usize)],
        flagged: &[Vec<Option<f64>>],
        seg: &str,
        out: &mut Vec<Finding>,
    ) {
        let (n, first) = (self.trial.n_frames(), self.trial.first_frame());
        for (&(i, k), flags) in pairs.iter().zip(flagged) {
            let (a, b) = (markers[i], markers[k]);
            for (start, end) in runs(flags.iter().map(Option::is_some)) {
                let (from, to) = (first + start as i64, first + end as i64);
                let frames = if end + 1 == n {
                    format!("{from}")
                } else {
                    format!("{from}-{to}")
                };
                out.push(Finding {
                    kind: CheckKind::Swap,
                    severity: Severity::Warning,
                    message: format!(
                        "{} and {} look swapped in frames {}–{}: exchanged, they fit the \
                         subject model's distances to the other {seg} markers",
                        self.name(a),
                        self.name(b),
                        from,
                        to,
                    ),
                    fix: Some(format!(
                        "--swap-labels {},{}@{frames}",
                        self.name(a),
                        self.name(b)
                    )),
                });
            }
        }
    }
}

/// A necessary condition of the swap test of [`Ctx::segment_findings`] in a frame where
/// all the segment's markers are present: with `count` other markers `c`, `plain =
/// Σ_c |d_ac − r_ac| + |d_bc − r_bc|` and `asymmetry = Σ_c |r_ac − r_bc|`. The test asks
/// `asymmetry ≥ SWAP_MIN_ASYMMETRY · count`, `plain > 0.02 · count` and `crossed < 0.3 ·
/// plain` with `crossed = Σ_c |d_bc − r_ac| + |d_ac − r_bc|`; by the triangle inequality
/// `|d_bc − r_ac| ≥ |r_ac − r_bc| − |d_bc − r_bc|` (and likewise for `a`), so `crossed ≥
/// 2 · asymmetry − plain`, and the last condition needs `asymmetry < 0.65 · plain`. `plain`
/// may come from sums in another order than the test's: the margin (relative 1e-6, far
/// above the rounding of a few dozen terms) keeps every frame the test could accept.
fn swap_bound_passes(plain: f64, asymmetry: f64, count: usize) -> bool {
    let slack = 1.0 + 1e-6;
    let count = count as f64;
    count > 0.0
        && asymmetry * slack >= SWAP_MIN_ASYMMETRY * count
        && plain * slack > 0.02 * count
        && asymmetry < 0.65 * plain * slack
}
