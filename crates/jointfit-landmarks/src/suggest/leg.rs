//! One leg's roles: the epicondyles and malleoli as the widest plausible pair, the heel and
//! forefoot, every other marker's segment, and where each sits against the height band its
//! role expects (stages 4–6 of the parent module's docs).

use super::body::Marker;
use super::labels::{has, ANKLE, FOOT, HEEL, KNEE, META, SHANK, THIGH, TOE};
use super::Role;
use crate::markerset::LegMarkers;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seg {
    Thigh,
    Shank,
    Foot,
}

/// The pair of markers among `cands` `sep` apart sideways (m, inclusive range) and at most
/// `dy` apart in height, widest first: (lateral, medial) for the leg on side `sign`.
fn pair(
    m: &[Marker],
    cands: &[usize],
    sep: (f64, f64),
    dy: f64,
    sign: f64,
) -> Option<(usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for (x, &a) in cands.iter().enumerate() {
        for &b in &cands[x + 1..] {
            let d = (m[a].lateral - m[b].lateral).abs();
            if d < sep.0 || d > sep.1 || (m[a].pos.y - m[b].pos.y).abs() > dy {
                continue;
            }
            if best.is_none_or(|(w, _, _)| d > w) {
                let (lat, med) = if m[a].lateral * sign > m[b].lateral * sign {
                    (a, b)
                } else {
                    (b, a)
                };
                best = Some((d, lat, med));
            }
        }
    }
    best.map(|(_, l, md)| (l, md))
}

/// Height bands (fractions of the ASIS height) of the module docs, stage 4.
const THIGH_BAND: (f64, f64) = (0.55, 1.05);
const SHANK_BAND: (f64, f64) = (0.12, 0.55);
const FOOT_BAND: (f64, f64) = (-0.05, 0.12);
const KNEE_BAND: (f64, f64) = (0.4, 0.65);
const ANKLE_BAND: (f64, f64) = (0.0, 0.2);

/// Where marker `i` sits against the band its role expects, and whether it is inside.
fn place(m: &Marker, band: (f64, f64)) -> (String, bool) {
    (
        format!(
            "at {:.2} of the ASIS height (expected {:.2}–{:.2})",
            m.u, band.0, band.1
        ),
        m.u >= band.0 && m.u < band.1,
    )
}

/// One leg's markers `mine` (indices into `m`) and what the roles are based on.
struct Leg<'a> {
    m: &'a [Marker],
    mine: &'a [usize],
    sign: f64,
    notes: Vec<String>,
    roles: Vec<Role>,
}

impl Leg<'_> {
    fn named(&self, keys: &[&str]) -> Vec<usize> {
        self.mine
            .iter()
            .copied()
            .filter(|&i| has(&self.m[i].norm, keys))
            .collect()
    }

    fn role(&mut self, role: &str, i: usize, by_label: bool, band: (f64, f64)) {
        let (text, ok) = place(&self.m[i], band);
        self.roles
            .push(Role::new(role, &self.m[i].label, by_label, text, ok));
    }

    /// The (lateral, medial) landmark pair of a joint (stage 5): by name, else by position.
    fn landmarks(
        &mut self,
        keys: &[&str],
        band: (f64, f64),
        sep: (f64, f64),
        what: &str,
    ) -> Result<(usize, usize), String> {
        let (p, by_label) = match pair(self.m, &self.named(keys), sep, 0.06, self.sign) {
            Some(p) => (p, true),
            None => {
                let cands: Vec<usize> = self
                    .mine
                    .iter()
                    .copied()
                    .filter(|&i| self.m[i].u >= band.0 && self.m[i].u < band.1)
                    .collect();
                let p = pair(self.m, &cands, sep, 0.06, self.sign)
                    .ok_or_else(|| format!("no pair of {what} markers found"))?;
                self.notes.push(format!(
                    "{what}: chose {} (lateral) and {} (medial) by position; check them",
                    self.m[p.0].label, self.m[p.1].label
                ));
                (p, false)
            }
        };
        let (lat, med) = match what {
            "knee" => ("lateral epicondyle", "medial epicondyle"),
            _ => ("lateral malleolus", "medial malleolus"),
        };
        self.role(lat, p.0, by_label, band);
        self.role(med, p.1, by_label, band);
        Ok(p)
    }

    /// The segment a marker tracks (stage 4), and whether its label said so; `None` for a
    /// medial landmark or a landmark-named marker off its pair.
    fn segment(&self, i: usize, landmarks: [usize; 4]) -> Option<(Seg, bool)> {
        let [lat_knee, med_knee, lat_ank, med_ank] = landmarks;
        if i == med_knee || i == med_ank {
            return None;
        }
        if i == lat_knee {
            return Some((Seg::Thigh, true));
        }
        if i == lat_ank {
            return Some((Seg::Shank, true));
        }
        let (n, u) = (&self.m[i].norm, self.m[i].u);
        if has(n, FOOT) || has(n, HEEL) {
            Some((Seg::Foot, true))
        } else if has(n, SHANK) {
            Some((Seg::Shank, true))
        } else if has(n, THIGH) {
            Some((Seg::Thigh, true))
        } else if has(n, KNEE) || has(n, ANKLE) {
            None
        } else if u >= THIGH_BAND.0 {
            Some((Seg::Thigh, false))
        } else if u >= SHANK_BAND.0 {
            Some((Seg::Shank, false))
        } else {
            Some((Seg::Foot, false))
        }
    }

    /// The heel (stage 6): the heel-named foot marker, else the most posterior one.
    fn heel(&mut self, foot: &[usize]) -> usize {
        let named = self
            .named(HEEL)
            .into_iter()
            .filter(|i| foot.contains(i))
            .min_by(|&a, &b| self.m[a].pos.y.total_cmp(&self.m[b].pos.y));
        let i = named.unwrap_or_else(|| {
            let i = foot
                .iter()
                .copied()
                .min_by(|&a, &b| self.m[a].pos.x.total_cmp(&self.m[b].pos.x))
                .expect("non-empty");
            self.notes.push(format!(
                "heel: chose {} as the most posterior foot marker",
                self.m[i].label
            ));
            i
        });
        self.role("heel", i, named.is_some(), FOOT_BAND);
        i
    }

    /// The forefoot (stage 6): toe-named markers, else metatarsal heads, else the most
    /// anterior foot marker.
    fn forefoot(
        &mut self,
        foot: &[usize],
        heel: usize,
        ankle_y: f64,
    ) -> Result<Vec<usize>, String> {
        let forward = |keys: &[&str]| -> Vec<usize> {
            self.named(keys)
                .into_iter()
                .filter(|&i| foot.contains(&i) && i != heel && self.m[i].pos.y < ankle_y)
                .collect()
        };
        let mut chosen = forward(TOE);
        if chosen.is_empty() {
            chosen = forward(META);
        }
        let by_label = !chosen.is_empty();
        if chosen.is_empty() {
            let i = foot
                .iter()
                .copied()
                .filter(|&i| i != heel)
                .max_by(|&a, &b| self.m[a].pos.x.total_cmp(&self.m[b].pos.x))
                .ok_or("no forefoot marker")?;
            self.notes.push(format!(
                "forefoot: chose {} as the most anterior foot marker",
                self.m[i].label
            ));
            chosen.push(i);
        }
        for &i in &chosen {
            self.role("forefoot", i, by_label, FOOT_BAND);
        }
        Ok(chosen)
    }
}

