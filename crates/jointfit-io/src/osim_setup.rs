//! OpenSim `InverseKinematicsTool` setup files (OpenSim 3.x and 4.x) and `IKTaskSet` files.
//!
//! What a setup says, read as OpenSim 4.6 reads it (`InverseKinematicsTool`,
//! `InverseKinematicsToolBase`, `IKTaskSet`, `IKMarkerTask`, `IKCoordinateTask`):
//!
//! * `model_file`, `marker_file` (TRC, or STO of marker positions), `coordinate_file` (for
//!   `from_file` coordinate tasks), `output_motion_file`, `results_directory` (where the marker
//!   errors go), `time_range` (default: the whole trial), `accuracy` (default 1e-5),
//!   `constraint_weight` (default infinity), `report_errors` (default true);
//! * the `IKTaskSet`, inline or through OpenSim's `file` attribute: `IKMarkerTask`s (`apply`,
//!   default true; `weight`, default 0) and `IKCoordinateTask`s (the same, and `value_type`
//!   `default_value` (the model's default value of the coordinate, the default), `manual_value`
//!   (the task's `value`) or `from_file` (the coordinate file's column)).
//!
//! Paths, as OpenSim resolves them. `InverseKinematicsTool::run` loads `model_file` first, from
//! the process's working directory, and only then changes the working directory to the setup
//! file's directory (`IO::CwdChanger::changeToParentOf`) to read the marker and coordinate files
//! and to write the motion and the errors. So `marker_file`, `coordinate_file`,
//! `output_motion_file` and `results_directory` are relative to the setup file's directory.
//! `model_file` is relative to the working directory in OpenSim 4.6; where no file is there,
//! [`IkSetup::model_path`] takes it relative to the setup file's directory, as OpenSim's other
//! tools (`AbstractTool::loadModel`) resolve it. Empty and `Unassigned` values are unset.
//!
//! The parser checks the shape (an `InverseKinematicsTool` in an `OpenSimDocument`, numbers
//! where numbers belong) and names the file and line of anything it refuses; what the values
//! mean for a model is the caller's (`jointfit ik --setup`).

use std::path::{Path, PathBuf};

use roxmltree::{Document, Node};
use thiserror::Error;

/// Why a setup or task-set file was refused.
#[derive(Debug, Error)]
pub enum SetupError {
    #[error("{path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not XML: {message}")]
    Xml { path: String, message: String },
    #[error("{path}, line {line}: {message}")]
    Invalid {
        path: String,
        line: u32,
        message: String,
    },
}

/// Where a coordinate task takes its target from (OpenSim's `value_type`).
#[derive(Debug, Clone, PartialEq)]
pub enum TaskValue {
    /// The coordinate's default value in the model (`default_value`).
    Default,
    /// A fixed value (`manual_value`; rad or m, as OpenSim's `value`).
    Manual(f64),
    /// The coordinate's column of the setup's `coordinate_file` (`from_file`).
    FromFile,
}

/// One `IKMarkerTask`.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerTask {
    pub name: String,
    pub apply: bool,
    pub weight: f64,
    /// Line in the file it was read from.
    pub line: u32,
}

/// One `IKCoordinateTask`.
#[derive(Debug, Clone, PartialEq)]
pub struct CoordinateTaskSpec {
    pub name: String,
    pub apply: bool,
    pub weight: f64,
    pub value: TaskValue,
    /// Line in the file it was read from.
    pub line: u32,
}

/// An `IKTaskSet`: the marker and coordinate tasks in file order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IkTaskSet {
    pub markers: Vec<MarkerTask>,
    pub coordinates: Vec<CoordinateTaskSpec>,
    /// The file the tasks were read from (the setup itself, or its `file` attribute's target).
    pub path: PathBuf,
}

impl IkTaskSet {
    /// The weight of every marker in `names` (model markers) in OpenSim's IK
    /// (`InverseKinematicsTool::populateReferences`, `MarkersReference`): when the set applies at
    /// least one marker task, the markers of the applied tasks are tracked with their tasks'
    /// weights and every other marker is left out (weight 0); when it applies none, every marker
    /// is tracked with weight 1.
    pub fn marker_weights(&self, names: &[&str]) -> Vec<f64> {
        let applied: Vec<&MarkerTask> = self.markers.iter().filter(|t| t.apply).collect();
        if applied.is_empty() {
            return vec![1.0; names.len()];
        }
        names
            .iter()
            .map(|n| {
                applied
                    .iter()
                    .rev()
                    .find(|t| t.name == *n)
                    .map_or(0.0, |t| t.weight)
            })
            .collect()
    }

