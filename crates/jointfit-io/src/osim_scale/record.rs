//! What `scale` did, written beside the subject model (`SUBJECT.osim` →
//! `SUBJECT.scale.json`) so that a report on that model can show the scaling: the factors
//! of each group with their SDs, every marker's offset from its scaled generic place, the
//! inputs and the fit's RMS. The model file itself stays what OpenSim's scaling writes; a
//! report on a model without the file simply has no scaling section.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// One group's factors (x, y, z of its bodies' frames) and their SDs; SD 0: held at given
/// factors (a setup's manual scale).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordGroup {
    pub name: String,
    pub bodies: Vec<String>,
    pub factors: [f64; 3],
    pub sd: [f64; 3],
}

/// One registered marker's offset from its scaled generic place (mm, in its body).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordMarker {
    pub name: String,
    pub body: String,
    pub moved_mm: [f64; 3],
    /// RMS distance to the data (mm); `None`: absent from the trials.
    pub rms_mm: Option<f64>,
}

/// The scaling of a subject model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScaleRecord {
    pub generic: String,
    pub static_trial: String,
    pub trials: Vec<String>,
    pub groups: Vec<RecordGroup>,
    pub markers: Vec<RecordMarker>,
    /// Marker RMS over the fitted frames (mm).
    pub rms_mm: f64,
    pub frames: usize,
    pub generic_mass: f64,
    pub total_mass: f64,
    /// Implausible factors, in words.
    pub flags: Vec<String>,
}

/// The record's path beside a model: `SUBJECT.osim` → `SUBJECT.scale.json`.
pub fn record_path(model: &Path) -> PathBuf {
    model.with_extension("scale.json")
}

/// Writes the record beside `model`.
pub fn write_record(model: &Path, record: &ScaleRecord) -> Result<PathBuf, String> {
    let path = record_path(model);
    let text = serde_json::to_string_pretty(record).map_err(|e| e.to_string())?;
    crate::atomic::write_atomic(&path, text.as_bytes())
        .map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
    Ok(path)
}

/// The record beside `model`, if there is one.
pub fn read_record(model: &Path) -> Result<Option<ScaleRecord>, String> {
    let path = record_path(model);
    if !path.is_file() {
        return Ok(None);
    }
    let text = crate::limits::read_text(&path, crate::limits::DOCUMENT_BYTES, "scale record")
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| format!("{}: not a scale record: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_reads_back_from_beside_its_model() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("subject.osim");
        assert_eq!(read_record(&model).unwrap(), None);
        let rec = ScaleRecord {
            generic: "g.osim".into(),
            static_trial: "s.trc".into(),
            trials: vec!["w.trc".into()],
            groups: vec![RecordGroup {
                name: "thigh".into(),
                bodies: vec!["femur_r".into()],
                factors: [1.1, 1.1, 1.1],
                sd: [0.02; 3],
            }],
            markers: vec![RecordMarker {
                name: "R.Knee".into(),
                body: "femur_r".into(),
                moved_mm: [1.0, -2.0, 3.5],
                rms_mm: None,
            }],
            rms_mm: 3.3,
            frames: 1,
            generic_mass: 75.0,
            total_mass: 72.6,
            flags: vec![],
        };
        let path = write_record(&model, &rec).unwrap();
        assert_eq!(path, dir.path().join("subject.scale.json"));
        assert_eq!(read_record(&model).unwrap(), Some(rec));
        std::fs::write(&path, "{").unwrap();
        let e = read_record(&model).unwrap_err();
        assert!(
            e.starts_with(&format!("{}: not a scale record", path.display())),
            "{e}"
        );
    }
}