/// One leg's roles from its markers `mine` (indices into `m`), the notes on how they were
/// chosen, and what each role is based on.
pub(super) fn leg(
    m: &[Marker],
    mine: &[usize],
    sign: f64,
) -> Result<(LegMarkers, Vec<String>, Vec<Role>), String> {
    let mut l = Leg {
        m,
        mine,
        sign,
        notes: Vec::new(),
        roles: Vec::new(),
    };
    let (lat_knee, med_knee) = l.landmarks(KNEE, KNEE_BAND, (0.04, 0.18), "knee")?;
    let (lat_ank, med_ank) = l.landmarks(ANKLE, ANKLE_BAND, (0.03, 0.14), "ankle")?;
    let landmarks = [lat_knee, med_knee, lat_ank, med_ank];
    let segments: Vec<(usize, Seg, bool)> = mine
        .iter()
        .filter_map(|&i| l.segment(i, landmarks).map(|(s, named)| (i, s, named)))
        .collect();
    let list = |s: Seg| -> Vec<String> {
        segments
            .iter()
            .filter(|x| x.1 == s)
            .map(|x| m[x.0].label.clone())
            .collect()
    };
    let foot: Vec<usize> = segments
        .iter()
        .filter(|x| x.1 == Seg::Foot)
        .map(|x| x.0)
        .collect();
    if foot.is_empty() {
        return Err("no foot markers".into());
    }
    let heel = l.heel(&foot);
    let ankle_y = (m[lat_ank].pos.y + m[med_ank].pos.y) / 2.0;
    let forefoot = l.forefoot(&foot, heel, ankle_y)?;
    for &(i, s, named) in &segments {
        let (name, band) = match s {
            Seg::Thigh => ("thigh tracking", THIGH_BAND),
            Seg::Shank => ("shank tracking", SHANK_BAND),
            Seg::Foot => ("foot tracking", FOOT_BAND),
        };
        l.role(name, i, named, band);
    }
    let leg = LegMarkers {
        lateral_epicondyle: m[lat_knee].label.clone(),
        medial_epicondyle: m[med_knee].label.clone(),
        lateral_malleolus: m[lat_ank].label.clone(),
        medial_malleolus: m[med_ank].label.clone(),
        heel: m[heel].label.clone(),
        forefoot: forefoot.iter().map(|&i| m[i].label.clone()).collect(),
        thigh: list(Seg::Thigh),
        shank: list(Seg::Shank),
        foot: list(Seg::Foot),
    };
    for (seg, tracked) in [
        ("thigh", &leg.thigh),
        ("shank", &leg.shank),
        ("foot", &leg.foot),
    ] {
        let least = crate::markerset::min_tracking(seg);
        if tracked.len() < least {
            return Err(format!(
                "{seg} has {} tracking markers ({}), needs {least}",
                tracked.len(),
                tracked.join(", ")
            ));
        }
    }
    Ok((leg, l.notes, l.roles))
}
