//! `jointfit model show <MODEL> [--json]`.

use anyhow::Result;
use clap::Subcommand;
use jointfit::model::{CoordKind, JointKind, Model};
use serde::Serialize;

use crate::table::Table;

#[derive(Subcommand)]
pub enum ModelCommand {
    /// Print segments, joints, coordinates, parameters and markers of a model.
    Show {
        /// A model TOML file or a built-in model: lower-limb, lower-limb-right, lower-limb-left.
        model: String,
        /// Print JSON instead of tables.
        #[arg(long)]
        json: bool,
    },
}

pub fn run(cmd: ModelCommand) -> Result<()> {
    match cmd {
        ModelCommand::Show { model, json } => {
            let model = jointfit_io::model_file::load_model(&model)?;
            let summary = Summary::of(&model);
            if json {
                println!("{}", serde_json::to_string_pretty(&summary)?);
            } else {
                print!("{}", summary.render());
            }
            Ok(())
        }
    }
}

/// Everything `model show` prints, in display units (mm, deg).
#[derive(Serialize)]
struct Summary {
    name: String,
    description: String,
    segments: Vec<SegmentRow>,
    joints: Vec<JointRow>,
    coordinates: Vec<CoordRow>,
    parameters: Vec<ParamRow>,
    markers: Vec<MarkerRow>,
}

#[derive(Serialize)]
struct SegmentRow {
    name: String,
    parent: String,
}

#[derive(Serialize)]
struct JointRow {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    axes: Vec<[f64; 3]>,
    parent: String,
    child: String,
    coordinates: Vec<String>,
}

#[derive(Serialize)]
struct CoordRow {
    name: String,
    joint: String,
    unit: &'static str,
    range: [f64; 2],
    default: f64,
}

#[derive(Serialize)]
struct ParamRow {
    group: String,
    segment: String,
    name: String,
    unit: &'static str,
    nominal: f64,
    lower: f64,
    upper: f64,
    description: String,
}

#[derive(Serialize)]
struct MarkerRow {
    name: String,
    segment: String,
    position_mm: [f64; 3],
    weight: f64,
}

fn round(x: f64, decimals: i32) -> f64 {
    let k = 10f64.powi(decimals);
    (x * k).round() / k
}

impl Summary {
    fn of(model: &Model) -> Summary {
        let seg_name = |s: Option<jointfit::model::SegmentId>| {
            s.map_or("ground".to_string(), |s| model.segments()[s.0].name.clone())
        };
        let axes = |k: &JointKind| -> Vec<[f64; 3]> {
            let v = |a: &nalgebra::Vector3<f64>| [a.x, a.y, a.z];
            match k {
                JointKind::Free { rotation_axes } => rotation_axes.iter().map(v).collect(),
                JointKind::Gimbal { axes } => axes.iter().map(v).collect(),
                JointKind::Universal { axes } => axes.iter().map(v).collect(),
                JointKind::Pin { axis } | JointKind::Slider { axis } => vec![v(axis)],
                JointKind::Weld => vec![],
                JointKind::Custom { axes, .. } => axes.iter().map(|a| v(&a.axis)).collect(),
            }
        };
        Summary {
            name: model.spec().name.clone(),
            description: model.spec().description.clone(),
            segments: model
                .segments()
                .iter()
                .map(|s| SegmentRow {
                    name: s.name.clone(),
                    parent: seg_name(s.parent),
                })
                .collect(),
            joints: model
                .joints()
                .iter()
                .map(|j| JointRow {
                    name: j.name.clone(),
                    kind: j.kind.to_string(),
                    axes: axes(&j.kind),
                    parent: seg_name(j.parent),
                    child: seg_name(Some(j.child)),
                    coordinates: model.coordinates()[j.coords.clone()]
                        .iter()
                        .map(|c| c.name.clone())
                        .collect(),
                })
                .collect(),
            coordinates: model
                .coordinates()
                .iter()
                .map(|c| {
                    let (unit, k) = match c.kind {
                        CoordKind::Rotational => ("deg", 180.0 / std::f64::consts::PI),
                        CoordKind::Translational => ("m", 1.0),
                    };
                    CoordRow {
                        name: c.name.clone(),
                        joint: model.joints()[c.joint].name.clone(),
                        unit,
                        range: [round(c.range[0] * k, 6), round(c.range[1] * k, 6)],
                        default: round(c.default * k, 6),
                    }
                })
                .collect(),
            parameters: model
                .parameters()
                .iter()
                .map(|p| {
                    let (unit, k) = (
                        jointfit_app::present::unit_name(p.unit),
                        jointfit_app::present::unit_scale(p.unit),
                    );
                    ParamRow {
                        group: p.group.clone(),
                        segment: seg_name(p.uses[0].segment),
                        name: p.name.clone(),
                        unit,
                        nominal: round(p.nominal * k, 6),
                        lower: round(p.lower * k, 6),
                        upper: round(p.upper * k, 6),
                        description: p.description.clone(),
                    }
                })
                .collect(),
            markers: model
                .markers()
                .iter()
                .map(|m| MarkerRow {
                    name: m.name.clone(),
                    segment: model.segments()[m.segment.0].name.clone(),
                    position_mm: [
                        round(m.local.x * 1e3, 6),
                        round(m.local.y * 1e3, 6),
                        round(m.local.z * 1e3, 6),
                    ],
                    weight: m.weight,
                })
                .collect(),
        }
    }

