//! .mot/.sto: malformed inputs (one error each), what the writer refuses, and round trips of
//! random and long tables.

use jointfit_io::sto::{format_sto, parse_sto, write_sto, StoErrorKind, StoWriteError, Table};
use proptest::prelude::*;

use crate::sto::{assert_rows_identical, awkward, joint_angles};

fn sto_err(text: &str) -> String {
    let e = parse_sto(text, "case.sto").expect_err("should be rejected");
    let kind = match e.kind {
        StoErrorKind::Io(_) => "Io",
        StoErrorKind::Empty => "Empty",
        StoErrorKind::NoEndHeader => "NoEndHeader",
        StoErrorKind::BadHeaderValue { .. } => "BadHeaderValue",
        StoErrorKind::NoColumnLabels => "NoColumnLabels",
        StoErrorKind::NoTimeColumn { .. } => "NoTimeColumn",
        StoErrorKind::EmptyLabel { .. } => "EmptyLabel",
        StoErrorKind::ColumnCountMismatch { .. } => "ColumnCountMismatch",
        StoErrorKind::CellCount { .. } => "CellCount",
        StoErrorKind::BadNumber { .. } => "BadNumber",
        StoErrorKind::RowCountMismatch { .. } => "RowCountMismatch",
    };
    let msg = e.to_string();
    assert!(msg.starts_with("case.sto: "), "{msg}");
    format!("{kind}: {msg}")
}

#[test]
fn malformed_storage_files_map_to_one_error_each() {
    let good = "name\nversion=1\nnRows=2\nnColumns=3\ninDegrees=yes\nendheader\n\
                time\ta\tb\n0\t1\t2\n0.1\t3\t4\n";
    assert!(parse_sto(good, "good").is_ok());
    let cases = [
        (String::new(), "Empty"),
        ("name\nversion=1\nnRows=2\n".into(), "NoEndHeader"),
        (
            good.replace("nRows=2", "nRows=two"),
            "BadHeaderValue: case.sto: line 3",
        ),
        (
            good.replace("inDegrees=yes", "inDegrees=maybe"),
            "BadHeaderValue",
        ),
        ("x\nendheader\n\n".into(), "NoColumnLabels"),
        (good.replace("time\ta", "frame\ta"), "NoTimeColumn"),
        (good.replace("time\ta\tb", "time\t\tb"), "EmptyLabel"),
        (
            good.replace("nColumns=3", "nColumns=4"),
            "ColumnCountMismatch",
        ),
        (
            good.replace("0.1\t3\t4", "0.1\t3"),
            "CellCount: case.sto: line 9",
        ),
        (good.replace("0.1\t3\t4", "0.1\t3\t4\t5"), "CellCount"),
        (good.replace("0.1\t3\t4", "0.1\t3\t\t4"), "CellCount"),
        (
            good.replace("0\t1\t2", "0\t1,5\t2"),
            "BadNumber: case.sto: line 8, column \"a\"",
        ),
        (good.replace("nRows=2", "nRows=3"), "RowCountMismatch"),
    ];
    for (text, want) in cases {
        let got = sto_err(&text);
        assert!(got.starts_with(want), "{got:?} should start with {want:?}");
    }
}

#[test]
fn writer_refuses_what_opensim_would_misread() {
    let ok = joint_angles();
    assert!(format_sto(&ok).is_ok());
    let mut cases: Vec<(Table, &str)> = Vec::new();
    let mut t = ok.clone();
    t.columns[0] = "Time".into();
    cases.push((t, "NoTimeColumn"));
    for (label, reason) in [
        ("", "empty"),
        ("a\tb", "tab"),
        (" x", "blanks"),
        ("pelvis_tilt", "duplicate"),
    ] {
        let mut t = ok.clone();
        t.columns[2] = label.into();
        cases.push((t, reason));
    }
    let mut t = ok.clone();
    t.name = "a=b".into();
    cases.push((t, "BadName"));
    for line in ["endheader", "nRows=3", "two\nlines", "trailing "] {
        let mut t = ok.clone();
        t.extra_header.push(line.into());
        cases.push((t, "BadHeaderLine"));
    }
    let mut t = ok.clone();
    t.rows[3].pop();
    cases.push((t, "RowLength"));
    let mut t = ok.clone();
    t.rows[3][0] = t.rows[2][0];
    cases.push((t, "BadTime"));
    let mut t = ok.clone();
    t.rows[0][0] = f64::NAN;
    cases.push((t, "BadTime"));
    let mut t = ok.clone();
    t.rows[5][2] = f64::NEG_INFINITY;
    cases.push((t, "Infinite"));
    for (t, want) in cases {
        let e = format_sto(&t).unwrap_err();
        let kind = match &e {
            StoWriteError::NoTimeColumn { .. } => "NoTimeColumn",
            StoWriteError::BadLabel { reason, .. } => reason,
            StoWriteError::BadName(_) => "BadName",
            StoWriteError::BadHeaderLine(_) => "BadHeaderLine",
            StoWriteError::RowLength { .. } => "RowLength",
            StoWriteError::BadTime { .. } => "BadTime",
            StoWriteError::Infinite { .. } => "Infinite",
            StoWriteError::Io { .. } => "Io",
        };
        assert!(kind.contains(want), "{e} is not {want}");
    }
    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(
        write_sto(&dir.path().join("none/x.sto"), &ok),
        Err(StoWriteError::Io { .. })
    ));
}

