//! End-to-end tests on C3D files written here, byte by byte, from the format description:
//! every processor type, integer and float storage, LABELS2, units, more than 65535 frames,
//! and the error variants.

use super::*;

/// What to write.
struct Spec {
    processor: Processor,
    /// POINT:SCALE (negative: float storage); also written to the header unless
    /// `header_scale` says otherwise.
    scale: f32,
    header_scale: Option<f32>,
    n_points: usize,
    frames: usize,
    /// Header last frame (default: `frames`, saturated at 65535).
    header_last: Option<u16>,
    /// TRIAL:ACTUAL_END_FIELD.
    actual_end: Option<u32>,
    units: Option<&'static str>,
    analog_channels: usize,
    analog_per_frame: usize,
    /// POINT:RATE (and ANALOG:RATE per sample), Hz.
    rate: f32,
    /// Header words 11–12 (default: `rate`).
    header_rate: Option<f32>,
    /// POINT:LABELS (default: `M0`, `M1`, …).
    labels: Option<Vec<&'static str>>,
}

impl Default for Spec {
    fn default() -> Self {
        Self {
            processor: Processor::Intel,
            scale: -0.1,
            header_scale: None,
            n_points: 3,
            frames: 5,
            header_last: None,
            actual_end: None,
            units: Some("mm"),
            analog_channels: 2,
            analog_per_frame: 2,
            rate: 100.0,
            header_rate: None,
            labels: None,
        }
    }
}

/// The position written for `point` in `frame`, in file units; (0,0,0) for point 1 in
/// frame 2 (a gap written as zeros) — point 2 in frame 3 gets a negative residual word.
fn position(frame: usize, point: usize) -> [f32; 3] {
    if (frame, point) == (2, 1) {
        return [0.0; 3];
    }
    let f = frame as f32;
    [
        100.0 + f + point as f32 * 10.0,
        -50.0 + 0.5 * f,
        1000.0 - point as f32,
    ]
}

struct Enc(Processor);

impl Enc {
    fn u16(&self, v: u16) -> [u8; 2] {
        match self.0 {
            Processor::Mips => v.to_be_bytes(),
            _ => v.to_le_bytes(),
        }
    }
    fn f32(&self, v: f32) -> [u8; 4] {
        match self.0 {
            Processor::Intel => v.to_le_bytes(),
            Processor::Mips => v.to_be_bytes(),
            Processor::Dec => {
                if v == 0.0 {
                    return [0; 4];
                }
                let le = (v.to_bits() + (2 << 23)).to_le_bytes();
                [le[2], le[3], le[0], le[1]]
            }
        }
    }
}

fn record(e: &Enc, id: i8, name: &str, body: &[u8]) -> Vec<u8> {
    let mut r = vec![name.len() as u8, id as u8];
    r.extend_from_slice(name.as_bytes());
    r.extend_from_slice(&e.u16((2 + body.len()) as u16));
    r.extend_from_slice(body);
    r
}

fn param(ty: i8, dims: &[u8], data: &[u8]) -> Vec<u8> {
    let mut b = vec![ty as u8, dims.len() as u8];
    b.extend_from_slice(dims);
    b.extend_from_slice(data);
    b.push(0);
    b
}

fn write(s: &Spec) -> Vec<u8> {
    let e = Enc(s.processor);
    let mut recs = parameter_records(&e, s);
    // Lay the records out once to learn the block count, then again with DATA_START.
    let blocks = (lay_section(s, &recs).len() + 32).div_ceil(512);
    let data_block = 2 + blocks as u16;
    recs.push(record(
        &e,
        1,
        "DATA_START",
        &param(2, &[], &e.u16(data_block)),
    ));
    let mut section = lay_section(s, &recs);
    assert!(
        section.len() <= blocks * 512,
        "test writer: section grew past its blocks"
    );
    section[2] = blocks as u8;
    section.resize(blocks * 512, 0);

    let mut out = header_block(&e, s, data_block);
    out.extend_from_slice(&section);
    out.extend_from_slice(&data_section(&e, s));
    let padded = out.len().div_ceil(512) * 512;
    out.resize(padded, 0);
    out
}

/// The point labels written: `s.labels`, else `M0`, `M1`, ….
fn labels_of(s: &Spec) -> Vec<String> {
    match &s.labels {
        Some(l) => l.iter().map(|x| x.to_string()).collect(),
        None => (0..s.n_points).map(|i| format!("M{i}")).collect(),
    }
}

