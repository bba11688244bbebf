//! The lab's vertical from the marker layout (`jointfit::vertical::detect_up`) on every
//! shared dataset whose up axis is known (PROVENANCE.md, and the files' own layout: the
//! C3D labs record Z or −Z up, the OpenSim/OpenCap TRC exports Y up).

use jointfit::spatial::UpAxis;
use jointfit::vertical::detect_up;
use jointfit_io::trial_file::read_trial;
use jointfit_testkit::data_file;

const KNOWN: &[(&str, UpAxis)] = &[
    ("opencap_expert1/static1.trc", UpAxis::Y),
    ("opencap_expert1/walking1.trc", UpAxis::Y),
    ("opencap_expert1/DJ1.trc", UpAxis::Y),
    ("opensim_gait2392_subject01/subject01_static.trc", UpAxis::Y),
    ("opensim_gait2392_subject01/subject01_walk1.trc", UpAxis::Y),
    ("opensim_hamner_subject02/subject02_static.trc", UpAxis::Y),
    ("opensim_hamner_subject02/subject02_running.trc", UpAxis::Y),
    ("opensim_jam_healthy/static1.trc", UpAxis::Y),
    ("opensim_jam_healthy/overground_17.trc", UpAxis::Y),
    (
        "biobuddy_functional_vicon/anatomical_posture.c3d",
        UpAxis::NegZ,
    ),
    ("biobuddy_functional_vicon/Test_func_anat.c3d", UpAxis::NegZ),
    (
        "biobuddy_functional_vicon/Test_func_rknee.c3d",
        UpAxis::NegZ,
    ),
    ("biobuddy_functional_vicon/Test_func_lhip.c3d", UpAxis::NegZ),
    ("c3d_reader/ezc3d/Qualisys.c3d", UpAxis::Z),
    ("c3d_reader/ezc3d/Vicon.c3d", UpAxis::Z),
    ("c3d_reader/opensim/walking2.c3d", UpAxis::Z),
    ("c3d_reader/opensim/walking5.c3d", UpAxis::Z),
    ("c3d_reader/btk/Gait.c3d", UpAxis::Z),
    ("c3d_reader/c3dorg/sample_03/gait-pig.c3d", UpAxis::Z),
];

#[test]
fn detected_up_axis_matches_every_lab() {
    let mut wrong = Vec::new();
    for (rel, want) in KNOWN {
        let Some(path) = data_file(rel) else {
            println!("skipped: no data");
            return;
        };
        let trial = read_trial(&path).unwrap_or_else(|e| panic!("{rel}: {e}"));
        match detect_up(&trial) {
            Some(d) if d.up == *want => println!("{rel}: {d}"),
            other => wrong.push(format!("{rel}: want {want}, got {other:?}")),
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
