//! Reading and writing point clouds; the built-in rotation sets.

use crate::arrays::{points_array, points_of, to_py_err, value_err};
use ggs::io::{self, Format};
use ggs::rotations::RotationSet;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;

fn parse_format(format: Option<&str>) -> PyResult<Option<Format>> {
    format
        .map(|f| {
            Format::from_name(f).ok_or_else(|| {
                PyValueError::new_err(format!("unknown format '{f}' ({})", io::FORMAT_NAMES))
            })
        })
        .transpose()
}

/// Read a point cloud as an (N, 3) float64 array.
#[pyfunction]
#[pyo3(signature = (path, format, scan, apply_pose, array, sample_mesh))]
pub(crate) fn read_point_cloud<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: Option<&str>,
    scan: Option<usize>,
    apply_pose: bool,
    array: Option<String>,
    sample_mesh: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    if sample_mesh == Some(0) {
        return Err(PyValueError::new_err(
            "sample_mesh: 0 points asked for (at least 1)",
        ));
    }
    let opts = io::ReadOptions {
        format: parse_format(format)?,
        e57: io::e57::E57Options { scan, apply_pose },
        npz_array: array,
        mesh_samples: sample_mesh,
    };
    let loaded = py
        .detach(|| io::read_points_with(&path, &opts))
        .map_err(to_py_err)?;
    points_array(py, &loaded.points)
}

/// Write an (N, 3) array to a point-cloud file, atomically.
#[pyfunction]
#[pyo3(signature = (path, points, format))]
pub(crate) fn write_point_cloud(
    py: Python<'_>,
    path: PathBuf,
    points: &Bound<'_, PyAny>,
    format: Option<&str>,
) -> PyResult<()> {
    let fmt = parse_format(format)?;
    let pts = points_of("points", points)?;
    py.detach(|| io::write_cloud(&path, &pts, fmt))
        .map_err(to_py_err)
}

/// A built-in rotation set as an (N, 3, 3) float64 array.
#[pyfunction]
pub(crate) fn rotation_set<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let set = RotationSet::named(name).map_err(value_err)?;
    let flat: Vec<f64> = set
        .matrices
        .iter()
        .flat_map(|m| (0..3).flat_map(move |r| (0..3).map(move |c| m[(r, c)])))
        .collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([set.len(), 3, 3])?
        .into_any())
}
