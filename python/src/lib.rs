//! The native part of the `ggs` Python package: numpy arrays in, dicts and numpy arrays out.
//! The public API (argument conversion, `ggs.Result`, warnings, helpers, docstrings) is the
//! Python layer in `python/ggs/`; these functions are its engine.
//!
//! The heavy calls (`register`, `refine`) run on a worker thread with the GIL released; the
//! calling thread wakes every 50 ms to let Python handle signals (Ctrl-C stops a long search
//! through the search's cancel flag and raises `KeyboardInterrupt`) and to report progress.

mod arrays;
mod bench;
mod report;
mod result;

use arrays::{matrix_of, points_array, points_of, rotations_of, to_py_err, value_err};
use ggs::io::{self, Format};
use ggs::pipeline::{self, Preset, RegistrationConfig, VoxelSize};
use ggs::refine::{self, CorrespondenceDistance, Method, RefineConfig, RobustKernel};
use ggs::rotations::RotationSet;
use ggs::{search, Cloud};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use result::result_dict;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

/// A Python progress callback `progress(done, total)` and the count the search updates.
struct Progress {
    callback: Py<PyAny>,
    done: Arc<AtomicUsize>,
    total: usize,
}

impl Progress {
    /// Call the callback if the count moved since `last`.
    fn report(&self, py: Python<'_>, last: &mut usize) -> PyResult<()> {
        let now = self.done.load(Ordering::Relaxed);
        if now != *last {
            *last = now;
            self.callback.call1(py, (now, self.total))?;
        }
        Ok(())
    }
}

/// Run `work` on a scoped worker thread with the GIL released, polling for signals and
/// reporting progress; on Ctrl-C (or an exception in the callback) set `cancel`, wait for the
/// worker and raise.
fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &Arc<AtomicBool>,
    progress: Option<&Progress>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let (tx, rx) = mpsc::channel();
        // A Receiver is not Sync; the mutex lets the GIL-free closures borrow it.
        let rx = std::sync::Mutex::new(rx);
        scope.spawn(move || {
            let _ = tx.send(work());
        });
        let mut last = 0;
        loop {
            let got = py.detach(|| {
                rx.lock()
                    .expect("only this thread locks it")
                    .recv_timeout(Duration::from_millis(50))
            });
            match got {
                Ok(v) => {
                    if let Some(p) = progress {
                        p.report(py, &mut last)?;
                    }
                    return Ok(v);
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let polled = py
                        .check_signals()
                        .and_then(|_| progress.map_or(Ok(()), |p| p.report(py, &mut last)));
                    if let Err(e) = polled {
                        cancel.store(true, Ordering::Relaxed);
                        // The worker stops at its next rotation; drain it before raising.
                        let _ = py.detach(|| rx.lock().expect("only this thread").recv());
                        return Err(e);
                    }
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err("the registration thread panicked"))
                }
            }
        }
    })
}

/// The refinement `method` (or None for `none`): the library's defaults
/// ([`RefineConfig::default`]) changed by the arguments given.
#[allow(clippy::too_many_arguments)]
fn parse_refine(
    method: &str,
    max_distance: Option<f64>,
    distance_quantile: Option<f64>,
    max_iterations: Option<usize>,
    neighbors: Option<usize>,
    kernel: &str,
    threads: usize,
) -> PyResult<Option<RefineConfig>> {
    if method == "none" {
        return Ok(None);
    }
    let m = Method::from_name(method).ok_or_else(|| {
        PyValueError::new_err(format!(
            "refine: unknown method '{method}' (gicp, p2plane, p2p, none)"
        ))
    })?;
    let base = RefineConfig::default();
    let quantile = distance_quantile.unwrap_or(refine::DEFAULT_DISTANCE_QUANTILE);
    let kernel: RobustKernel = kernel.parse().map_err(value_err)?;
    Ok(Some(RefineConfig {
        method: m,
        correspondence: match max_distance {
            Some(d) => CorrespondenceDistance::Fixed(d),
            None => CorrespondenceDistance::Quantile(quantile),
        },
        kernel,
        max_iterations: max_iterations.unwrap_or(base.max_iterations),
        neighbors: neighbors.unwrap_or(base.neighbors),
        threads,
        ..base
    }))
}