/// POINT, ANALOG and TRIAL groups and their parameters (all but POINT:DATA_START).
fn parameter_records(e: &Enc, s: &Spec) -> Vec<Vec<u8>> {
    let int = |v: u16| param(2, &[], &e.u16(v));
    let flt = |v: f32| param(4, &[], &e.f32(v));
    let mut recs = vec![
        record(e, -1, "POINT", &[0]),
        record(e, -2, "ANALOG", &[0]),
        record(e, -3, "TRIAL", &[0]),
        record(e, 1, "USED", &int(s.n_points as u16)),
        record(e, 1, "SCALE", &flt(s.scale)),
        record(e, 1, "RATE", &flt(s.rate)),
        record(e, 1, "FRAMES", &int(s.frames.min(65535) as u16)),
        record(e, 2, "USED", &int(s.analog_channels as u16)),
        record(e, 2, "RATE", &flt(s.rate * s.analog_per_frame as f32)),
        record(e, 2, "GEN_SCALE", &flt(0.5)),
    ];
    if let Some(u) = s.units {
        recs.push(record(
            e,
            1,
            "UNITS",
            &param(-1, &[u.len() as u8], u.as_bytes()),
        ));
    }
    recs.extend(label_records(e, &labels_of(s)));
    recs.extend(analog_records(e, s));
    if let Some(end) = s.actual_end {
        let w: Vec<u8> = [end as u16, (end >> 16) as u16]
            .iter()
            .flat_map(|&x| e.u16(x))
            .collect();
        recs.push(record(
            e,
            3,
            "ACTUAL_START_FIELD",
            &param(2, &[2], &[e.u16(1), e.u16(0)].concat()),
        ));
        recs.push(record(e, 3, "ACTUAL_END_FIELD", &param(2, &[2], &w)));
    }
    recs
}

/// POINT:LABELS, LABELS2, … (255 labels each, 4 characters wide).
fn label_records(e: &Enc, labels: &[String]) -> Vec<Vec<u8>> {
    labels
        .chunks(255)
        .enumerate()
        .map(|(k, chunk)| {
            let name = if k == 0 {
                "LABELS".to_string()
            } else {
                format!("LABELS{}", k + 1)
            };
            let text: Vec<u8> = chunk
                .iter()
                .flat_map(|l| format!("{l:<4}").into_bytes())
                .collect();
            record(e, 1, &name, &param(-1, &[4, chunk.len() as u8], &text))
        })
        .collect()
}

/// ANALOG:SCALE (channel c: c + 1) and ANALOG:OFFSET (10 each).
fn analog_records(e: &Enc, s: &Spec) -> Vec<Vec<u8>> {
    let scales: Vec<u8> = (0..s.analog_channels)
        .flat_map(|c| e.f32(c as f32 + 1.0))
        .collect();
    let offsets: Vec<u8> = (0..s.analog_channels).flat_map(|_| e.u16(10)).collect();
    vec![
        record(
            e,
            2,
            "SCALE",
            &param(4, &[s.analog_channels as u8], &scales),
        ),
        record(
            e,
            2,
            "OFFSET",
            &param(2, &[s.analog_channels as u8], &offsets),
        ),
    ]
}

/// The parameter section before padding: its 4-byte header, the records, the end mark.
fn lay_section(s: &Spec, recs: &[Vec<u8>]) -> Vec<u8> {
    let mut section = vec![1, 0x50, 0, s.processor.code()];
    for r in recs {
        section.extend_from_slice(r);
    }
    section.extend_from_slice(&[0, 0]);
    section
}

/// Block 1.
fn header_block(e: &Enc, s: &Spec, data_block: u16) -> Vec<u8> {
    let mut header = vec![0u8; 512];
    header[0] = 2;
    header[1] = 0x50;
    let mut put =
        |word: usize, b: &[u8]| header[2 * (word - 1)..2 * (word - 1) + b.len()].copy_from_slice(b);
    put(2, &e.u16(s.n_points as u16));
    put(3, &e.u16((s.analog_channels * s.analog_per_frame) as u16));
    put(4, &e.u16(1));
    put(
        5,
        &e.u16(s.header_last.unwrap_or(s.frames.min(65535) as u16)),
    );
    put(7, &e.f32(s.header_scale.unwrap_or(s.scale)));
    put(9, &e.u16(data_block));
    put(10, &e.u16(s.analog_per_frame as u16));
    put(11, &e.f32(s.header_rate.unwrap_or(s.rate)));
    header
}