    /// Sets the marker weights of `spec` to those of OpenSim's IK with these tasks
    /// ([`IkTaskSet::marker_weights`]): the weights `jointfit ik --setup` fits with, and the
    /// calibration's marker weights when it takes a setup's tasks. Returns the names of the
    /// applied marker tasks that name no marker of `spec` (OpenSim ignores them).
    pub fn apply_marker_weights(&self, spec: &mut jointfit::model::spec::ModelSpec) -> Vec<String> {
        let names: Vec<&str> = spec.markers.iter().map(|m| m.name.as_str()).collect();
        let weights = self.marker_weights(&names);
        let unknown = self
            .markers
            .iter()
            .filter(|t| t.apply && !names.contains(&t.name.as_str()))
            .map(|t| t.name.clone())
            .collect();
        for (m, w) in spec.markers.iter_mut().zip(weights) {
            m.weight = w;
        }
        unknown
    }

    /// The applied coordinate tasks (OpenSim skips the others).
    pub fn applied_coordinates(&self) -> impl Iterator<Item = &CoordinateTaskSpec> {
        self.coordinates.iter().filter(|t| t.apply)
    }
}

/// An `InverseKinematicsTool` setup.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSetup {
    /// The setup file.
    pub path: PathBuf,
    /// The tool's `name` attribute (OpenSim names the marker-errors file after it).
    pub name: String,
    /// `model_file` as written (`None`: unset).
    pub model_file: Option<String>,
    /// `marker_file` as written.
    pub marker_file: Option<String>,
    /// `coordinate_file` as written.
    pub coordinate_file: Option<String>,
    /// `output_motion_file` as written.
    pub output_motion_file: Option<String>,
    /// `results_directory` as written.
    pub results_directory: Option<String>,
    /// `time_range` (s; default `[−∞, ∞]`).
    pub time_range: [f64; 2],
    /// `accuracy` (default 1e-5).
    pub accuracy: f64,
    /// `constraint_weight` (default infinity).
    pub constraint_weight: f64,
    /// `report_errors` (default true).
    pub report_errors: bool,
    pub tasks: IkTaskSet,
}

impl IkSetup {
    /// The setup file's directory (`.` for a bare file name).
    pub fn dir(&self) -> PathBuf {
        match self.path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        }
    }
    /// A path of the setup relative to the setup file's directory (absolute paths as they are).
    pub fn relative_to_setup(&self, raw: &str) -> PathBuf {
        let p = Path::new(raw);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir().join(p)
        }
    }
    /// The model file: relative to the working directory (OpenSim 4.6's IK tool), else, when
    /// nothing is there, relative to the setup file's directory (see the module docs).
    pub fn model_path(&self) -> Option<PathBuf> {
        let raw = self.model_file.as_deref()?;
        let here = PathBuf::from(raw);
        if here.is_absolute() || here.exists() {
            return Some(here);
        }
        Some(self.relative_to_setup(raw))
    }
    /// The marker file, relative to the setup file's directory.
    pub fn marker_path(&self) -> Option<PathBuf> {
        self.marker_file
            .as_deref()
            .map(|r| self.relative_to_setup(r))
    }
    /// The coordinate file, relative to the setup file's directory.
    pub fn coordinate_path(&self) -> Option<PathBuf> {
        self.coordinate_file
            .as_deref()
            .map(|r| self.relative_to_setup(r))
    }
    /// The output motion file, relative to the setup file's directory (OpenSim writes it
    /// there, not into `results_directory`).
    pub fn output_path(&self) -> Option<PathBuf> {
        self.output_motion_file
            .as_deref()
            .map(|r| self.relative_to_setup(r))
    }
    /// The results directory (the marker errors), relative to the setup file's directory;
    /// the setup file's directory when unset.
    pub fn results_path(&self) -> PathBuf {
        match self.results_directory.as_deref() {
            Some(r) => self.relative_to_setup(r),
            None => self.dir(),
        }
    }
}

fn read_text(path: &Path) -> Result<String, SetupError> {
    crate::limits::read_text(path, crate::limits::DOCUMENT_BYTES, "setup").map_err(|source| {
        SetupError::Read {
            path: path.display().to_string(),
            source,
        }
    })
}