/// The pipeline options of `register`, as the Python layer passes them.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct Options {
    preset: String,
    rotations: Option<String>,
    refine: Option<String>,
    kernel: String,
    threads: usize,
    top_k: Option<usize>,
    search: Option<String>,
    precision: String,
    max_hypotheses: Option<usize>,
    margin: Option<f64>,
    verify: bool,
    polish: bool,
    max_memory: Option<u64>,
    distinct_radius: Option<f64>,
    dedup: Option<f64>,
    coarse_factor: Option<f64>,
    coarse_keep: Option<f64>,
    coarse_keep_min: Option<usize>,
    max_distance: Option<f64>,
    distance_quantile: Option<f64>,
    max_iterations: Option<usize>,
    neighbors: Option<usize>,
    refine_cell: Option<f64>,
}

impl Options {
    /// The coarse-to-fine parameters: the preset's (the library's defaults for a preset
    /// without them) changed by those given.
    fn coarse_to_fine(&self, preset: search::SearchMode) -> search::CoarseToFine {
        let d = match preset {
            search::SearchMode::CoarseToFine(c) => c,
            search::SearchMode::Exhaustive => search::CoarseToFine::default(),
        };
        search::CoarseToFine {
            factor: self.coarse_factor.unwrap_or(d.factor),
            keep_fraction: self.coarse_keep.unwrap_or(d.keep_fraction),
            keep_min: self.coarse_keep_min.unwrap_or(d.keep_min),
            neighbour_deg: d.neighbour_deg,
        }
    }
}

fn pipeline_config(
    voxel: Option<f64>,
    o: &Options,
    matrices: Option<&Bound<'_, PyAny>>,
) -> PyResult<RegistrationConfig> {
    let preset: Preset = o.preset.parse().map_err(value_err)?;
    let mut cfg = RegistrationConfig::preset(preset);
    cfg.threads = o.threads;
    if let Some(v) = voxel {
        cfg.voxel = VoxelSize::Fixed(v);
    }
    if let Some(name) = &o.rotations {
        cfg.rotations = RotationSet::named(name).map_err(value_err)?;
    }
    if let Some(m) = matrices {
        cfg.rotations = rotations_of("rotations", m)?;
    }
    if let Some(tol) = o.dedup {
        cfg.rotations = cfg
            .rotations
            .without_duplicates_within(tol)
            .map_err(value_err)?;
    }
    cfg.search.mode = match (&o.search, cfg.search.mode) {
        (Some(name), _) => search::SearchMode::from_name(name, o.coarse_to_fine(cfg.search.mode))
            .map_err(value_err)?,
        (None, m @ search::SearchMode::CoarseToFine(_)) => {
            search::SearchMode::CoarseToFine(o.coarse_to_fine(m))
        }
        (None, m) => m,
    };
    cfg.search.precision = o.precision.parse().map_err(value_err)?;
    if let Some(k) = o.top_k {
        cfg.search.top_k = k;
    }
    cfg.search.max_memory = o.max_memory;
    cfg.search.distinct_radius_deg = o.distinct_radius;
    if !o.verify {
        cfg.verify = None;
    }
    match (&mut cfg.verify, o.max_hypotheses, o.margin) {
        (Some(v), n, m) => {
            if let Some(n) = n {
                v.max_hypotheses = n;
            }
            if let Some(m) = m {
                v.margin = m;
            }
        }
        (None, None, None) => {}
        (None, _, _) => return Err(PyValueError::new_err(
            "max_hypotheses and margin need verification (not with verify=False or preset='paper')",
        )),
    }
    if o.polish {
        cfg.polish = Some(pipeline::PolishConfig::default());
    }
    if let Some(c) = o.refine_cell {
        cfg.final_stage = cfg
            .final_stage
            .with_cell_voxels(c)
            .map_err(|e| PyValueError::new_err(format!("refine_cell: {e}")))?;
    }
    if o.max_iterations.is_some() {
        // The user's cap, not the stage's.
        cfg.final_stage.max_iterations = usize::MAX;
    }
    let method = match &o.refine {
        Some(m) => Some(m.as_str()),
        None => cfg.refine.map(|r| r.method.name()),
    };
    cfg.refine = match method {
        Some(m) => parse_refine(
            m,
            o.max_distance,
            o.distance_quantile,
            o.max_iterations,
            o.neighbors,
            &o.kernel,
            o.threads,
        )?,
        None => None,
    };
    Ok(cfg)
}

