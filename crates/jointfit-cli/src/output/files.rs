//! [`Files`]: the inputs and outputs of one command, checked before any work so that no
//! output is an input or another output (see the parent module's docs).

use std::fs;
use std::path::{Component, Path, PathBuf};

use anyhow::{bail, Result};

/// How a file is known: device and inode when it exists, else its canonical directory and
/// name (or, when the directory does not exist either, the absolute path with `.` and `..`
/// resolved by spelling).
#[derive(Debug, PartialEq, Eq, Hash)]
enum Identity {
    Inode(u64, u64),
    Path(PathBuf),
}

fn identity(p: &Path) -> Identity {
    #[cfg(unix)]
    if let Ok(md) = fs::metadata(p) {
        use std::os::unix::fs::MetadataExt;
        return Identity::Inode(md.dev(), md.ino());
    }
    let canonical = match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) => {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            fs::canonicalize(dir).ok().map(|d| d.join(name))
        }
        _ => None,
    };
    // `t.trc/` and similar spellings: the file the directory and name lead to.
    #[cfg(unix)]
    if let Some(md) = canonical.as_ref().and_then(|c| fs::metadata(c).ok()) {
        use std::os::unix::fs::MetadataExt;
        return Identity::Inode(md.dev(), md.ino());
    }
    Identity::Path(canonical.unwrap_or_else(|| lexical_absolute(p)))
}

