//! Unit tests of `parameters.rs` and its byte parser `parameters/section.rs`.

use super::*;

/// Builds a little-endian record with a correct next offset.
fn record(id: i8, name: &str, body: &[u8]) -> Vec<u8> {
    let mut r = vec![name.len() as u8, id as u8];
    r.extend_from_slice(name.as_bytes());
    r.extend_from_slice(&((2 + body.len()) as i16).to_le_bytes());
    r.extend_from_slice(body);
    r
}

fn section(records: &[Vec<u8>]) -> Vec<u8> {
    let mut s = vec![1, 0x50, 1, 84];
    for r in records {
        s.extend_from_slice(r);
    }
    s.extend_from_slice(&[0, 0]);
    s.resize(512, 0);
    s
}

fn param_body(ty: i8, dims: &[u8], data: &[u8], desc: &str) -> Vec<u8> {
    let mut b = vec![ty as u8, dims.len() as u8];
    b.extend_from_slice(dims);
    b.extend_from_slice(data);
    b.push(desc.len() as u8);
    b.extend_from_slice(desc.as_bytes());
    b
}

#[test]
fn parses_all_types_and_orders() {
    let labels = b"A   BB  ";
    let recs = vec![
        // Parameter before its group.
        record(
            1,
            "LABELS",
            &param_body(-1, &[4, 2], labels, "marker names"),
        ),
        record(-1, "POINT", &[3, b'3', b'D', b'!']),
        record(1, "USED", &param_body(2, &[], &(-2i16).to_le_bytes(), "")),
        record(1, "RATE", &param_body(4, &[], &50f32.to_le_bytes(), "")),
        record(1, "FLAGS", &param_body(1, &[3], &[1, 2, 255], "")),
    ];
    let s = parse_section(&section(&recs), 0).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let p = &s.parameters;
    assert_eq!(p.group("point").unwrap().description, "3D!");
    assert_eq!(
        p.get("POINT", "labels").unwrap().strings().unwrap(),
        ["A", "BB"]
    );
    assert_eq!(p.get("POINT", "USED").unwrap().u16(), Some(65534));
    assert_eq!(p.get("POINT", "RATE").unwrap().f64(), Some(50.0));
    assert_eq!(
        p.get("POINT", "FLAGS").unwrap().f64s().unwrap(),
        [1.0, 2.0, 255.0]
    );
    assert_eq!(
        p.get("POINT", "LABELS").unwrap().description,
        "marker names"
    );
}

#[test]
fn labels_continue_over_numbered_parameters() {
    let recs = vec![
        record(-1, "POINT", &[0]),
        record(1, "LABELS", &param_body(-1, &[2, 1], b"A1", "")),
        record(1, "LABELS2", &param_body(-1, &[2, 2], b"B1B2", "")),
        record(1, "LABELS4", &param_body(-1, &[2, 1], b"D1", "")),
    ];
    let s = parse_section(&section(&recs), 0).unwrap();
    assert_eq!(
        s.parameters.strings_continued("POINT", "LABELS"),
        ["A1", "B1", "B2"]
    );
}

#[test]
fn bad_offset_falls_back_to_record_end() {
    let mut a = record(-1, "POINT", &[0]);
    a[7] = 0x70; // offset low byte: way off
    let recs = vec![
        a,
        record(1, "USED", &param_body(2, &[], &3i16.to_le_bytes(), "")),
    ];
    let s = parse_section(&section(&recs), 0).unwrap();
    assert_eq!(s.parameters.get("POINT", "USED").unwrap().u16(), Some(3));
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
}

#[test]
fn oversized_values_are_skipped_not_allocated() {
    // 255^7 floats declared in a 512-byte section.
    let body = param_body(4, &[255; 7], &[], "");
    let recs = vec![record(-1, "G", &[0]), record(1, "HUGE", &body)];
    let s = parse_section(&section(&recs), 0).unwrap();
    assert!(s.parameters.get("G", "HUGE").is_none());
    assert!(s.warnings[0].contains("HUGE"), "{:?}", s.warnings);
}

#[test]
fn errors() {
    assert!(matches!(
        parse_section(&[1, 2, 3], 0),
        Err(SectionError::Outside { .. })
    ));
    assert!(matches!(
        parse_section(&[1, 0x50, 1, 99, 0, 0], 0),
        Err(SectionError::Processor(99))
    ));
}

/// A parameter repeated in a group keeps its first value; the repeats of one group are one
/// warning (bigparlove.c3d repeats 2760 parameters: one line each buried every other message).
#[test]
fn repeated_parameters_are_one_warning_per_group() {
    let rate = |v: f32| param_body(4, &[], &v.to_le_bytes(), "");
    let mut recs = vec![record(-1, "POINT", &[0]), record(-2, "SUBJECTS", &[0])];
    recs.push(record(1, "RATE", &rate(50.0)));
    recs.push(record(1, "RATE", &rate(60.0)));
    let names: Vec<String> = (0..8).map(|k| format!("P{k}")).collect();
    for n in &names {
        recs.push(record(2, n, &rate(1.0)));
    }
    for n in &names {
        recs.push(record(2, n, &rate(2.0)));
    }
    let s = parse_section(&section(&recs), 0).unwrap();
    assert_eq!(s.parameters.get("POINT", "RATE").unwrap().f64(), Some(50.0));
    assert_eq!(s.parameters.get("SUBJECTS", "P7").unwrap().f64(), Some(1.0));
    assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
    assert_eq!(
        s.warnings[0],
        "parameter section: parameter RATE appears twice in group id 1; kept the first"
    );
    assert_eq!(
        s.warnings[1],
        "parameter section: 8 repeated parameters in group id 2 (P0, P1, P2, P3, P4 and 3 \
         more); kept the first of each"
    );
}
