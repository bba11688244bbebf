//! OpenSim's scaling inputs: `MarkerSet` files (OpenSim 3: `<body>`; OpenSim 4:
//! `<socket_parent_frame>`) attached to a model's text, and `ScaleTool` setup files.

use std::path::{Path, PathBuf};

use roxmltree::{Document, Node};

use crate::osim_read::xml::{child, elements, name, numbers, path_leaf, text};

/// Errors of a marker-set or scale-setup file: those of an `.osim` file (the same XML
/// reading, the same one-line messages).
pub use crate::osim_read::OsimReadError as SetupError;

/// One marker of a marker set.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerDef {
    pub name: String,
    pub body: String,
    /// Location in the body (m).
    pub location: [f64; 3],
    /// Kept where it is by marker placement.
    pub fixed: bool,
}

fn read(path: &Path) -> Result<String, SetupError> {
    crate::limits::read_text(path, crate::limits::DOCUMENT_BYTES, "setup").map_err(|source| {
        SetupError::Read {
            path: path.to_path_buf(),
            source,
        }
    })
}

fn invalid(path: &Path, doc: &Document, node: Node, message: String) -> SetupError {
    SetupError::Invalid {
        path: path.to_path_buf(),
        line: doc.text_pos_at(node.range().start).row,
        message,
    }
}

fn parse<'i>(path: &Path, text: &'i str) -> Result<Document<'i>, SetupError> {
    Document::parse(text).map_err(|e| SetupError::Invalid {
        path: path.to_path_buf(),
        line: e.pos().row,
        message: format!("not XML: {e}"),
    })
}

/// The markers of an OpenSim `MarkerSet` file (versions 3 and 4).
pub fn read_marker_set(path: &Path) -> Result<Vec<MarkerDef>, SetupError> {
    let t = read(path)?;
    let doc = parse(path, &t)?;
    let mut out = Vec::new();
    for m in doc
        .descendants()
        .filter(|n| n.tag_name().name() == "Marker")
    {
        let what = format!("Marker {:?}", name(m));
        let body = text(m, "socket_parent_frame")
            .or_else(|| text(m, "body"))
            .map(path_leaf)
            .filter(|b| !b.is_empty())
            .ok_or_else(|| {
                invalid(
                    path,
                    &doc,
                    m,
                    format!("{what}: no <body> or <socket_parent_frame>"),
                )
            })?;
        let v = numbers(m, "location")
            .map_err(|f| invalid(path, &doc, m, format!("{what}: {}", f.msg)))?;
        let [x, y, z] = v[..] else {
            return Err(invalid(
                path,
                &doc,
                m,
                format!("{what}: <location> needs three numbers"),
            ));
        };
        out.push(MarkerDef {
            name: name(m).to_string(),
            body: body.to_string(),
            location: [x, y, z],
            fixed: text(m, "fixed") == Some("true"),
        });
    }
    if out.is_empty() {
        return Err(SetupError::Invalid {
            path: path.to_path_buf(),
            line: 1,
            message: "no <Marker> elements".into(),
        });
    }
    Ok(out)
}

/// The model text with its `MarkerSet` replaced by `markers` (OpenSim 4 form), or one added
/// when the model has none. Everything else is kept byte for byte.
pub fn with_marker_set(model: &str, markers: &[MarkerDef]) -> Result<String, String> {
    let doc = Document::parse(model).map_err(|e| format!("not XML: {e}"))?;
    let m = child(doc.root_element(), "Model").ok_or("no <Model>")?;
    let mut set = String::from("<MarkerSet name=\"markerset\">\n\t\t\t<objects>\n");
    for d in markers {
        set.push_str(&format!(
            "\t\t\t\t<Marker name=\"{}\">\n\t\t\t\t\t<socket_parent_frame>/bodyset/{}</socket_parent_frame>\n\t\t\t\t\t<location>{} {} {}</location>\n\t\t\t\t\t<fixed>{}</fixed>\n\t\t\t\t</Marker>\n",
            crate::xml::escape(&d.name),
            crate::xml::escape(&d.body),
            d.location[0],
            d.location[1],
            d.location[2],
            d.fixed
        ));
    }
    set.push_str("\t\t\t</objects>\n\t\t\t<groups />\n\t\t</MarkerSet>");
    let (at, end) = match child(m, "MarkerSet") {
        Some(old) => (old.range().start, old.range().end),
        None => {
            let close = m.range().end - "</Model>".len();
            if !model[close..].starts_with("</Model>") {
                return Err("cannot find </Model>".into());
            }
            (close, close)
        }
    };
    let extra = if end == at { "\n\t" } else { "" };
    Ok(format!("{}{set}{extra}{}", &model[..at], &model[end..]))
}

