//! Which trial column feeds each model marker.

use nalgebra::Vector3;

use super::IkError;
use crate::model::Model;
use crate::trial::Trial;

/// Which trial column feeds each model marker, and the coordinate tasks the trial's frames
/// obey.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerMap {
    /// `columns[j]`: trial column of model marker `j` (`None`: the trial lacks it, and it is
    /// missing in every frame).
    pub columns: Vec<Option<usize>>,
    /// Coordinate tasks over the trial's frames (OpenSim's `IKCoordinateTask`;
    /// [`super::CoordinateTask`]); empty by default.
    pub coordinate_tasks: Vec<super::CoordinateTask>,
}

impl MarkerMap {
    /// Matches model markers to trial labels by name; every model marker must be present.
    pub fn by_name(model: &Model, labels: &[String]) -> Result<MarkerMap, IkError> {
        let (map, absent) = Self::allowing_absent(model, labels);
        if !absent.is_empty() {
            return Err(IkError::MissingMarkers {
                missing: absent,
                available: labels.join(", "),
            });
        }
        Ok(map)
    }

    /// Matches model markers to trial labels by name; model markers the trial lacks are
    /// missing in every frame (a frame is still solved while each segment keeps enough
    /// markers). Returns the map and the names of the absent markers.
    pub fn allowing_absent(model: &Model, labels: &[String]) -> (MarkerMap, Vec<String>) {
        let mut absent = Vec::new();
        let columns = model
            .markers()
            .iter()
            .map(|m| {
                let c = labels.iter().position(|l| l == &m.name);
                if c.is_none() {
                    absent.push(m.name.clone());
                }
                c
            })
            .collect();
        (
            MarkerMap {
                columns,
                coordinate_tasks: Vec::new(),
            },
            absent,
        )
    }

    /// The model-ordered targets of one trial frame (NaN where missing).
    pub(crate) fn targets(&self, trial: &Trial, frame: usize, out: &mut Vec<Vector3<f64>>) {
        let row = trial.frame(frame);
        out.clear();
        out.extend(self.columns.iter().map(|c| match c {
            Some(c) => row[*c],
            None => Vector3::from_element(f64::NAN),
        }));
    }
}
