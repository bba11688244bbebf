//! Model files: a TOML model description on disk, or a built-in model by name.

use std::path::{Path, PathBuf};

use jointfit::model::lower_limb::{builtin, BUILTIN_NAMES};
use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, ModelError};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ModelFileError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A TOML syntax or schema error, on one line: `line L, column C: what`.
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: invalid model: {source}")]
    Invalid { path: PathBuf, source: ModelError },
    #[error(transparent)]
    Osim(#[from] crate::osim_read::OsimReadError),
    #[error("{name:?} is neither a model file nor a built-in model ({})", BUILTIN_NAMES.join(", "))]
    NotFound { name: String },
}

/// Reads a model description: a built-in name (`lower-limb-right`, `lower-limb-left`), an
/// OpenSim 4 `.osim` file (see [`crate::osim_read`]) or a TOML file path.
pub fn load_spec(name_or_path: &str) -> Result<ModelSpec, ModelFileError> {
    let path = Path::new(name_or_path);
    if BUILTIN_NAMES.contains(&name_or_path) && !path.exists() {
        return Ok(builtin(name_or_path).expect("listed built-in"));
    }
    if !path.exists() {
        return Err(ModelFileError::NotFound {
            name: name_or_path.to_string(),
        });
    }
    if is_osim(path) {
        return Ok(crate::osim_read::read_osim(path)?.spec);
    }
    let text = crate::limits::read_text(path, crate::limits::DOCUMENT_BYTES, "model").map_err(
        |source| ModelFileError::Read {
            path: path.to_path_buf(),
            source,
        },
    )?;
    ModelSpec::from_toml(&text).map_err(|e| ModelFileError::Parse {
        path: path.to_path_buf(),
        message: toml_one_line(&text, &e),
    })
}

/// Whether a path names an OpenSim model (`.osim`, any case).
pub fn is_osim(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("osim"))
}

/// A TOML error as one line, `line L, column C: message`, without the quoted source line
/// (which may be megabytes long); the message is capped at 200 characters.
fn toml_one_line(text: &str, e: &toml::de::Error) -> String {
    let msg: String = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
    let msg = if msg.chars().count() > 200 {
        format!("{}…", msg.chars().take(200).collect::<String>())
    } else {
        msg
    };
    match e.span() {
        Some(span) => {
            let before = &text.as_bytes()[..span.start.min(text.len())];
            let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
            let line_start = before
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1);
            let column = String::from_utf8_lossy(&before[line_start..])
                .chars()
                .count()
                + 1;
            format!("TOML error at line {line}, column {column}: {msg}")
        }
        None => format!("TOML error: {msg}"),
    }
}

/// Writes a model description as TOML, atomically (temp file + rename).
pub fn save_spec(path: &Path, spec: &ModelSpec) -> std::io::Result<()> {
    crate::atomic::write_atomic(path, spec.to_toml().as_bytes())
}

/// Reads and compiles a model (see [`load_spec`]).
pub fn load_model(name_or_path: &str) -> Result<Model, ModelFileError> {
    let spec = load_spec(name_or_path)?;
    Model::compile(&spec).map_err(|source| ModelFileError::Invalid {
        path: PathBuf::from(name_or_path),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_and_errors() {
        assert_eq!(
            load_model("lower-limb-left").unwrap().parameters().len(),
            27
        );
        let e = load_model("no-such-model").unwrap_err().to_string();
        assert_eq!(
            e,
            "\"no-such-model\" is neither a model file nor a built-in model (lower-limb, lower-limb-right, lower-limb-left)"
        );
        let dir = jointfit_testkit::scratch("mf");
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "name = \"x\"\nsegments = 3\n").unwrap();
        let e = load_model(bad.to_str().unwrap()).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", bad.display())), "{e}");
        assert!(e.contains("line 2"), "{e}");
        let invalid = dir.join("invalid.toml");
        let mut spec = builtin("lower-limb-right").unwrap();
        spec.markers[0].segment = "arm".into();
        std::fs::write(&invalid, spec.to_toml()).unwrap();
        let e = load_model(invalid.to_str().unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("invalid model: marker \"RASI\" refers to segment \"arm\""),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