    fn render(&self) -> String {
        let mut out = format!("model {}\n", self.name);
        if !self.description.is_empty() {
            out += &format!("{}\n", self.description);
        }
        out += &format!("\nsegments ({})\n", self.segments.len());
        let mut t = Table::new(&["segment", "parent"]);
        for s in &self.segments {
            t.row(vec![s.name.clone(), s.parent.clone()]);
        }
        out += &t.render();

        out += &format!("\njoints ({})\n", self.joints.len());
        let mut t = Table::new(&["joint", "type", "parent", "child", "coordinates"]);
        for j in &self.joints {
            t.row(vec![
                j.name.clone(),
                j.kind.clone(),
                j.parent.clone(),
                j.child.clone(),
                j.coordinates.join(", "),
            ]);
        }
        out += &t.render();

        out += &format!("\ncoordinates ({})\n", self.coordinates.len());
        let mut t = Table::new(&["coordinate", "joint", "unit", "min", "max", "default"]);
        for c in &self.coordinates {
            t.row(vec![
                c.name.clone(),
                c.joint.clone(),
                c.unit.to_string(),
                format!("{:.1}", c.range[0]),
                format!("{:.1}", c.range[1]),
                format!("{:.2}", c.default),
            ]);
        }
        out += &t.render();

        out += &format!("\nparameters ({})", self.parameters.len());
        let groups: Vec<String> = {
            let mut g: Vec<String> = Vec::new();
            for p in &self.parameters {
                if !g.contains(&p.group) {
                    g.push(p.group.clone());
                }
            }
            g.iter()
                .map(|name| {
                    let n = self.parameters.iter().filter(|p| &p.group == name).count();
                    format!("{name} {n}")
                })
                .collect()
        };
        out += &format!(": {}\n", groups.join(", "));
        let mut t = Table::new(&[
            "group",
            "segment",
            "parameter",
            "unit",
            "nominal",
            "lower",
            "upper",
        ]);
        for p in &self.parameters {
            t.row(vec![
                p.group.clone(),
                p.segment.clone(),
                p.name.clone(),
                p.unit.to_string(),
                format!("{:.2}", p.nominal),
                format!("{:.2}", p.lower),
                format!("{:.2}", p.upper),
            ]);
        }
        out += &t.render();

        out += &format!("\nmarkers ({})\n", self.markers.len());
        let mut t = Table::new(&["marker", "segment", "x mm", "y mm", "z mm", "weight"]);
        for m in &self.markers {
            t.row(vec![
                m.name.clone(),
                m.segment.clone(),
                format!("{:.1}", m.position_mm[0]),
                format!("{:.1}", m.position_mm[1]),
                format!("{:.1}", m.position_mm[2]),
                format!("{}", m.weight),
            ]);
        }
        out += &t.render();
        out
    }
}