/// Every frame: the points (x, y, z, residual word) then the analog words.
fn data_section(e: &Enc, s: &Spec) -> Vec<u8> {
    let float = s.scale < 0.0;
    let mut out = Vec::new();
    let mut put = |v: f32| {
        if float {
            out.extend_from_slice(&e.f32(v));
        } else {
            out.extend_from_slice(&e.u16(v as i16 as u16));
        }
    };
    for f in 0..s.frames {
        for p in 0..s.n_points {
            for v in position(f, p) {
                put(if float { v } else { (v / s.scale).round() });
            }
            put(if (f, p) == (3, 2) { -1.0 } else { 773.0 });
        }
        for k in 0..s.analog_channels * s.analog_per_frame {
            put(f32::from((f * 100 + k) as i16));
        }
    }
    out
}

fn check(c: &C3d, s: &Spec, metres_per_unit: f64) {
    let p = &c.points;
    assert_eq!((p.n_frames, p.n_points()), (s.frames, s.n_points));
    assert_eq!(p.labels[0], "M0");
    assert_eq!(p.labels[s.n_points - 1], format!("M{}", s.n_points - 1));
    let tol = if s.scale < 0.0 {
        1e-12
    } else {
        s.scale as f64 * metres_per_unit
    };
    for f in [0, 1, s.frames - 1] {
        for m in 0..s.n_points {
            let got = p.positions[f * s.n_points + m];
            if (f, m) == (3, 2) || (f, m) == (2, 1) {
                continue;
            }
            let want = position(f, m).map(|v| f64::from(v) * metres_per_unit);
            for a in 0..3 {
                assert!(
                    (got[a] - want[a]).abs() <= tol,
                    "frame {f} point {m}: {got:?} vs {want:?}"
                );
            }
            assert!(
                (p.residuals[f * s.n_points + m]
                    - 5.0 * f64::from(s.scale.abs()) * metres_per_unit)
                    .abs()
                    < 1e-9
            );
            assert_eq!(p.camera_masks[f * s.n_points + m], 3);
        }
    }
    if s.frames > 3 && s.n_points > 2 {
        assert!(
            p.positions[3 * s.n_points + 2].x.is_nan(),
            "negative residual word"
        );
        assert!(p.positions[2 * s.n_points + 1].x.is_nan(), "exact zeros");
    }
    // Analog: (raw − 10) × (c + 1) × 0.5.
    let a = &c.analog;
    assert_eq!(a.n_channels(), s.analog_channels);
    assert_eq!(a.n_samples(), s.frames * s.analog_per_frame);
    let nc = s.analog_channels;
    let f = 1;
    for k in 0..nc * s.analog_per_frame {
        let raw = (f * 100 + k) as f64;
        let want = (raw - 10.0) * ((k % nc) as f64 + 1.0) * 0.5;
        assert_eq!(a.samples[f * nc * s.analog_per_frame + k], want);
    }
}

#[test]
fn every_processor_and_storage() {
    for processor in [Processor::Intel, Processor::Dec, Processor::Mips] {
        for scale in [-0.1f32, 0.1] {
            let s = Spec {
                processor,
                scale,
                ..Spec::default()
            };
            let c = parse_c3d(&write(&s)).unwrap_or_else(|e| panic!("{processor:?} {scale}: {e}"));
            assert_eq!(c.processor, processor);
            assert_eq!(c.float_storage, scale < 0.0);
            assert!(c.warnings.is_empty(), "{:?}", c.warnings);
            check(&c, &s, 1e-3);
            let t = c.to_trial().unwrap();
            assert_eq!(t.n_frames(), 5);
            assert_eq!(t.rate(), 100.0);
        }
    }
}

#[test]
fn units_and_missing_units() {
    for (u, m) in [
        (Some("m"), 1.0),
        (Some("cm"), 1e-2),
        (Some("MM"), 1e-3),
        (None, 1e-3),
    ] {
        let s = Spec {
            units: u,
            ..Spec::default()
        };
        let c = parse_c3d(&write(&s)).unwrap();
        check(&c, &s, m);
        assert_eq!(u.is_none(), c.warnings.iter().any(|w| w.contains("UNITS")));
    }
    let s = Spec {
        units: Some("in"),
        ..Spec::default()
    };
    assert!(matches!(parse_c3d(&write(&s)), Err(C3dError::UnknownUnits(u)) if u == "in"));
}

