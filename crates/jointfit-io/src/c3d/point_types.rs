//! Which points of a C3D file are markers.
//!
//! Gait software stores its computed outputs as 3D points beside the markers: joint angles,
//! forces, moments and powers (Vicon Plug-in Gait writes `LHipAngles`, `RKneeMoment`, … into
//! the POINT section). The C3D user guide (C3D.ORG, "The C3D File Format User Guide", 2008,
//! POINT group) lists them by label in the POINT parameters ANGLES, FORCES, MOMENTS, POWERS,
//! SCALARS and REACTIONS (POINT:TYPE_GROUPS names these parameters). BTK types each point from
//! these lists, and OpenSim's BTK-based C3D reader keeps only BTK's markers in its marker table; the
//! trial ([`super::C3d::to_trial`]) leaves them out the same way, so that no marker-set
//! suggestion or fit ever takes an angle or a power for a marker.

use super::parameters::Parameters;

/// The POINT parameters that list computed outputs by label.
pub const OUTPUT_LISTS: [&str; 6] = [
    "ANGLES",
    "FORCES",
    "MOMENTS",
    "POWERS",
    "SCALARS",
    "REACTIONS",
];

/// Indices of the points whose (trimmed) label one of [`OUTPUT_LISTS`] names, in point
/// order; empty when no point would be left (a file of outputs only keeps its points).
pub fn output_points(params: &Parameters, labels: &[String]) -> Vec<usize> {
    let listed: std::collections::HashSet<String> = OUTPUT_LISTS
        .iter()
        .flat_map(|p| params.strings_continued("POINT", p))
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect();
    let out: Vec<usize> = labels
        .iter()
        .enumerate()
        .filter(|(_, l)| listed.contains(l.trim()))
        .map(|(i, _)| i)
        .collect();
    if out.len() == labels.len() {
        Vec::new()
    } else {
        out
    }
}

/// The reader's note about the points left out (`outputs` from [`output_points`]).
pub fn note(outputs: &[usize], labels: &[String]) -> String {
    const SHOWN: usize = 4;
    let names: Vec<&str> = outputs
        .iter()
        .take(SHOWN)
        .map(|&i| labels[i].as_str())
        .collect();
    let more = outputs.len().saturating_sub(SHOWN);
    let rest = if more > 0 {
        format!(" and {more} more")
    } else {
        String::new()
    };
    format!(
        "left out {} points that POINT:ANGLES/FORCES/MOMENTS/POWERS/SCALARS/REACTIONS list as \
         computed outputs, not markers ({}{rest})",
        outputs.len(),
        names.join(", ")
    )
}
