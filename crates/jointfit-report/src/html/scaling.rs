//! The section "Scaling from the generic model": what `jointfit scale` did to the model the
//! report is about (its record, `jointfit_io::osim_scale::record`): each group's factors
//! with a 95 % interval (± 1.96 SD of the fit's Laplace approximation; SD 0 for a factor
//! held at a given value), and every marker's offset from its scaled generic place, largest
//! first. Element ids: `tbl-scale-factors`, `tbl-marker-offsets`.

use std::fmt::Write;

use jointfit_io::osim_scale::record::ScaleRecord;

use crate::svg::escape;

/// z of a two-sided 95 % normal interval.
const Z95: f64 = 1.959_963_984_540_054;

fn factors_cell(f: [f64; 3]) -> String {
    if f[0] == f[1] && f[1] == f[2] {
        format!("{:.4}", f[0])
    } else {
        format!("{:.4} {:.4} {:.4}", f[0], f[1], f[2])
    }
}

fn interval_cell(f: [f64; 3], sd: [f64; 3]) -> String {
    if sd.iter().all(|s| *s == 0.0) {
        return "held (given)".into();
    }
    let one = |k: usize| format!("{:.4}–{:.4}", f[k] - Z95 * sd[k], f[k] + Z95 * sd[k]);
    if f[0] == f[1] && f[1] == f[2] && sd[0] == sd[1] && sd[1] == sd[2] {
        one(0)
    } else {
        (0..3).map(one).collect::<Vec<_>>().join(", ")
    }
}

fn factor_table(h: &mut String, rec: &ScaleRecord) {
    h.push_str(
        "<div class=\"scroll\"><table id=\"tbl-scale-factors\"><thead><tr><th>group</th>\
         <th>bodies</th><th class=\"n\">factor</th><th class=\"n\">95 % interval</th>\
         </tr></thead><tbody>",
    );
    for g in &rec.groups {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td></tr>",
            escape(&g.name),
            escape(&g.bodies.join(", ")),
            factors_cell(g.factors),
            interval_cell(g.factors, g.sd)
        );
    }
    h.push_str("</tbody></table></div>");
}

fn marker_table(h: &mut String, rec: &ScaleRecord) {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let mut rows: Vec<_> = rec.markers.iter().collect();
    rows.sort_by(|a, b| norm(b.moved_mm).total_cmp(&norm(a.moved_mm)));
    h.push_str(
        "<h3>Markers registered on the subject</h3><div class=\"scroll\">\
         <table id=\"tbl-marker-offsets\"><thead><tr><th>marker</th><th>body</th>\
         <th class=\"n\">moved (mm)</th><th class=\"n\">x</th><th class=\"n\">y</th>\
         <th class=\"n\">z</th><th class=\"n\">RMS to data (mm)</th></tr></thead><tbody>",
    );
    for m in rows {
        let v = m.moved_mm;
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td class=\"n\">{:.1}</td><td class=\"n\">{:.1}</td>\
             <td class=\"n\">{:.1}</td><td class=\"n\">{:.1}</td><td class=\"n\">{}</td></tr>",
            escape(&m.name),
            escape(&m.body),
            norm(v),
            v[0],
            v[1],
            v[2],
            m.rms_mm
                .map_or("not in the trials".to_string(), |r| format!("{r:.1}"))
        );
    }
    h.push_str("</tbody></table></div>");
}

/// The section's body.
pub(super) fn render(h: &mut String, rec: &ScaleRecord) {
    let trials = if rec.trials.is_empty() {
        String::new()
    } else {
        format!(" and {}", rec.trials.join(", "))
    };
    let _ = write!(
        h,
        "<p class=\"lead\">Scaled from {} on the static trial {}{} ({} frame(s), marker RMS \
         {:.1} mm); total mass {:.2} kg (generic {:.2} kg). Factors apply to the bodies' x, y, \
         z; markers moved from their scaled generic place in their body's frame.</p>",
        escape(&rec.generic),
        escape(&rec.static_trial),
        escape(&trials),
        rec.frames,
        rec.rms_mm,
        rec.total_mass,
        rec.generic_mass
    );
    if !rec.flags.is_empty() {
        h.push_str("<div class=\"notes\">");
        for f in &rec.flags {
            let _ = write!(h, "<p>Implausible: {}</p>", escape(f));
        }
        h.push_str("</div>");
    }
    factor_table(h, rec);
    marker_table(h, rec);
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit_io::osim_scale::record::{RecordGroup, RecordMarker};

    #[test]
    fn factors_show_their_interval_or_that_they_were_held() {
        let group = |name: &str, f: [f64; 3], sd: [f64; 3]| RecordGroup {
            name: name.into(),
            bodies: vec![format!("{name}_r")],
            factors: f,
            sd,
        };
        let marker = |name: &str, moved_mm: [f64; 3]| RecordMarker {
            name: name.into(),
            body: "femur_r".into(),
            moved_mm,
            rms_mm: Some(2.0),
        };
        let rec = ScaleRecord {
            generic: "generic.osim".into(),
            static_trial: "static.trc".into(),
            trials: vec![],
            groups: vec![
                group("thigh", [1.1; 3], [0.01; 3]),
                group("tibia", [0.98; 3], [0.0; 3]),
                group("pelvis", [1.0, 1.2, 1.1], [0.01, 0.02, 0.03]),
            ],
            markers: vec![
                marker("small", [1.0, 0.0, 0.0]),
                marker("big", [0.0, 30.0, 40.0]),
            ],
            rms_mm: 2.5,
            frames: 1,
            generic_mass: 75.0,
            total_mass: 70.0,
            flags: vec!["left and right <differ>".into()],
        };
        let mut h = String::new();
        render(&mut h, &rec);
        // 1.1 ± 1.96·0.01
        assert!(h.contains("<td class=\"n\">1.1000</td><td class=\"n\">1.0804–1.1196</td>"));
        assert!(h.contains("<td class=\"n\">0.9800</td><td class=\"n\">held (given)</td>"));
        assert!(h.contains("1.0000 1.2000 1.1000"));
        assert!(h.contains("0.9804–1.0196, 1.1608–1.2392, 1.0412–1.1588"));
        // largest offset first: |(0, 30, 40)| = 50 mm
        let (big, small) = (h.find(">big<").unwrap(), h.find(">small<").unwrap());
        assert!(big < small);
        assert!(h.contains("<td class=\"n\">50.0</td>"));
        assert!(h.contains("left and right &lt;differ&gt;"));
    }
}