#[test]
fn more_than_255_labels_continue_in_labels2() {
    let s = Spec {
        n_points: 300,
        frames: 4,
        analog_channels: 0,
        analog_per_frame: 0,
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    assert_eq!(c.points.labels.len(), 300);
    assert_eq!(c.points.labels[255], "M255");
    check(&c, &s, 1e-3);
}

#[test]
fn more_than_65535_frames_from_actual_end_field() {
    let frames = 70_000;
    let s = Spec {
        n_points: 1,
        frames,
        header_last: Some(65535),
        actual_end: Some(frames as u32),
        analog_channels: 0,
        analog_per_frame: 0,
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    assert_eq!(c.points.n_frames, frames);
    assert_eq!(c.last_frame(), frames as i64);
    assert!(
        c.warnings.iter().any(|w| w.contains("ACTUAL_END_FIELD")),
        "{:?}",
        c.warnings
    );
    let last = c.points.positions[frames - 1] * 1000.0;
    assert!((last.x - f64::from(position(frames - 1, 0)[0])).abs() < 1e-9);
}

#[test]
fn errors_are_specific() {
    let good = write(&Spec::default());
    assert!(matches!(
        parse_c3d(&good[..100]),
        Err(C3dError::TooShort { len: 100 })
    ));
    let mut b = good.clone();
    b[0] = 200;
    assert!(matches!(
        parse_c3d(&b),
        Err(C3dError::ParameterBlock { block: 200, .. })
    ));
    let mut b = good.clone();
    b[512 + 3] = 99;
    assert!(matches!(parse_c3d(&b), Err(C3dError::UnknownProcessor(99))));
    // Cut the data section in the middle of a frame and of a block.
    let data_start = 512 * (usize::from(good[16]) - 1);
    let cut = data_start + 100;
    assert!(matches!(
        parse_c3d(&good[..cut]),
        Err(C3dError::Truncated { .. })
    ));
    // Integer data whose header scale disagrees with POINT:SCALE.
    let s = Spec {
        scale: 0.1,
        header_scale: Some(0.2),
        ..Spec::default()
    };
    assert!(matches!(
        parse_c3d(&write(&s)),
        Err(C3dError::ScaleMismatch { .. })
    ));
    // Float data both ways: only the residual scale differs (every Vicon Nexus file: header
    // −1, POINT:SCALE −0.01); read without a note. Scales that disagree on the storage (the
    // sign): read as POINT:SCALE says, with a warning.
    let s = Spec {
        scale: -0.1,
        header_scale: Some(-1.0),
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    assert!(!c.warnings.iter().any(|w| w.contains("POINT:SCALE")));
    let s = Spec {
        scale: -0.1,
        header_scale: Some(1.0),
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    assert!(c.warnings.iter().any(|w| w.contains("POINT:SCALE")));
    // A point rate of 0 reads, but makes no trial.
    let mut c = parse_c3d(&good).unwrap();
    c.points.rate = 0.0;
    assert!(matches!(c.to_trial(), Err(C3dError::Trial(_))));
}

#[test]
fn read_c3d_names_the_file() {
    let e = read_c3d(Path::new("/nonexistent/x.c3d")).unwrap_err();
    assert!(matches!(e, C3dError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/x.c3d"));
}

#[test]
fn to_trial_makes_labels_unique() {
    let mut c = parse_c3d(&write(&Spec::default())).unwrap();
    c.points.labels = vec!["A".into(), "A".into(), String::new()];
    let t = c.to_trial().unwrap();
    assert_eq!(t.labels(), ["A", "A_2", "POINT3"]);
}

/// Frame counts declared in a header or a parameter are checked against the bytes present
/// before anything is allocated: 4e9 frames in TRIAL:ACTUAL_END_FIELD (and a header that
/// says 65535) read the count that fits the file, with a warning, or are a one-line error
/// when the data are cut inside a frame. Never an allocation of the declared size.
#[test]
fn billions_of_declared_frames_allocate_nothing() {
    let base = Spec {
        frames: 5,
        actual_end: Some(4_000_000_000),
        ..Spec::default()
    };
    // The header agrees with the data; the parameter's 4e9 does not fit and is ignored.
    let c = parse_c3d(&write(&base)).unwrap();
    assert_eq!(c.points.n_frames, 5);
    // The header says 65535 too: POINT:FRAMES (5) fits the data and is read, with a warning.
    let s = Spec {
        header_last: Some(65535),
        ..base
    };
    let bytes = write(&s);
    let c = parse_c3d(&bytes).unwrap();
    assert_eq!(c.points.n_frames, 5);
    assert!(
        c.warnings.iter().any(|w| w.contains("65535")),
        "{:?}",
        c.warnings
    );
    // Cut inside a frame (not at a block boundary): a one-line error naming both counts.
    let cut = &bytes[..bytes.len() - 512 + 7];
    let e = parse_c3d(cut).unwrap_err();
    assert!(
        matches!(
            e,
            C3dError::Truncated {
                declared: 65535,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(e.to_string().lines().count(), 1);
}

/// A header saturated at 65535 frames, no TRIAL:ACTUAL_END_FIELD and POINT:FRAMES 65535 too
/// (its 16-bit word saturated): the frames past 65535 are read, counted from the data size,
/// the zero padding of the last block is not taken for frames, and a warning says so.
#[test]
fn more_than_65535_frames_without_actual_end_field_counted_from_the_data() {
    // Float storage only: the test's coordinates past frame 32767 overflow 16-bit words.
    for (frames, n_points, processor, analog_channels) in [
        (70_000, 1, Processor::Intel, 0),
        (65_600, 3, Processor::Mips, 2),
        (66_000, 2, Processor::Dec, 1),
    ] {
        let s = Spec {
            n_points,
            frames,
            processor,
            header_last: Some(65535),
            analog_channels,
            analog_per_frame: analog_channels.min(1),
            ..Spec::default()
        };
        let c = parse_c3d(&write(&s)).unwrap();
        assert_eq!(c.points.n_frames, frames, "{:?}", c.warnings);
        let notes: Vec<&String> = c
            .warnings
            .iter()
            .filter(|w| w.contains("65535") && w.contains(&frames.to_string()))
            .collect();
        assert_eq!(notes.len(), 1, "{:?}", c.warnings);
        check(&c, &s, 1e-3);
    }
    // Exactly 65535 frames stored: nothing more to read, no note.
    let s = Spec {
        n_points: 1,
        frames: 65535,
        header_last: Some(65535),
        analog_channels: 0,
        analog_per_frame: 0,
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    assert_eq!(c.points.n_frames, 65535);
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

/// A header frame rate that differs from POINT:RATE: POINT:RATE is used, and one note names
/// both.
#[test]
fn header_rate_disagreeing_with_point_rate_is_noted() {
    let s = Spec {
        rate: 120.0,
        header_rate: Some(60.0),
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    assert_eq!(c.point_rate(), 120.0);
    let notes: Vec<&String> = c.warnings.iter().filter(|w| w.contains("Hz")).collect();
    assert_eq!(notes.len(), 1, "{:?}", c.warnings);
    assert!(notes[0].contains("60") && notes[0].contains("120") && notes[0].contains("used"));
    // Equal rates: no note.
    let c = parse_c3d(&write(&Spec {
        rate: 120.0,
        ..Spec::default()
    }))
    .unwrap();
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

/// Repeated labels are noted once, naming each repeated label and its count; the trial gets
/// the renamed repeats the note announces.
#[test]
fn repeated_labels_are_noted_in_one_line() {
    let s = Spec {
        n_points: 5,
        labels: Some(vec!["RKNE", "LKNE", "RKNE", "LASI", "LKNE"]),
        analog_channels: 0,
        analog_per_frame: 0,
        ..Spec::default()
    };
    let c = parse_c3d(&write(&s)).unwrap();
    let notes: Vec<&String> = c
        .warnings
        .iter()
        .filter(|w| w.contains("repeated"))
        .collect();
    assert_eq!(notes.len(), 1, "{:?}", c.warnings);
    assert!(notes[0].contains("RKNE ×2") && notes[0].contains("LKNE ×2"));
    assert!(!notes[0].contains("LASI"));
    let t = c.to_trial().unwrap();
    assert_eq!(t.labels(), ["RKNE", "LKNE", "RKNE_2", "LASI", "LKNE_2"]);
    let c = parse_c3d(&write(&Spec::default())).unwrap();
    assert!(!c.warnings.iter().any(|w| w.contains("repeated")));
}
