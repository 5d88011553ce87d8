//! Evaluation: Open3D-style fitness and RMSE, RRE and RTE.

use crate::arrays::{matrix_of, points_of, to_py_err};
use ggs::refine;
use ggs::Cloud;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Open3D-style evaluation of `transformation` at `max_distance`, as a dict.
#[pyfunction]
pub(crate) fn evaluate<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    transformation: &Bound<'py, PyAny>,
    max_distance: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let t = matrix_of("transformation", transformation)?;
    let e = py
        .detach(|| refine::evaluate::evaluate(&source, &target, &t, max_distance))
        .map_err(to_py_err)?;
    let d = PyDict::new(py);
    d.set_item("fitness", e.fitness_source)?;
    d.set_item("fitness_target", e.fitness_target)?;
    d.set_item("inlier_rmse", e.inlier_rmse)?;
    d.set_item("inliers", e.inliers)?;
    Ok(d)
}

/// Relative rotation error between two 4×4 transforms, degrees.
#[pyfunction]
pub(crate) fn rre(estimate: &Bound<'_, PyAny>, truth: &Bound<'_, PyAny>) -> PyResult<f64> {
    Ok(ggs::metrics::rre(
        &matrix_of("estimate", estimate)?,
        &matrix_of("truth", truth)?,
    ))
}

/// Relative translation error between two 4×4 transforms, in the clouds' units.
#[pyfunction]
pub(crate) fn rte(estimate: &Bound<'_, PyAny>, truth: &Bound<'_, PyAny>) -> PyResult<f64> {
    Ok(ggs::metrics::rte(
        &matrix_of("estimate", estimate)?,
        &matrix_of("truth", truth)?,
    ))
}
