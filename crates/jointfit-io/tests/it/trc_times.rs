//! The trial keeps a TRC's own Time column: OpenSim copies it into its results, and
//! force-plate files are paired with the motion by time. Irregular stamps within half a frame
//! survive reading, writing a TRC and writing a `.mot`; stamps that do not increase fall back
//! to frame / DataRate with a note.

use jointfit_io::trc::{format_trc, parse_trc, parse_trc_file, TrcNote, TrcWriteOptions};

/// One marker at 100 Hz whose Time column is `times`, printed as given.
fn trc(times: &[&str]) -> String {
    let n = times.len();
    let mut s = format!(
        "PathFileType\t4\t(X/Y/Z)\tt.trc\n\
         DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
         100\t100\t{n}\t1\tmm\t100\t7\t{n}\n\
         Frame#\tTime\tA\t\t\n\
         \t\tX1\tY1\tZ1\n\
         \n"
    );
    for (i, t) in times.iter().enumerate() {
        s.push_str(&format!("{}\t{t}\t{}\t2\t3\n", 7 + i, i + 1));
    }
    s
}

/// Irregular times (jitter under half a frame, starting at 1.5 s).
const IRREGULAR: [&str; 5] = ["1.500", "1.512", "1.519", "1.531", "1.540"];

fn irregular() -> Vec<f64> {
    IRREGULAR.iter().map(|t| t.parse().unwrap()).collect()
}

#[test]
fn irregular_times_are_kept_and_round_trip() {
    let want = irregular();
    let f = parse_trc_file(&trc(&IRREGULAR), "t.trc").unwrap();
    assert!(f.notes.is_empty(), "{:?}", f.notes);
    let t = &f.trial;
    assert_eq!(t.times(), Some(&want[..]));
    let got: Vec<f64> = (0..t.n_frames()).map(|i| t.time(i)).collect();
    assert_eq!(got, want);
    // Selecting markers and cutting frames keep the stamps of the frames kept.
    let cut = t.select(&["A"]).unwrap().slice_frames(1, 4);
    assert_eq!(cut.times(), Some(&want[1..4]));
    assert_eq!(cut.time(0), 1.512);
    // Writing a TRC writes them back.
    let text = format_trc(t, "t.trc", &TrcWriteOptions::default()).unwrap();
    let again = parse_trc(&text, "again.trc").unwrap();
    assert_eq!(again.times(), Some(&want[..]));
    // A .mot gets them as its time column.
    let model = jointfit::model::Model::compile(
        &jointfit::model::lower_limb::builtin("lower-limb-left").unwrap(),
    )
    .unwrap();
    let coords = vec![vec![0.0; model.coordinates().len()]; t.n_frames()];
    let table = jointfit_io::sto::coordinates_table(&model, t, &coords);
    let mot = jointfit_io::sto::format_sto(&table).unwrap();
    let read = jointfit_io::sto::parse_sto(&mot, "t.mot").unwrap();
    let col: Vec<f64> = read.rows.iter().map(|r| r[0]).collect();
    assert_eq!(col, want);
}

#[test]
fn times_that_do_not_increase_fall_back_to_the_rate() {
    // Within half a frame of DataRate everywhere, but frame 9 repeats frame 8's time.
    let f = parse_trc_file(&trc(&["0.000", "0.015", "0.015"]), "t.trc").unwrap();
    assert!(
        matches!(
            f.notes[..],
            [TrcNote::TimeNotIncreasing {
                line: 9,
                frame: 9,
                ..
            }]
        ),
        "{:?}",
        f.notes
    );
    assert!(f.notes[0].to_string().contains("line 9"));
    assert_eq!(f.trial.times(), None);
    assert_eq!(f.trial.time(2), 0.02);
    // The Time column as written is still reported.
    assert_eq!(f.times, [0.0, 0.015, 0.015]);
}
