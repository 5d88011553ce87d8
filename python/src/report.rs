//! Pictures and HTML reports: `ggs.Result.report_html` and `ggs.render`.

use crate::arrays::{points_of, to_py_err};
use ggs::html::registration::RegistrationReport;
use ggs::render::{self, Layer};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;

/// What a registration report shows, kept by `ggs.Result` (display samples of both clouds,
/// at most `ggs::render::DISPLAY_POINTS` points each, and the registration).
#[pyclass(frozen, module = "ggs._ggs")]
pub struct Report {
    pub inner: RegistrationReport,
}

#[pymethods]
impl Report {
    /// The self-contained HTML page.
    fn html(&self) -> String {
        self.inner.html()
    }

    /// Write the page to `path` atomically; `command` is shown as the line that reproduces it.
    #[pyo3(signature = (path, source_name=None, target_name=None, command=None))]
    fn write(
        &self,
        path: PathBuf,
        source_name: Option<String>,
        target_name: Option<String>,
        command: Option<String>,
    ) -> PyResult<()> {
        let mut report = self.inner.clone();
        report.source_name = source_name.unwrap_or(report.source_name);
        report.target_name = target_name.unwrap_or(report.target_name);
        report.command = command;
        report.write(&path).map_err(to_py_err)
    }
}

/// An (height, width, 3) uint8 picture of `layers` (pairs of points and an RGB colour) in
/// one of the principal views ("plan", "front", "side") of the first layer's points.
#[pyfunction]
#[pyo3(signature = (layers, view, width, height))]
pub fn render_view<'py>(
    py: Python<'py>,
    layers: Vec<(Bound<'py, PyAny>, (u8, u8, u8))>,
    view: &str,
    width: usize,
    height: usize,
) -> PyResult<Bound<'py, PyAny>> {
    if width == 0 || height == 0 || width > 16384 || height > 16384 {
        return Err(PyValueError::new_err(format!(
            "size must be between 1 and 16384 pixels each way, got {width} × {height}"
        )));
    }
    let mut clouds = Vec::with_capacity(layers.len());
    for (k, (points, color)) in layers.iter().enumerate() {
        let pts = points_of(&format!("layer {k}"), points)?;
        clouds.push((
            render::display_sample(&pts, render::DISPLAY_POINTS),
            [color.0, color.1, color.2],
        ));
    }
    let frame = clouds.first().map(|c| c.0.as_slice()).unwrap_or(&[]);
    let views = render::principal_views(frame);
    let Some(v) = views.iter().find(|v| v.name == view) else {
        return Err(PyValueError::new_err(format!(
            "view must be \"plan\", \"front\" or \"side\", got {view:?}"
        )));
    };
    let layers: Vec<Layer> = clouds
        .iter()
        .map(|(points, color)| Layer {
            points,
            color: *color,
        })
        .collect();
    let image = py.detach(|| render::render(&layers, v, width, height));
    let flat = PyArray1::from_vec(py, image.pixels);
    Ok(flat.reshape([height, width, 3])?.into_any())
}
