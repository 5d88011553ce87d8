//! Python bindings of ggs: numpy arrays in, numpy arrays out.
//!
//! The heavy calls (`register`, `refine`) run on a worker thread with the GIL released; the
//! calling thread wakes every 50 ms to let Python handle signals, so Ctrl-C stops a long
//! search (through the search's cancel flag) and raises `KeyboardInterrupt`.

use ggs::io::{self, Format};
use ggs::refine::{self, CorrespondenceDistance, Method, RefineConfig, RefineResult, RobustKernel};
use ggs::rotations::RotationSet;
use ggs::search::{self, Hypothesis, SearchConfig, SearchResult};
use ggs::{Cloud, GgsError, Point, Rigid};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

/// Voxels along the target's longest side when no voxel is given (as `ggs register`).
const AUTO_VOXEL_CELLS: usize = 32;

fn to_py_err(e: GgsError) -> PyErr {
    match e {
        GgsError::Io { .. } => PyOSError::new_err(e.to_string()),
        GgsError::Cancelled => pyo3::exceptions::PyKeyboardInterrupt::new_err("cancelled"),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// An (N, 3) float32 or float64 array as points (read in place, whatever its strides;
/// copied once into the cloud). Anything else is a `ValueError` naming the argument.
fn points_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<Point>> {
    fn rows<T: Copy + Into<f64> + numpy::Element>(
        name: &str,
        a: PyReadonlyArray2<'_, T>,
    ) -> PyResult<Vec<Point>> {
        let view = a.as_array();
        let mut out = Vec::with_capacity(view.nrows());
        for (i, r) in view.rows().into_iter().enumerate() {
            let p: Point = [r[0].into(), r[1].into(), r[2].into()];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "{name}: row {i} has a NaN or infinite coordinate {p:?}"
                )));
            }
            out.push(p);
        }
        Ok(out)
    }
    let describe = || -> String {
        let dtype = obj
            .getattr("dtype")
            .map(|d| d.to_string())
            .unwrap_or_else(|_| obj.get_type().to_string());
        let shape = obj
            .getattr("shape")
            .map(|s| s.to_string())
            .unwrap_or_else(|_| "(no shape)".into());
        format!("{name}: expected an (N, 3) float32 or float64 numpy array, got dtype {dtype} with shape {shape}")
    };
    let check_shape = |shape: &[usize]| -> PyResult<()> {
        if shape.len() != 2 || shape[1] != 3 {
            return Err(PyValueError::new_err(describe()));
        }
        if shape[0] == 0 {
            return Err(PyValueError::new_err(format!(
                "{name}: the array has no point"
            )));
        }
        Ok(())
    };
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        check_shape(a.shape())?;
        return rows(name, a);
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f32>>() {
        check_shape(a.shape())?;
        return rows(name, a);
    }
    Err(PyValueError::new_err(describe()))
}

fn matrix_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Rigid> {
    let a = obj
        .extract::<PyReadonlyArray2<'_, f64>>()
        .map_err(|_| PyValueError::new_err(format!("{name}: expected a 4×4 float64 array")))?;
    if a.shape() != [4, 4] {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a 4×4 array, got shape {:?}",
            a.shape()
        )));
    }
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    Rigid::from_row_major(&v, 1e-4).map_err(|m| PyValueError::new_err(format!("{name}: {m}")))
}

fn matrix_array<'py>(py: Python<'py>, t: &Rigid) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = t.to_rows().concat();
    Ok(PyArray1::from_vec(py, flat).reshape([4, 4])?.into_any())
}

fn points_array<'py>(py: Python<'py>, pts: &[Point]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = pts.iter().flat_map(|p| p.iter().copied()).collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([pts.len(), 3])?
        .into_any())
}