fn parse_doc<'i>(text: &'i str, path: &Path) -> Result<Document<'i>, SetupError> {
    Document::parse(text).map_err(|e| SetupError::Xml {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

/// A refusal at `node`'s line.
fn invalid(path: &Path, node: Node, message: String) -> SetupError {
    let line = node.document().text_pos_at(node.range().start).row;
    SetupError::Invalid {
        path: path.display().to_string(),
        line,
        message,
    }
}

fn line_of(node: Node) -> u32 {
    node.document().text_pos_at(node.range().start).row
}

fn child<'a, 'i>(node: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == tag)
}

/// An element's text with comments beside it set aside ([`crate::xml::value_piece`]; the
/// first piece when comments split it).
fn value_of<'a>(c: Node<'a, '_>) -> &'a str {
    let piece = match crate::xml::value_piece(c) {
        Ok(p) => p,
        Err(_) => c.children().find(|t| t.is_text()),
    };
    piece.and_then(|t| t.text()).unwrap_or("")
}

/// A child's text, trimmed; `None` when absent, empty or `Unassigned`.
fn text_value(node: Node, tag: &str) -> Option<String> {
    let t = value_of(child(node, tag)?).trim().to_string();
    (!t.is_empty() && t != "Unassigned").then_some(t)
}

/// One number as OpenSim writes it (`Inf`, `-Inf`, `1e-005` included).
fn parse_number(s: &str) -> Option<f64> {
    match s.to_ascii_lowercase().as_str() {
        "inf" | "+inf" | "infinity" => Some(f64::INFINITY),
        "-inf" | "-infinity" => Some(f64::NEG_INFINITY),
        _ => s.parse::<f64>().ok(),
    }
}

fn numbers(path: &Path, node: Node, tag: &str) -> Result<Option<Vec<f64>>, SetupError> {
    let Some(c) = child(node, tag) else {
        return Ok(None);
    };
    let text = match crate::xml::value_piece(c) {
        Ok(piece) => piece.and_then(|t| t.text()).unwrap_or(""),
        Err(n) => return Err(invalid(path, c, crate::xml::split_value_message(tag, n))),
    };
    let mut out = Vec::new();
    for t in text.split_whitespace() {
        match parse_number(t) {
            Some(v) => out.push(v),
            None => return Err(invalid(path, c, format!("<{tag}>: {t:?} is not a number"))),
        }
    }
    Ok(Some(out))
}

fn number(path: &Path, node: Node, tag: &str, default: f64) -> Result<f64, SetupError> {
    match numbers(path, node, tag)? {
        None => Ok(default),
        Some(v) if v.is_empty() => Ok(default),
        Some(v) if v.len() == 1 => Ok(v[0]),
        Some(v) => Err(invalid(
            path,
            child(node, tag).expect("present"),
            format!("<{tag}> needs one number, has {}", v.len()),
        )),
    }
}

fn flag(path: &Path, node: Node, tag: &str, default: bool) -> Result<bool, SetupError> {
    let Some(c) = child(node, tag) else {
        return Ok(default);
    };
    match value_of(c).trim().to_ascii_lowercase().as_str() {
        "" => Ok(default),
        "true" | "1" => Ok(true),
        "false" | "0" => Ok(false),
        t => Err(invalid(
            path,
            c,
            format!("<{tag}>: {t:?} is neither true nor false"),
        )),
    }
}

/// Reads an `InverseKinematicsTool` setup file.
pub fn read_ik_setup(path: &Path) -> Result<IkSetup, SetupError> {
    let text = read_text(path)?;
    parse_ik_setup(&text, path)
}

/// Parses the text of an `InverseKinematicsTool` setup file read from `path` (named in errors;
/// its directory resolves the setup's relative paths and the task set's `file` attribute).
pub fn parse_ik_setup(text: &str, path: &Path) -> Result<IkSetup, SetupError> {
    let doc = parse_doc(text, path)?;
    let root = doc.root_element();
    let tool = match root.tag_name().name() {
        "OpenSimDocument" => child(root, "InverseKinematicsTool"),
        "InverseKinematicsTool" => Some(root),
        _ => None,
    };
    let Some(tool) = tool else {
        let what = if child(root, "IKTool").is_some() || root.tag_name().name() == "IKTool" {
            "an OpenSim 2 IKTool setup (save it from OpenSim 3 or 4 to convert it)".to_string()
        } else {
            format!(
                "no <InverseKinematicsTool> in <{}> (not an OpenSim IK setup file)",
                root.tag_name().name()
            )
        };
        return Err(invalid(path, root, what));
    };
    let time_range = match numbers(path, tool, "time_range")? {
        None => [f64::NEG_INFINITY, f64::INFINITY],
        Some(v) if v.is_empty() => [f64::NEG_INFINITY, f64::INFINITY],
        Some(v) if v.len() == 2 => [v[0], v[1]],
        Some(v) => {
            return Err(invalid(
                path,
                child(tool, "time_range").expect("present"),
                format!("<time_range> needs two numbers, has {}", v.len()),
            ))
        }
    };
    if time_range[1] < time_range[0] {
        return Err(invalid(
            path,
            child(tool, "time_range").expect("present"),
            format!(
                "<time_range> ends ({}) before it starts ({})",
                time_range[1], time_range[0]
            ),
        ));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tasks = match child(tool, "IKTaskSet") {
        None => IkTaskSet {
            path: path.to_path_buf(),
            ..IkTaskSet::default()
        },
        Some(set) => match set.attribute("file") {
            Some(f) if !f.trim().is_empty() && f.trim() != "Unassigned" => {
                let p = Path::new(f.trim());
                read_task_set(&if p.is_absolute() {
                    p.to_path_buf()
                } else {
                    dir.join(p)
                })?
            }
            _ => task_set(path, set)?,
        },
    };
    let accuracy = number(path, tool, "accuracy", 1e-5)?;
    if accuracy.is_nan() || accuracy <= 0.0 {
        return Err(invalid(
            path,
            child(tool, "accuracy").expect("present"),
            format!("<accuracy> must be positive, is {accuracy}"),
        ));
    }
    Ok(IkSetup {
        path: path.to_path_buf(),
        name: tool.attribute("name").unwrap_or("").to_string(),
        model_file: text_value(tool, "model_file"),
        marker_file: text_value(tool, "marker_file"),
        coordinate_file: text_value(tool, "coordinate_file"),
        output_motion_file: text_value(tool, "output_motion_file"),
        results_directory: text_value(tool, "results_directory"),
        time_range,
        accuracy,
        constraint_weight: number(path, tool, "constraint_weight", f64::INFINITY)?,
        report_errors: flag(path, tool, "report_errors", true)?,
        tasks,
    })
}

/// Reads the tasks of an `IKTaskSet` file (root `OpenSimDocument` or `IKTaskSet`), or of the
/// `IKTaskSet` of an `InverseKinematicsTool` setup file.
pub fn read_task_set(path: &Path) -> Result<IkTaskSet, SetupError> {
    let text = read_text(path)?;
    let doc = parse_doc(&text, path)?;
    let root = doc.root_element();
    let set = if root.tag_name().name() == "IKTaskSet" {
        Some(root)
    } else {
        child(root, "IKTaskSet")
            .or_else(|| child(root, "InverseKinematicsTool").and_then(|t| child(t, "IKTaskSet")))
    };
    match set {
        Some(set) if set.attribute("file").is_some_and(|f| !f.trim().is_empty()) => {
            // A task set in a setup file that points to another file.
            drop(doc);
            let setup = parse_ik_setup(&text, path)?;
            Ok(setup.tasks)
        }
        Some(set) => task_set(path, set),
        None => Err(invalid(
            path,
            root,
            format!("no <IKTaskSet> in <{}>", root.tag_name().name()),
        )),
    }
}

fn task_set(path: &Path, set: Node) -> Result<IkTaskSet, SetupError> {
    let mut out = IkTaskSet {
        path: path.to_path_buf(),
        ..IkTaskSet::default()
    };
    let Some(objects) = child(set, "objects") else {
        return Ok(out);
    };
    for task in objects.children().filter(|c| c.is_element()) {
        let name = task.attribute("name").unwrap_or("").to_string();
        let kind = task.tag_name().name();
        if name.is_empty() {
            return Err(invalid(path, task, format!("<{kind}> without a name")));
        }
        let apply = flag(path, task, "apply", true)?;
        let weight = number(path, task, "weight", 0.0)?;
        if weight.is_nan() || weight < 0.0 {
            return Err(invalid(
                path,
                task,
                format!("{kind} {name:?}: weight {weight} is not a non-negative number"),
            ));
        }
        let line = line_of(task);
        match kind {
            "IKMarkerTask" => out.markers.push(MarkerTask {
                name,
                apply,
                weight,
                line,
            }),
            "IKCoordinateTask" => {
                let value_type =
                    text_value(task, "value_type").unwrap_or_else(|| "default_value".to_string());
                let value = match value_type.to_ascii_lowercase().as_str() {
                    "default_value" => TaskValue::Default,
                    "manual_value" => TaskValue::Manual(number(path, task, "value", 0.0)?),
                    "from_file" => TaskValue::FromFile,
                    other => {
                        return Err(invalid(
                            path,
                            child(task, "value_type").unwrap_or(task),
                            format!(
                                "IKCoordinateTask {name:?}: value_type {other:?} is not \
                                 default_value, manual_value or from_file"
                            ),
                        ))
                    }
                };
                out.coordinates.push(CoordinateTaskSpec {
                    name,
                    apply,
                    weight,
                    value,
                    line,
                });
            }
            other => {
                return Err(invalid(
                    path,
                    task,
                    format!(
                        "<{other}> in an IKTaskSet (expected IKMarkerTask or IKCoordinateTask)"
                    ),
                ))
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const V3: &str = r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="30000">
	<InverseKinematicsTool name="subject01">
		<results_directory>./</results_directory>
		<input_directory />
		<model_file>subject01_simbody.osim</model_file>
		<constraint_weight>20</constraint_weight>
		<accuracy>1e-005</accuracy>
		<IKTaskSet name="gait2392_IK">
			<objects>
				<IKMarkerTask name="Sternum">
					<apply>true</apply>
					<weight>1</weight>
				</IKMarkerTask>
				<IKMarkerTask name="R.ASIS">
					<weight>10</weight>
				</IKMarkerTask>
				<IKMarkerTask name="Top.Head">
					<apply>false</apply>
					<weight>0.1</weight>
				</IKMarkerTask>
				<IKCoordinateTask name="subtalar_angle_r">
					<apply>true</apply>
					<weight>1000</weight>
					<value_type>default_value</value_type>
					<value>0</value>
				</IKCoordinateTask>
				<IKCoordinateTask name="knee_angle_r">
					<weight>2</weight>
					<value_type>manual_value</value_type>
					<value>-0.5</value>
				</IKCoordinateTask>
			</objects>
			<groups />
		</IKTaskSet>
		<marker_file>data/subject01_walk1.trc</marker_file>
		<coordinate_file></coordinate_file>
		<time_range> 0.5 2.5</time_range>
		<report_errors>true</report_errors>
		<output_motion_file>out/subject01_walk1_ik.mot</output_motion_file>
	</InverseKinematicsTool>
</OpenSimDocument>
"#;

    #[test]
    fn reads_an_opensim_3_setup() {
        let s = parse_ik_setup(V3, Path::new("/a/b/setup.xml")).unwrap();
        assert_eq!(s.name, "subject01");
        assert_eq!(s.time_range, [0.5, 2.5]);
        assert_eq!(s.accuracy, 1e-5);
        assert_eq!(s.constraint_weight, 20.0);
        assert!(s.coordinate_file.is_none());
        assert_eq!(
            s.marker_path().unwrap(),
            PathBuf::from("/a/b/data/subject01_walk1.trc")
        );
        assert_eq!(
            s.output_path().unwrap(),
            PathBuf::from("/a/b/out/subject01_walk1_ik.mot")
        );
        assert_eq!(s.results_path(), PathBuf::from("/a/b/./"));
        // Not in the working directory: the setup's directory.
        assert_eq!(
            s.model_path().unwrap(),
            PathBuf::from("/a/b/subject01_simbody.osim")
        );
        let t = &s.tasks;
        assert_eq!(t.markers.len(), 3);
        assert_eq!(t.markers[1].weight, 10.0);
        assert!(t.markers[1].apply, "apply defaults to true");
        assert_eq!(t.markers[1].line, 15);
        assert_eq!(t.coordinates[0].value, TaskValue::Default);
        assert_eq!(t.coordinates[1].value, TaskValue::Manual(-0.5));
        // Applied marker tasks only; markers without one are left out.
        assert_eq!(
            t.marker_weights(&["Sternum", "R.ASIS", "Top.Head", "C7"]),
            vec![1.0, 10.0, 0.0, 0.0]
        );
    }

    #[test]
    fn marker_weights_applied_to_a_model_description() {
        let s = parse_ik_setup(V3, Path::new("setup.xml")).unwrap();
        let mut spec =
            jointfit::model::lower_limb::lower_limb(jointfit::model::lower_limb::Side::Right);
        spec.markers[0].name = "Sternum".into();
        spec.markers[1].name = "R.ASIS".into();
        let unknown = s.tasks.apply_marker_weights(&mut spec);
        // Top.Head's task is not applied: not reported.
        assert!(unknown.is_empty(), "{unknown:?}");
        assert_eq!(spec.markers[0].weight, 1.0);
        assert_eq!(spec.markers[1].weight, 10.0);
        assert!(spec.markers[2..].iter().all(|m| m.weight == 0.0));
        // Applied tasks without a marker are reported.
        let mut spec =
            jointfit::model::lower_limb::lower_limb(jointfit::model::lower_limb::Side::Right);
        assert_eq!(
            s.tasks.apply_marker_weights(&mut spec),
            ["Sternum", "R.ASIS"]
        );
    }

    #[test]
    fn no_applied_marker_task_tracks_every_marker_with_weight_one() {
        let text = V3
            .replace(
                "<apply>true</apply>\n\t\t\t\t\t<weight>1</weight>",
                "<apply>false</apply>",
            )
            .replace("<weight>10</weight>", "<apply>false</apply>");
        let s = parse_ik_setup(&text, Path::new("setup.xml")).unwrap();
        assert!(s.tasks.markers.iter().all(|m| !m.apply));
        assert_eq!(s.tasks.marker_weights(&["Sternum", "C7"]), vec![1.0, 1.0]);
        assert_eq!(s.dir(), PathBuf::from("."));
    }

    #[test]
    fn opensim_4_defaults_and_infinities() {
        let text = r#"<OpenSimDocument Version="40000"><InverseKinematicsTool name="x">
            <model_file>Unassigned</model_file>
            <constraint_weight>Inf</constraint_weight>
            <time_range>-Inf Inf</time_range>
            <IKTaskSet><objects/></IKTaskSet>
        </InverseKinematicsTool></OpenSimDocument>"#;
        let s = parse_ik_setup(text, Path::new("s.xml")).unwrap();
        assert!(s.model_file.is_none());
        assert_eq!(s.time_range, [f64::NEG_INFINITY, f64::INFINITY]);
        assert_eq!(s.constraint_weight, f64::INFINITY);
        assert_eq!(s.accuracy, 1e-5);
        assert!(s.report_errors);
    }

    #[test]
    fn refusals_name_the_file_and_line() {
        let bad = V3.replace("<weight>10</weight>", "<weight>ten</weight>");
        let e = parse_ik_setup(&bad, Path::new("setup.xml")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "setup.xml, line 16: <weight>: \"ten\" is not a number"
        );
        let bad = V3.replace("default_value", "spline");
        let e = parse_ik_setup(&bad, Path::new("setup.xml")).unwrap_err();
        assert!(e.to_string().contains("value_type \"spline\""), "{e}");
        let bad = V3.replace(" 0.5 2.5", "2.5 0.5");
        let e = parse_ik_setup(&bad, Path::new("setup.xml")).unwrap_err();
        assert!(e.to_string().contains("ends (0.5) before it starts"), "{e}");
        let e = parse_ik_setup(
            "<OpenSimDocument><Model/></OpenSimDocument>",
            Path::new("m.osim"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("not an OpenSim IK setup"), "{e}");
        let e = parse_ik_setup("<a>", Path::new("x.xml")).unwrap_err();
        assert!(e.to_string().starts_with("x.xml: not XML"), "{e}");
    }

    #[test]
    fn task_set_through_the_file_attribute() {
        let dir = std::env::temp_dir().join(format!("jointfit-setup-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("tasks")).unwrap();
        std::fs::write(
            dir.join("tasks/set.xml"),
            r#"<OpenSimDocument Version="40000"><IKTaskSet name="t"><objects>
               <IKMarkerTask name="A"><weight>3</weight></IKMarkerTask>
               <IKCoordinateTask name="q"><weight>5</weight><value_type>from_file</value_type></IKCoordinateTask>
               </objects></IKTaskSet></OpenSimDocument>"#,
        )
        .unwrap();
        let setup = dir.join("setup.xml");
        std::fs::write(
            &setup,
            r#"<OpenSimDocument Version="40000"><InverseKinematicsTool>
               <IKTaskSet file="tasks/set.xml"/></InverseKinematicsTool></OpenSimDocument>"#,
        )
        .unwrap();
        let s = read_ik_setup(&setup).unwrap();
        assert_eq!(s.tasks.markers[0].weight, 3.0);
        assert_eq!(s.tasks.coordinates[0].value, TaskValue::FromFile);
        assert_eq!(s.tasks.path, dir.join("tasks/set.xml"));
        // The same tasks read from the setup or from the task-set file.
        assert_eq!(read_task_set(&setup).unwrap(), s.tasks);
        assert_eq!(read_task_set(&dir.join("tasks/set.xml")).unwrap(), s.tasks);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
