//! Operations on one cloud: voxel downsampling, normals.

use crate::arrays::{points_array, points_of};
use ggs::refine;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// One point per occupied cell of edge `voxel`: the mean of its points.
#[pyfunction]
pub(crate) fn voxel_downsample<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    voxel: f64,
) -> PyResult<Bound<'py, PyAny>> {
    if !(voxel.is_finite() && voxel > 0.0) {
        return Err(PyValueError::new_err(format!(
            "voxel: must be a positive number, got {voxel}"
        )));
    }
    let pts = points_of("points", points)?;
    let out = py.detach(|| ggs::thin::cell_centroids(&pts, voxel));
    points_array(py, &out)
}

/// Unit normals from the `neighbors` nearest points of each point (sign arbitrary).
#[pyfunction]
pub(crate) fn estimate_normals<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    neighbors: usize,
) -> PyResult<Bound<'py, PyAny>> {
    if neighbors < 3 {
        return Err(PyValueError::new_err(
            "neighbors: need at least 3 for a normal",
        ));
    }
    let pts = points_of("points", points)?;
    let normals = py.detach(|| {
        refine::estimate_normals(&pts, neighbors)
            .iter()
            .map(|n| [n.x, n.y, n.z])
            .collect::<Vec<_>>()
    });
    points_array(py, &normals)
}
