//! The native part of the `ggs` Python package: numpy arrays in, dicts and numpy arrays out.
//! The public API (argument conversion, `ggs.Result`, warnings, helpers, docstrings) is the
//! Python layer in `python/ggs/`; these functions are its engine.
//!
//! The heavy calls (`register`, `refine`) run on a worker thread with the GIL released; the
//! calling thread wakes every 50 ms to let Python handle signals (Ctrl-C stops a long search
//! through the search's cancel flag and raises `KeyboardInterrupt`) and to report progress.

mod align;
mod arrays;
mod bench;
mod cloud_ops;
mod interrupt;
mod io;
mod metrics;
mod registration;
mod report;

use ggs::pipeline::Preset;
use pyo3::prelude::*;

/// The native part of the `ggs` package.
#[pymodule]
fn _ggs(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(registration::register, m)?)?;
    m.add_function(wrap_pyfunction!(align::align, m)?)?;
    m.add_function(wrap_pyfunction!(align::place, m)?)?;
    m.add_class::<align::Aligner>()?;
    m.add_class::<align::AlignmentResult>()?;
    m.add_function(wrap_pyfunction!(registration::refine_py, m)?)?;
    m.add_function(wrap_pyfunction!(registration::settings, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_point_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(io::write_point_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(io::rotation_set, m)?)?;
    m.add_function(wrap_pyfunction!(cloud_ops::voxel_downsample, m)?)?;
    m.add_function(wrap_pyfunction!(cloud_ops::estimate_normals, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::rre, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::rte, m)?)?;
    m.add_function(wrap_pyfunction!(report::render_view, m)?)?;
    m.add_class::<report::Report>()?;
    m.add_class::<bench::BenchPlan>()?;
    m.add_class::<bench::RunDirectory>()?;
    m.add_function(wrap_pyfunction!(bench::bench_row_json, m)?)?;
    m.add("ROTATION_SETS", ggs::rotations::NAMES.to_vec())?;
    m.add("PRESETS", Preset::NAMES.to_vec())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