/// A body group of a `Measurement`: the bodies it scales and the axes it names.
#[derive(Debug, Clone, PartialEq)]
pub struct SetupGroup {
    pub name: String,
    pub bodies: Vec<String>,
}

/// What a `ScaleTool` setup says, paths resolved against the setup's directory.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScaleSetup {
    pub model: Option<PathBuf>,
    pub marker_set: Option<PathBuf>,
    pub static_trial: Option<PathBuf>,
    /// Time range of the static trial (s).
    pub time_range: Option<[f64; 2]>,
    /// Subject mass (kg; absent or -1: none).
    pub mass: Option<f64>,
    /// Subject height (m; the file gives mm).
    pub height: Option<f64>,
    /// The applied measurements' body groups (when `scaling_order` has `measurements`).
    pub groups: Vec<SetupGroup>,
    /// The applied manual scales `(body, [sx, sy, sz])` of the `ScaleSet` (when
    /// `scaling_order` has `manualScale`); they override a measurement's factors.
    pub manual_scales: Vec<(String, [f64; 3])>,
    /// `preserve_mass_distribution` (OpenSim's default: true).
    pub preserve_mass_distribution: bool,
    /// Weights of the marker placer's `IKMarkerTask`s (a task not applied: weight 0).
    pub marker_weights: Vec<(String, f64)>,
    pub output_model: Option<PathBuf>,
}

fn optional_number(
    path: &Path,
    doc: &Document,
    node: Node,
    tag: &str,
) -> Result<Option<f64>, SetupError> {
    if child(node, tag).is_none() {
        return Ok(None);
    }
    let v = numbers(node, tag).map_err(|f| invalid(path, doc, node, f.msg))?;
    Ok(v.first().copied())
}

/// The `ModelScaler`'s measurements (their body groups), manual scales, scaling order and
/// mass distribution flag.
fn read_scaler(
    path: &Path,
    doc: &Document,
    scaler: Node,
    s: &mut ScaleSetup,
) -> Result<(), SetupError> {
    let order: Vec<&str> = text(scaler, "scaling_order")
        .unwrap_or("measurements")
        .split_whitespace()
        .collect();
    s.preserve_mass_distribution = text(scaler, "preserve_mass_distribution") != Some("false");
    let objects = |tag: &str| {
        child(scaler, tag)
            .and_then(|n| child(n, "objects"))
            .into_iter()
            .flat_map(elements)
    };
    if order.contains(&"measurements") {
        for m in objects("MeasurementSet").filter(|m| text(*m, "apply") != Some("false")) {
            let bodies: Vec<String> = child(m, "BodyScaleSet")
                .and_then(|b| child(b, "objects"))
                .map(|o| elements(o).map(|b| name(b).to_string()).collect())
                .unwrap_or_default();
            if !bodies.is_empty() {
                s.groups.push(SetupGroup {
                    name: name(m).to_string(),
                    bodies,
                });
            }
        }
    }
    if order.contains(&"manualScale") {
        for sc in objects("ScaleSet").filter(|m| text(*m, "apply") != Some("false")) {
            let body = text(sc, "segment").unwrap_or("").to_string();
            let v = numbers(sc, "scales").map_err(|f| invalid(path, doc, sc, f.msg))?;
            let [x, y, z] = v[..] else {
                return Err(invalid(
                    path,
                    doc,
                    sc,
                    format!("Scale of {body:?}: <scales> needs three numbers"),
                ));
            };
            s.manual_scales.push((body, [x, y, z]));
        }
    }
    Ok(())
}