/// Run `work` on a scoped worker thread with the GIL released, polling for signals; on
/// Ctrl-C set `cancel`, wait for the worker and return the signal's exception.
fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &Arc<AtomicBool>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let (tx, rx) = mpsc::channel();
        // A Receiver is not Sync; the mutex lets the GIL-free closures borrow it.
        let rx = std::sync::Mutex::new(rx);
        scope.spawn(move || {
            let _ = tx.send(work());
        });
        loop {
            let got = py.detach(|| {
                rx.lock()
                    .expect("only this thread locks it")
                    .recv_timeout(Duration::from_millis(50))
            });
            match got {
                Ok(v) => return Ok(v),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals() {
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

fn parse_refine(
    method: &str,
    max_distance: Option<f64>,
    distance_quantile: f64,
    max_iterations: usize,
    neighbors: usize,
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
    Ok(Some(RefineConfig {
        method: m,
        correspondence: match max_distance {
            Some(d) => CorrespondenceDistance::Fixed(d),
            None => CorrespondenceDistance::Quantile(distance_quantile),
        },
        kernel: RobustKernel::None,
        max_iterations,
        neighbors,
        threads,
        ..RefineConfig::default()
    }))
}

/// The outcome of a registration or a refinement.
#[pyclass(name = "Result", module = "ggs", frozen)]
struct PyResultObj {
    transform: Rigid,
    coarse: Option<SearchResult>,
    refined: Option<RefineResult>,
    total_ms: f64,
}

fn hypothesis_dict<'py>(py: Python<'py>, h: &Hypothesis) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rotation_index", h.rotation_index)?;
    d.set_item("score", h.score)?;
    d.set_item("match_score", h.match_score)?;
    d.set_item("offset", h.offset.to_vec())?;
    d.set_item("transformation", matrix_array(py, &h.transform)?)?;
    Ok(d)
}

#[pymethods]
impl PyResultObj {
    /// The final 4×4 transform (float64), `p_target = T · p_source`.
    #[getter]
    fn transformation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        matrix_array(py, &self.transform)
    }

    /// The coarse search's transform (None after `refine`).
    #[getter]
    fn coarse_transformation<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.coarse
            .as_ref()
            .map(|c| matrix_array(py, &c.transform))
            .transpose()
    }

    /// Share of source points with a target point within the correspondence distance after
    /// refinement (None without refinement).
    #[getter]
    fn fitness(&self) -> Option<f64> {
        self.refined.as_ref().map(|r| r.report.fitness_source)
    }

    /// Share of target points matched (None without refinement).
    #[getter]
    fn fitness_target(&self) -> Option<f64> {
        self.refined.as_ref().map(|r| r.report.fitness_target)
    }

    /// RMS distance of the inlier correspondences, in the clouds' units (None without
    /// refinement).
    #[getter]
    fn inlier_rmse(&self) -> Option<f64> {
        self.refined.as_ref().map(|r| r.report.inlier_rmse)
    }

    /// The coarse search's exact integer score (None after `refine`).
    #[getter]
    fn score(&self) -> Option<i64> {
        self.coarse.as_ref().map(|c| c.score)
    }

    /// Runner-up match score / best match score, over rotations more than the distinct
    /// radius away (near 1: ambiguous). None if there is no runner-up.
    #[getter]
    fn ambiguity(&self) -> Option<f64> {
        self.coarse.as_ref().and_then(|c| c.ambiguity)
    }

    /// Index of the best rotation in the rotation set.
    #[getter]
    fn rotation_index(&self) -> Option<usize> {
        self.coarse.as_ref().map(|c| c.rotation_index)
    }

    /// The voxel size used by the coarse search.
    #[getter]
    fn voxel(&self) -> Option<f64> {
        self.coarse.as_ref().map(|c| c.voxel)
    }

    /// Whether the refinement converged (None without refinement).
    #[getter]
    fn converged(&self) -> Option<bool> {
        self.refined.as_ref().map(|r| r.report.converged)
    }

    /// Times in milliseconds: coarse stages, refinement and the whole call.
    #[getter]
    fn timings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        if let Some(c) = &self.coarse {
            let t = &c.timings;
            d.set_item("coarse_ms", t.total_ms)?;
            d.set_item("target_ms", t.target_ms)?;
            d.set_item("extents_ms", t.extents_ms)?;
            d.set_item("search_ms", t.search_ms)?;
        }
        if let Some(r) = &self.refined {
            d.set_item("refine_ms", r.total_ms)?;
        }
        d.set_item("total_ms", self.total_ms)?;
        Ok(d)
    }

    /// The best distinct hypotheses of the coarse search (`top_k` of them), best first: dicts
    /// with rotation_index, score, match_score, offset and transformation.
    #[getter]
    fn hypotheses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        if let Some(c) = &self.coarse {
            for h in &c.hypotheses {
                list.append(hypothesis_dict(py, h)?)?;
            }
        }
        Ok(list)
    }

    /// The refinement's quality report as a dict (None without refinement).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(r) = &self.refined else {
            return Ok(None);
        };
        let q = &r.report;
        let d = PyDict::new(py);
        d.set_item("method", format!("{:?}", r.method).to_lowercase())?;
        d.set_item("fitness_source", q.fitness_source)?;
        d.set_item("fitness_target", q.fitness_target)?;
        d.set_item("inlier_rmse", q.inlier_rmse)?;
        d.set_item("inliers", q.inliers)?;
        d.set_item("correspondence_distance", q.correspondence_distance)?;
        d.set_item("iterations", q.iterations)?;
        d.set_item("converged", q.converged)?;
        d.set_item("stop_reason", q.stop_reason.clone())?;
        d.set_item(
            "information_eigenvalues",
            q.information_eigenvalues.to_vec(),
        )?;
        d.set_item("degenerate", q.degenerate)?;
        Ok(Some(d))
    }

    fn __repr__(&self) -> String {
        let t = self.transform.to_rows();
        let rows: Vec<String> = t
            .iter()
            .map(|r| format!("[{:.6}, {:.6}, {:.6}, {:.6}]", r[0], r[1], r[2], r[3]))
            .collect();
        let mut s = String::from("ggs.Result(");
        if let Some(c) = &self.coarse {
            s += &format!(
                "rotation_index={}, score={}, ambiguity={}, ",
                c.rotation_index,
                c.score,
                c.ambiguity.map_or("None".into(), |a| format!("{a:.3}"))
            );
        }
        if let Some(r) = &self.refined {
            s += &format!(
                "fitness={:.4}, inlier_rmse={:.6}, ",
                r.report.fitness_source, r.report.inlier_rmse
            );
        }
        s += &format!(
            "total_ms={:.1},\n  transformation=[{}])",
            self.total_ms,
            rows.join(",\n                  ")
        );
        s
    }
}

