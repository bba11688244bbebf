//! The disagreements of `c3d_vs_python.rs` that are known and explained, and the files both
//! Python readers fail on.

use jointfit_io::c3d::C3dError;

/// Known, explained disagreements: (file name, reader, aspect, why). Aspects: `layout`
/// (frame/point counts and every sample: nothing of that reader is compared), `missing`
/// (the missing sets differ; coordinates compared where both have them), `first_frame`,
/// `rate`, `analog` (analog values).
pub const KNOWN: &[(&str, &str, &str, &str)] = &[
    (
        "kyowadengyo.c3d",
        "ezc3d",
        "layout",
        "POINT:USED says 12 points, the header 11. Only 11 fit the 152 declared frames into the \
         data section; ezc3d takes 12 and reads 145 frames whose 'coordinates' from frame 1 on \
         are analog words (≈2046). jointfit reads 11 points × 152 frames, smooth trajectories \
         (checked below); `c3d` rejects the file.",
    ),
    (
        "phasespace_sample.c3d",
        "ezc3d",
        "layout",
        "the parameter section is empty; ezc3d then reads 0 points × 0 frames, while the header \
         declares 40 float points × 701 frames, which is what `c3d` and jointfit read.",
    ),
    (
        "read_NOTworking2.c3d",
        "ezc3d",
        "first_frame",
        "the header's first frame is 0; ezc3d cannot express that 0-based (it reports 0, i.e. \
         frame 1); jointfit and `c3d` report 0 as stored.",
    ),
    (
        "Kistler.c3d",
        "ezc3d",
        "rate",
        "no POINT group (analog only); ezc3d invents POINT:RATE = 0, jointfit uses the header's \
         60 Hz (analog 600 Hz = 10 samples per frame, consistent).",
    ),
    (
        "561xxa01_anonym.C3D",
        "ezc3d",
        "layout",
        "no ANALOG:RATE: ezc3d then reads no analog words, although the header (word 3) and \
         ANALOG:USED declare 18 per frame, so its frames are 18 floats short from frame 1 on; \
         jointfit and `c3d` read 18 channels and agree on every sample.",
    ),
    (
        "standing.C3D",
        "ezc3d",
        "layout",
        "as 561xxa01_anonym: no ANALOG:RATE, ezc3d skips the 6 declared analog words per frame.",
    ),
    (
        "type1.C3D",
        "ezc3d",
        "layout",
        "as 561xxa01_anonym: no ANALOG:RATE, ezc3d skips the 6 declared analog words per frame.",
    ),
    (
        "Analysis.c3d",
        "ezc3d",
        "analog",
        "ANALOG:OFFSET is -32768 with ANALOG:FORMAT SIGNED; ezc3d uses |OFFSET| (32768); the \
         standard says signed here, as jointfit and `c3d` read it (the values are then ≈65536: \
         the writer most likely meant unsigned).",
    ),
    (
        "16bitanalog.c3d",
        "ezc3d",
        "analog",
        "channels 32–38 have ANALOG:OFFSET -32768 and no ANALOG:FORMAT; ezc3d uses |OFFSET|, \
         the standard (jointfit, `c3d`) signed -32768.",
    ),
    (
        "shd01.c3d",
        "ezc3d",
        "analog",
        "ANALOG:FORMAT is UNSIGNED, so the standard reads ANALOG:OFFSET -32752 as 32784 \
         (jointfit, `c3d`); ezc3d uses |OFFSET| = 32752.",
    ),
    (
        "admarche2.c3d",
        "c3d",
        "missing",
        "the writer put two raw 16-bit words (00 7F 00 7F) where the float residual word goes; \
         read as a float that is 1.7e38, non-negative, so valid (jointfit, ezc3d); `c3d` casts \
         it to int32, which overflows to a negative value, and marks every sample invalid.",
    ),
];

/// What jointfit does with a file that both Python readers fail on.
pub enum Expect {
    /// Reads it: frames, points, first label; trajectories are checked for sanity.
    Reads {
        frames: usize,
        points: usize,
        first_label: &'static str,
    },
    /// Rejects it with this error.
    Rejects(fn(&C3dError) -> bool, &'static str),
}

/// Files both ezc3d and `c3d` fail on, and why jointfit does what it does.
pub const BOTH_FAIL: &[(&str, Expect)] = &[
    // 0 bytes: nothing to read.
    (
        "Empty.c3d",
        Expect::Rejects(|e| matches!(e, C3dError::TooShort { len: 0 }), "TooShort"),
    ),
    // Integer data with header scale 0.0551 and POINT:SCALE 0.0215: the coordinates differ by
    // ×2.56 depending on which is believed (the header's gives plausible anatomy, shoulder
    // ≈1.46 m, but nothing in the file says so). Refused rather than guessed. (Also SGI/MIPS,
    // which ezc3d does not support; `c3d` refuses it for the same scale mismatch.)
    (
        "MACsample.c3d",
        Expect::Rejects(
            |e| matches!(e, C3dError::ScaleMismatch { .. }),
            "ScaleMismatch",
        ),
    ),
    // POINT:LABELS lacks its description-length byte; its next-record offset is right, so
    // following offsets (not sequential parsing) reads every parameter.
    (
        "mocap36.c3d",
        Expect::Reads {
            frames: 1380,
            points: 36,
            first_label: "Skeleton_Hip2",
        },
    ),
    // Same defect in POINT:LABELS (BTK calls the file badParameterOffset); labels keep their
    // inner blanks ("Point    1").
    (
        "badParameterOffset.c3d",
        Expect::Reads {
            frames: 111,
            points: 41,
            first_label: "Point    1",
        },
    ),
    // The data section (block 12) overwrites the end of the 12 declared parameter blocks in
    // the middle of EVENT_CONTEXT:LABELS; the parameters before it (POINT, ANALOG, ...) are
    // intact, so jointfit stops at the broken record (with a warning) and reads the data.
    (
        "bad_parameter_section.c3d",
        Expect::Reads {
            frames: 332,
            points: 45,
            first_label: "P1",
        },
    ),
];