/// Reads a `ScaleTool` setup file.
pub fn read_scale_setup(path: &Path) -> Result<ScaleSetup, SetupError> {
    let t = read(path)?;
    let doc = parse(path, &t)?;
    let tool = doc
        .descendants()
        .find(|n| n.tag_name().name() == "ScaleTool")
        .ok_or_else(|| invalid(path, &doc, doc.root_element(), "no <ScaleTool>".into()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let file = |node: Option<Node>, tag: &str| -> Option<PathBuf> {
        let v = text(node?, tag)?;
        (!v.is_empty() && v != "Unassigned").then(|| dir.join(v))
    };
    let number = |node: Node, tag: &str| optional_number(path, &doc, node, tag);
    let maker = child(tool, "GenericModelMaker");
    let scaler = child(tool, "ModelScaler");
    let placer = child(tool, "MarkerPlacer");
    let mut s = ScaleSetup {
        model: file(maker, "model_file"),
        marker_set: file(maker, "marker_set_file"),
        static_trial: file(scaler, "marker_file").or_else(|| file(placer, "marker_file")),
        mass: number(tool, "mass")?.filter(|m| *m > 0.0),
        height: number(tool, "height")?
            .filter(|h| *h > 0.0)
            .map(|h| h / 1000.0),
        output_model: file(placer, "output_model_file")
            .or_else(|| file(scaler, "output_model_file")),
        preserve_mass_distribution: true,
        ..Default::default()
    };
    if let Some(sc) = scaler {
        read_scaler(path, &doc, sc, &mut s)?;
    }
    if let Some(tasks) = placer
        .and_then(|p| child(p, "IKTaskSet"))
        .and_then(|t| child(t, "objects"))
    {
        for t in elements(tasks).filter(|t| t.tag_name().name() == "IKMarkerTask") {
            let w = if text(t, "apply") == Some("false") {
                0.0
            } else {
                number(t, "weight")?.unwrap_or(1.0)
            };
            s.marker_weights.push((name(t).to_string(), w));
        }
    }
    for node in [scaler, placer].into_iter().flatten() {
        if s.time_range.is_none() && child(node, "time_range").is_some() {
            let v = numbers(node, "time_range").map_err(|f| invalid(path, &doc, node, f.msg))?;
            if let [a, b] = v[..] {
                s.time_range = Some([a, b]);
            }
        }
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marker_sets_of_both_versions_attach_to_a_model() {
        let dir = tempfile::tempdir().unwrap();
        let v3 = dir.path().join("v3.xml");
        std::fs::write(
            &v3,
            "<OpenSimDocument Version=\"20302\"><MarkerSet><objects>\
             <Marker name=\"A\"><body> femur_r </body><location> 0.1 -0.2 0.03 </location>\
             <fixed> true </fixed></Marker></objects></MarkerSet></OpenSimDocument>",
        )
        .unwrap();
        let v4 = dir.path().join("v4.xml");
        std::fs::write(
            &v4,
            "<OpenSimDocument Version=\"40000\"><MarkerSet><objects>\
             <Marker name=\"B\"><socket_parent_frame>/bodyset/tibia_l</socket_parent_frame>\
             <location>1 2 3</location></Marker></objects></MarkerSet></OpenSimDocument>",
        )
        .unwrap();
        let a = read_marker_set(&v3).unwrap();
        assert_eq!(
            a,
            vec![MarkerDef {
                name: "A".into(),
                body: "femur_r".into(),
                location: [0.1, -0.2, 0.03],
                fixed: true
            }]
        );
        let b = read_marker_set(&v4).unwrap();
        assert_eq!(
            (b[0].body.as_str(), b[0].location, b[0].fixed),
            ("tibia_l", [1.0, 2.0, 3.0], false)
        );

        let model = "<OpenSimDocument Version=\"40000\"><Model name=\"m\"><BodySet/></Model></OpenSimDocument>";
        let with = with_marker_set(model, &a).unwrap();
        assert!(with.starts_with("<OpenSimDocument Version=\"40000\"><Model name=\"m\"><BodySet/>"));
        assert!(with.ends_with("</Model></OpenSimDocument>"));
        let doc = Document::parse(&with).unwrap();
        let m = doc
            .descendants()
            .find(|n| n.has_tag_name("Marker"))
            .unwrap();
        assert_eq!(text(m, "socket_parent_frame"), Some("/bodyset/femur_r"));
        assert_eq!(numbers(m, "location").unwrap(), vec![0.1, -0.2, 0.03]);
        // replacing an existing set keeps one
        let again = with_marker_set(&with, &b).unwrap();
        assert_eq!(again.matches("<MarkerSet").count(), 1);
        assert!(again.contains("/bodyset/tibia_l"));
    }

    #[test]
    fn a_scale_setup_names_its_files_mass_height_and_groups() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("setup.xml");
        std::fs::write(
            &p,
            "<OpenSimDocument><ScaleTool name=\"s\"><mass> 72.6 </mass><height> 1803.4 </height>\
             <GenericModelMaker><model_file> g.osim </model_file>\
             <marker_set_file> m.xml </marker_set_file></GenericModelMaker>\
             <ModelScaler><MeasurementSet><objects>\
             <Measurement name=\"thigh\"><apply> true </apply><BodyScaleSet><objects>\
             <BodyScale name=\"femur_r\"/><BodyScale name=\"femur_l\"/></objects></BodyScaleSet></Measurement>\
             <Measurement name=\"off\"><apply> false </apply><BodyScaleSet><objects>\
             <BodyScale name=\"torso\"/></objects></BodyScaleSet></Measurement>\
             </objects></MeasurementSet><marker_file> s.trc </marker_file>\
             <time_range> 1 2 </time_range></ModelScaler>\
             <MarkerPlacer><output_model_file> out.osim </output_model_file></MarkerPlacer>\
             </ScaleTool></OpenSimDocument>",
        )
        .unwrap();
        let s = read_scale_setup(&p).unwrap();
        assert_eq!(s.model, Some(dir.path().join("g.osim")));
        assert_eq!(s.marker_set, Some(dir.path().join("m.xml")));
        assert_eq!(s.static_trial, Some(dir.path().join("s.trc")));
        assert_eq!(s.output_model, Some(dir.path().join("out.osim")));
        assert_eq!(s.mass, Some(72.6));
        assert!((s.height.unwrap() - 1.8034).abs() < 1e-12);
        assert_eq!(s.time_range, Some([1.0, 2.0]));
        assert_eq!(
            s.groups,
            vec![SetupGroup {
                name: "thigh".into(),
                bodies: vec!["femur_r".into(), "femur_l".into()]
            }]
        );
        assert!(s.preserve_mass_distribution);
        assert!(s.manual_scales.is_empty() && s.marker_weights.is_empty());
    }

    #[test]
    fn a_scale_setup_gives_manual_scales_mass_flag_and_marker_weights() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("setup.xml");
        let setup = |order: &str| {
            format!(
                "<OpenSimDocument><ScaleTool name=\"s\"><ModelScaler>\
                 <scaling_order> {order} </scaling_order>\
                 <MeasurementSet><objects><Measurement name=\"thigh\"><BodyScaleSet><objects>\
                 <BodyScale name=\"femur_r\"/></objects></BodyScaleSet></Measurement></objects></MeasurementSet>\
                 <ScaleSet><objects>\
                 <Scale name=\"\"><scales> 1.1 1.2 1.3 </scales><segment> tibia_r </segment><apply> true </apply></Scale>\
                 <Scale name=\"\"><scales> 2 2 2 </scales><segment> torso </segment><apply> false </apply></Scale>\
                 </objects></ScaleSet><preserve_mass_distribution> false </preserve_mass_distribution>\
                 </ModelScaler><MarkerPlacer><IKTaskSet><objects>\
                 <IKMarkerTask name=\"R.ASIS\"><apply> true </apply><weight> 1000 </weight></IKMarkerTask>\
                 <IKMarkerTask name=\"Sternum\"><apply> false </apply><weight> 1 </weight></IKMarkerTask>\
                 <IKCoordinateTask name=\"knee\"><apply> true </apply><weight> 1 </weight></IKCoordinateTask>\
                 </objects></IKTaskSet></MarkerPlacer></ScaleTool></OpenSimDocument>"
            )
        };
        std::fs::write(&p, setup("manualScale")).unwrap();
        let s = read_scale_setup(&p).unwrap();
        assert!(s.groups.is_empty());
        assert_eq!(s.manual_scales, vec![("tibia_r".into(), [1.1, 1.2, 1.3])]);
        assert!(!s.preserve_mass_distribution);
        assert_eq!(
            s.marker_weights,
            vec![("R.ASIS".into(), 1000.0), ("Sternum".into(), 0.0)]
        );
        std::fs::write(&p, setup("measurements")).unwrap();
        let s = read_scale_setup(&p).unwrap();
        assert_eq!(s.groups.len(), 1);
        assert!(s.manual_scales.is_empty());
    }
}