fn arb_table() -> impl Strategy<Value = Table> {
    let value = prop_oneof![
        4 => any::<f64>().prop_filter("finite", |v| v.is_finite()),
        4 => -1e3f64..1e3,
        1 => Just(f64::NAN),
        1 => Just(-0.0),
    ];
    (1usize..6, 0usize..15).prop_flat_map(move |(nc, nr)| {
        let labels = proptest::collection::vec("[a-z][a-z0-9_.]{0,8}", nc - 1);
        let steps = proptest::collection::vec(1e-6f64..1.0, nr);
        let cells = proptest::collection::vec(value.clone(), nr * (nc - 1));
        let name = "[A-Za-z][A-Za-z0-9 _.]{0,12}[A-Za-z0-9]|";
        (labels, steps, cells, name, any::<bool>(), -10.0f64..10.0).prop_map(
            move |(labels, steps, cells, name, deg, t0)| {
                let labels: Vec<String> = labels
                    .iter()
                    .enumerate()
                    .map(|(i, l)| format!("{l}_{i}"))
                    .collect();
                let refs: Vec<&str> = labels.iter().map(String::as_str).collect();
                let mut t = Table::new(&name, &refs, deg);
                let mut time = t0;
                for (r, dt) in steps.iter().enumerate() {
                    time += dt;
                    let mut row = vec![time];
                    row.extend_from_slice(&cells[r * (nc - 1)..(r + 1) * (nc - 1)]);
                    t.rows.push(row);
                }
                t
            },
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Table → text → Table is exact, bit for bit, and writing again repeats the text.
    #[test]
    fn sto_round_trip(table in arb_table()) {
        let text = format_sto(&table).unwrap();
        let back = parse_sto(&text, "p.sto").unwrap();
        prop_assert_eq!(&back.name, &table.name);
        prop_assert_eq!(&back.columns, &table.columns);
        prop_assert_eq!(back.in_degrees, table.in_degrees);
        assert_rows_identical(&back.rows, &table.rows, "round trip");
        prop_assert_eq!(format_sto(&back).unwrap(), text);
    }
}

/// The rows are formatted in parallel chunks of 4096: a table of 10 000 rows (three chunks,
/// the last one short) reads back bit for bit, in order, and the text is line for line what
/// formatting each row alone gives.
#[test]
fn long_tables_are_formatted_in_order() {
    let mut table = Table::new("Coordinates", &["a", "b"], true);
    for i in 0..10_000 {
        table
            .rows
            .push(vec![i as f64 / 100.0, awkward(i, 1), awkward(i, 2)]);
    }
    let text = format_sto(&table).unwrap();
    let back = parse_sto(&text, "long.mot").unwrap();
    assert_rows_identical(&back.rows, &table.rows, "10 000 rows");
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| *l == "endheader").unwrap() + 2;
    for (k, row) in [0usize, 4095, 4096, 8191, 8192, 9999]
        .iter()
        .map(|&k| (k, &table.rows[k]))
    {
        let mut one = Table::new("Coordinates", &["a", "b"], true);
        one.rows.push(row.clone());
        let alone = format_sto(&one).unwrap();
        assert_eq!(lines[header + k], alone.lines().last().unwrap(), "row {k}");
    }
}