/// Register `source` onto `target` (the pipeline); returns the result as a dict.
#[pyfunction]
#[pyo3(signature = (source, target, voxel, options, rotation_matrices=None, progress=None))]
fn register<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    voxel: Option<f64>,
    options: Options,
    rotation_matrices: Option<&Bound<'py, PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let t0 = Instant::now();
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let mut cfg = pipeline_config(voxel, &options, rotation_matrices)?;
    let cancel = Arc::new(AtomicBool::new(false));
    cfg.search.cancel = Some(cancel.clone());
    let progress = progress.map(|callback| Progress {
        callback,
        done: Arc::new(AtomicUsize::new(0)),
        total: cfg.rotations.len(),
    });
    if let Some(p) = &progress {
        let done = p.done.clone();
        cfg.search.progress = Some(Arc::new(move |n| done.store(n, Ordering::Relaxed)));
    }
    let reg = run_interruptible(py, &cancel, progress.as_ref(), || {
        pipeline::register(&source, &target, &cfg)
    })?
    .map_err(to_py_err)?;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let d = result_dict(
        py,
        &reg.transform,
        Some(&reg),
        reg.refine.as_ref(),
        total_ms,
    )?;
    let mut inner = ggs::html::registration::RegistrationReport::new(&source, &target, reg);
    inner.total_ms = Some(total_ms);
    d.set_item("_report", report::Report { inner })?;
    Ok(d)
}

/// Refine `init` by ICP; returns the result as a dict.
#[pyfunction(name = "refine")]
#[pyo3(signature = (source, target, init, method, max_distance, distance_quantile, max_iterations, neighbors, kernel, threads))]
#[allow(clippy::too_many_arguments)]
fn refine_py<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    init: &Bound<'py, PyAny>,
    method: &str,
    max_distance: Option<f64>,
    distance_quantile: Option<f64>,
    max_iterations: Option<usize>,
    neighbors: Option<usize>,
    kernel: &str,
    threads: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let t0 = Instant::now();
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let init = matrix_of("init", init)?;
    let cfg = parse_refine(
        method,
        max_distance,
        distance_quantile,
        max_iterations,
        neighbors,
        kernel,
        threads,
    )?
    .ok_or_else(|| PyValueError::new_err("refine: method must be gicp, p2plane or p2p"))?;
    let cancel = Arc::new(AtomicBool::new(false));
    let r = run_interruptible(py, &cancel, None, || {
        refine::refine(&source, &target, &init, &cfg)
    })?
    .map_err(to_py_err)?;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    result_dict(py, &r.transform, None, Some(&r), total_ms)
}

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
fn read_point_cloud<'py>(
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
        .detach(|| io::read_cloud_with(&path, &opts))
        .map_err(to_py_err)?;
    points_array(py, &loaded.cloud.points)
}

/// Write an (N, 3) array to a point-cloud file, atomically.
#[pyfunction]
#[pyo3(signature = (path, points, format))]
fn write_point_cloud(
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
fn rotation_set<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
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

/// One point per occupied cell of edge `voxel`: the mean of its points.
#[pyfunction]
fn voxel_downsample<'py>(
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
fn estimate_normals<'py>(
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
        let index = refine::neighbors::PointIndex::new(&pts);
        refine::covariance::local_shapes(&pts, &index, neighbors, 1e-3)
            .iter()
            .map(|s| [s.normal.x, s.normal.y, s.normal.z])
            .collect::<Vec<_>>()
    });
    points_array(py, &normals)
}

/// Open3D-style evaluation of `transformation` at `max_distance`, as a dict.
#[pyfunction]
fn evaluate<'py>(
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
fn rre(estimate: &Bound<'_, PyAny>, truth: &Bound<'_, PyAny>) -> PyResult<f64> {
    Ok(ggs::metrics::rre(
        &matrix_of("estimate", estimate)?,
        &matrix_of("truth", truth)?,
    ))
}

/// Relative translation error between two 4×4 transforms, in the clouds' units.
#[pyfunction]
fn rte(estimate: &Bound<'_, PyAny>, truth: &Bound<'_, PyAny>) -> PyResult<f64> {
    Ok(ggs::metrics::rte(
        &matrix_of("estimate", estimate)?,
        &matrix_of("truth", truth)?,
    ))
}

/// The native part of the `ggs` package.
#[pymodule]
fn _ggs(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(register, m)?)?;
    m.add_function(wrap_pyfunction!(refine_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_point_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(write_point_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(rotation_set, m)?)?;
    m.add_function(wrap_pyfunction!(voxel_downsample, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_normals, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(rre, m)?)?;
    m.add_function(wrap_pyfunction!(rte, m)?)?;
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
