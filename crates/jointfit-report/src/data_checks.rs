//! The report's "Data checks" section: per trial, how it was read (the lab's vertical and
//! where it came from, the file reader's notes), the repairs applied
//! (`jointfit::repair`) and the findings of `jointfit::checks` with the option that repairs
//! each. Rendered by [`render`] (called from `html::render` when there is anything to show).

use std::fmt::Write;

use crate::svg::escape;

/// One data-check finding, as shown.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckRow {
    /// `scale`, `cluster`, `swap`, `jump`, `gaps`, `offset`.
    pub kind: String,
    /// `warning` or `error`.
    pub severity: String,
    pub message: String,
    /// The command-line option that repairs it, if one does.
    pub fix: Option<String>,
}

/// What reading one trial noticed and did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrialChecks {
    /// The trial's file name.
    pub trial: String,
    /// How the vertical was chosen, e.g. `z (the subject model's lab_up)`.
    pub up: String,
    /// The file reader's notes (short data, assumed units, extra rows, a rotated trial).
    pub notes: Vec<String>,
    /// Repairs applied, one sentence each.
    pub repairs: Vec<String>,
    pub findings: Vec<CheckRow>,
}

/// Writes the section body (a table per trial) into `h`.
pub fn render(h: &mut String, trials: &[TrialChecks]) {
    h.push_str(
        "<p class=\"caption\">What the files said and what the checks found before the fit: \
         segment clusters whose distances differ from the model's (the static trial's, or the \
         .osim file's markers), clusters or markers that sit at the same wrong place of their \
         segment in every frame after inverse kinematics (a cluster moved since the static \
         trial), labels that look swapped, marker jumps and gaps. Each repair named here is an \
         option of <code>ik</code>, <code>calibrate</code> and <code>check</code>.</p>",
    );
    for t in trials {
        let _ = write!(
            h,
            "<h3>{}</h3><p>up axis: {}</p>",
            escape(&t.trial),
            escape(&t.up)
        );
        if !t.notes.is_empty() || !t.repairs.is_empty() {
            h.push_str("<ul>");
            for n in &t.notes {
                let _ = write!(h, "<li>reader: {}</li>", escape(n));
            }
            for r in &t.repairs {
                let _ = write!(h, "<li>repair: {}</li>", escape(r));
            }
            h.push_str("</ul>");
        }
        if t.findings.is_empty() {
            h.push_str("<p>No findings.</p>");
            continue;
        }
        h.push_str(
            "<table class=\"checks\"><thead><tr><th>check</th><th>severity</th>\
             <th>finding</th><th>repair</th></tr></thead><tbody>",
        );
        for f in &t.findings {
            let fix = f
                .fix
                .as_ref()
                .map_or(String::new(), |x| format!("<code>{}</code>", escape(x)));
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{fix}</td></tr>",
                escape(&f.kind),
                escape(&f.severity),
                escape(&f.message)
            );
        }
        h.push_str("</tbody></table>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_and_shows_fixes() {
        let mut h = String::new();
        render(
            &mut h,
            &[TrialChecks {
                trial: "walk<1>.trc".into(),
                up: "z (--up)".into(),
                notes: vec!["short & sweet".into()],
                repairs: vec!["excluded marker A".into()],
                findings: vec![CheckRow {
                    kind: "swap".into(),
                    severity: "warning".into(),
                    message: "A and B look swapped".into(),
                    fix: Some("--swap-labels A,B@750".into()),
                }],
            }],
        );
        assert!(h.contains("walk&lt;1&gt;.trc"));
        assert!(h.contains("short &amp; sweet"));
        assert!(h.contains("<code>--swap-labels A,B@750</code>"));
        assert!(h.contains("repair: excluded marker A"));
    }

    #[test]
    fn shows_a_moved_cluster() {
        let mut h = String::new();
        render(
            &mut h,
            &[TrialChecks {
                trial: "walking1.trc".into(),
                up: "y (the default)".into(),
                findings: vec![CheckRow {
                    kind: "offset".into(),
                    severity: "warning".into(),
                    message: "the thigh cluster (L_thigh1, L_thigh2) sits 117 mm from its place"
                        .into(),
                    fix: Some("calibrate --refine-markers".into()),
                }],
                ..TrialChecks::default()
            }],
        );
        assert!(h.contains("<td>offset</td>"));
        assert!(h.contains("the thigh cluster (L_thigh1, L_thigh2) sits 117 mm"));
        assert!(h.contains("<code>calibrate --refine-markers</code>"));
        assert!(h.contains("same wrong place of their segment"));
    }
}