/// Register `source` onto `target`: coarse grid search, then refinement.
#[pyfunction]
#[pyo3(signature = (source, target, voxel=None, rotations="limited15", refine="gicp", threads=None, top_k=1, search="exhaustive", precision="mixed"))]
#[allow(clippy::too_many_arguments)]
fn register(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    voxel: Option<f64>,
    rotations: &str,
    refine: &str,
    threads: Option<usize>,
    top_k: usize,
    search: &str,
    precision: &str,
) -> PyResult<PyResultObj> {
    let t0 = Instant::now();
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let threads = threads.unwrap_or(0);
    if top_k == 0 {
        return Err(PyValueError::new_err("top_k must be at least 1"));
    }
    let set = RotationSet::named(rotations).map_err(to_py_err)?;
    let voxel = match voxel {
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(v) => {
            return Err(PyValueError::new_err(format!(
                "voxel must be positive, got {v}"
            )))
        }
        None => search::auto_voxel(&target, AUTO_VOXEL_CELLS).ok_or_else(|| {
            PyValueError::new_err("cannot choose a voxel size: the target has zero extent")
        })?,
    };
    let refine_cfg = parse_refine(refine, None, 0.25, 500, 20, threads)?;
    let mode = search::SearchMode::from_name(search, search::CoarseToFine::default())
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let precision: search::Precision = precision
        .parse()
        .map_err(|e: ggs::GgsError| PyValueError::new_err(e.to_string()))?;
    let cancel = Arc::new(AtomicBool::new(false));
    let cfg = SearchConfig {
        voxel,
        threads,
        top_k,
        distinct_radius_deg: None,
        max_memory: None,
        progress: None,
        cancel: Some(cancel.clone()),
        mode,
        precision,
    };
    let outcome = run_interruptible(py, &cancel, || -> ggs::Result<_> {
        let coarse = search::coarse_register(&source, &target, &set, &cfg)?;
        let refined = match &refine_cfg {
            Some(c) => Some(refine::refine(&source, &target, &coarse.transform, c)?),
            None => None,
        };
        Ok((coarse, refined))
    })?;
    let (coarse, refined) = outcome.map_err(to_py_err)?;
    Ok(PyResultObj {
        transform: refined.as_ref().map_or(coarse.transform, |r| r.transform),
        coarse: Some(coarse),
        refined,
        total_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// Refine an initial 4×4 transform `init` (`p_target = init · p_source`) by ICP.
#[pyfunction(name = "refine")]
#[pyo3(signature = (source, target, init, method="gicp", max_distance=None, distance_quantile=0.25, max_iterations=500, neighbors=20, threads=None))]
#[allow(clippy::too_many_arguments)]
fn refine_py(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    init: &Bound<'_, PyAny>,
    method: &str,
    max_distance: Option<f64>,
    distance_quantile: f64,
    max_iterations: usize,
    neighbors: usize,
    threads: Option<usize>,
) -> PyResult<PyResultObj> {
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
        threads.unwrap_or(0),
    )?
    .ok_or_else(|| PyValueError::new_err("refine: method must be gicp, p2plane or p2p"))?;
    let cancel = Arc::new(AtomicBool::new(false));
    let r = run_interruptible(py, &cancel, || {
        refine::refine(&source, &target, &init, &cfg)
    })?
    .map_err(to_py_err)?;
    Ok(PyResultObj {
        transform: r.transform,
        coarse: None,
        refined: Some(r),
        total_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
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

/// Read a point cloud (any format ggs reads) as an (N, 3) float64 array. E57: `scan` picks
/// one scan (default: all, each moved by its pose unless `apply_pose=False`); NPZ: `array`
/// names the array; meshes: `sample_mesh=N` samples N points on the faces.
#[pyfunction]
#[pyo3(signature = (path, format=None, *, scan=None, apply_pose=true, array=None, sample_mesh=None))]
#[allow(clippy::too_many_arguments)]
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

/// Write an (N, 3) array to a point-cloud file, atomically; the format follows the
/// extension (ply, pcd, xyz/txt/pts/csv, npy, bin, las, laz, e57) unless given.
#[pyfunction]
#[pyo3(signature = (path, points, format=None))]
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
    let set = RotationSet::named(name).map_err(to_py_err)?;
    let flat: Vec<f64> = set
        .matrices
        .iter()
        .flat_map(|m| (0..3).flat_map(move |r| (0..3).map(move |c| m[(r, c)])))
        .collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([set.len(), 3, 3])?
        .into_any())
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
    m.add_class::<PyResultObj>()?;
    m.add_function(wrap_pyfunction!(register, m)?)?;
    m.add_function(wrap_pyfunction!(refine_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_point_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(write_point_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(rotation_set, m)?)?;
    m.add_function(wrap_pyfunction!(rre, m)?)?;
    m.add_function(wrap_pyfunction!(rte, m)?)?;
    m.add("ROTATION_SETS", ggs::rotations::NAMES.to_vec())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