fn lexical_absolute(p: &Path) -> PathBuf {
    let base = std::env::current_dir().unwrap_or_default();
    let mut out = PathBuf::new();
    for c in base.join(p).components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// The `what` of the one input an in-place output may replace.
const MODEL: &str = "model";

struct Entry {
    what: String,
    path: PathBuf,
    /// Outputs only: may replace the model input (and no other input) when the command's
    /// `--force` is given.
    in_place_ok: bool,
    /// Outputs only: the command creates the file's directory when it is missing.
    creates_dir: bool,
}

/// The inputs and outputs of one command, checked before any work (see the module docs).
#[derive(Default)]
pub struct Files {
    inputs: Vec<Entry>,
    outputs: Vec<Entry>,
    force: bool,
}

impl Files {
    pub fn new() -> Files {
        Files::default()
    }

    /// An input file (`what` names it in messages, e.g. `"trial"`).
    pub fn input(mut self, what: &str, path: impl AsRef<Path>) -> Files {
        self.inputs.push(Entry {
            what: what.to_string(),
            path: path.as_ref().to_path_buf(),
            in_place_ok: false,
            creates_dir: false,
        });
        self
    }

    /// A model argument: an input when it names an existing file (not a built-in name).
    pub fn model(self, what: &str, name_or_path: &str) -> Files {
        if Path::new(name_or_path).is_file() {
            self.input(what, name_or_path)
        } else {
            self
        }
    }

    /// An output file, which must not be an input or another output; its directory must
    /// exist.
    pub fn output(mut self, what: &str, path: impl AsRef<Path>) -> Files {
        self.outputs.push(Entry {
            what: what.to_string(),
            path: path.as_ref().to_path_buf(),
            in_place_ok: false,
            creates_dir: false,
        });
        self
    }

    /// An output file `dir/name` whose directory the command creates when missing.
    pub fn output_in_dir(mut self, what: &str, dir: &Path, name: &str) -> Files {
        self.outputs.push(Entry {
            what: what.to_string(),
            path: dir.join(name),
            in_place_ok: false,
            creates_dir: true,
        });
        self
    }

    /// An output that may replace the input called `"model"` when `force` is set (an
    /// in-place update of the model file); it may never replace any other input (a trial, a
    /// marker set), with or without `force`.
    pub fn output_in_place(mut self, what: &str, path: impl AsRef<Path>, force: bool) -> Files {
        self.outputs.push(Entry {
            what: what.to_string(),
            path: path.as_ref().to_path_buf(),
            in_place_ok: true,
            creates_dir: false,
        });
        self.force |= force;
        self
    }

    /// Refuses outputs that are directories, lack a file name, coincide with an input
    /// (unless allowed) or with each other, or lie in a directory that does not exist.
    pub fn check(self) -> Result<()> {
        for o in &self.outputs {
            o.check_output()?;
        }
        self.check_clashes()?;
        for o in &self.outputs {
            let dir = match o.path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            if !o.creates_dir && !dir.is_dir() {
                bail!(
                    "{}: {} cannot be written: directory {} does not exist",
                    o.path.display(),
                    o.what,
                    dir.display()
                );
            }
        }
        Ok(())
    }

    /// No output is an input (but the model, in place with `--force`), and no two outputs
    /// are one file.
    fn check_clashes(&self) -> Result<()> {
        let ins: Vec<(&Entry, Identity)> = self
            .inputs
            .iter()
            .filter(|e| e.path.exists())
            .map(|e| (e, identity(&e.path)))
            .collect();
        let outs: Vec<(&Entry, Identity)> = self
            .outputs
            .iter()
            .map(|e| (e, identity(&e.path)))
            .collect();
        // By identity in hash maps: a batch may name many thousands of files.
        let mut inputs = std::collections::HashMap::new();
        for (i, iid) in &ins {
            inputs.entry(iid).or_insert(*i);
        }
        for (o, oid) in &outs {
            if let Some(i) = inputs.get(oid) {
                let model = i.what == MODEL;
                if !(o.in_place_ok && self.force && model) {
                    let hint = if o.in_place_ok && model {
                        " (add --force to update it in place)"
                    } else {
                        ""
                    };
                    bail!(
                        "{}: {} is the same file as {} {}; refusing to overwrite an input{hint}",
                        o.path.display(),
                        o.what,
                        i.what,
                        i.path.display()
                    );
                }
            }
        }
        let mut seen: std::collections::HashMap<&Identity, &Entry> =
            std::collections::HashMap::new();
        for (b, bid) in &outs {
            if let Some(a) = seen.insert(bid, b) {
                bail!(
                    "{} ({}) and {} ({}) are the same file; each output needs its own",
                    a.path.display(),
                    a.what,
                    b.path.display(),
                    b.what
                );
            }
        }
        Ok(())
    }
}

impl Entry {
    /// One output on its own: an interrupted commit into its directory finished first; a
    /// file name that is not a directory nor read-only; a directory the command creates that
    /// is not a file.
    fn check_output(&self) -> Result<()> {
        let o = self;
        // A writer killed during its commit into this directory: completed or undone
        // first, so this command starts from whole files (`jointfit_io::staging`).
        if let Some(dir) = o.path.parent() {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            for done in jointfit_io::staging::recover(dir) {
                super::stderr_fmt(format_args!(
                    "jointfit: note: {}: completed the commit of a run that was killed \
                     while writing it\n",
                    done.display()
                ));
            }
        }
        let shown = o.path.display();
        if o.path.file_name().is_none() {
            bail!("{shown}: {} does not name a file", o.what);
        }
        if o.path.is_dir() {
            bail!("{shown}: {} is a directory, not a file", o.what);
        }
        // A read-only file is one its owner protected: never silently replaced.
        if let Ok(md) = fs::metadata(&o.path) {
            if md.permissions().readonly() {
                bail!(
                    "{shown}: {} exists and is read-only; refusing to replace it (make it \
                     writable or choose another name)",
                    o.what
                );
            }
        }
        // Refused before any work: a long fit must not end on this error.
        if let (true, Some(dir)) = (o.creates_dir, o.path.parent()) {
            if dir.exists() && !dir.is_dir() {
                bail!(
                    "{}: {} exists and is not a directory ({} is written into it)",
                    dir.display(),
                    o.what,
                    o.path.file_name().unwrap_or_default().to_string_lossy()
                );
            }
        }
        Ok(())
    }
}

/// Refuses a model output whose extension names another format (`fit.osim` for a TOML
/// model, `fit.mot`, `fit.trc`): the file would hold a model in a format its name denies.
/// `formats` are the extensions written (lower case); a name without an extension, or with
/// one that names no format of motion capture or modelling (`fit.out`), is accepted.
pub fn check_model_extension(path: &Path, formats: &[&str]) -> Result<()> {
    const KNOWN: [&str; 12] = [
        "osim", "toml", "mot", "sto", "trc", "c3d", "csv", "json", "xml", "html", "svg", "txt",
    ];
    let Some(ext) = path.extension().and_then(|e| e.to_str()) else {
        return Ok(());
    };
    let is = |f: &&str| ext.eq_ignore_ascii_case(f);
    if formats.iter().any(is) || !KNOWN.iter().any(is) {
        return Ok(());
    }
    let names: Vec<String> = formats.iter().map(|f| format!(".{f}")).collect();
    bail!(
        "{}: the model is written as {}; a .{ext} name would mislabel it (name the output {})",
        path.display(),
        match formats {
            ["toml"] => "a jointfit model (TOML)".to_string(),
            _ => names.join(" or "),
        },
        names.join(" or ")
    )
}
