//! Python bindings of ggs: numpy arrays in, numpy arrays out.
//!
//! The heavy calls (`register`, `refine`) run on a worker thread with the GIL released; the
//! calling thread wakes every 50 ms to let Python handle signals, so Ctrl-C stops a long
//! search (through the search's cancel flag) and raises `KeyboardInterrupt`.

use ggs::io::{self, Format};
use ggs::pipeline::{self, Preset, Registration, RegistrationConfig, VoxelSize};
use ggs::refine::{self, CorrespondenceDistance, Method, RefineConfig, RefineResult, RobustKernel};
use ggs::rotations::RotationSet;
use ggs::search::{self, Hypothesis, SearchResult};
use ggs::{Cloud, GgsError, Point, Rigid};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

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

/// The refinement `method` (or None for `none`): the library's defaults
/// ([`RefineConfig::default`]) changed by the arguments given.
fn parse_refine(
    method: &str,
    max_distance: Option<f64>,
    distance_quantile: Option<f64>,
    max_iterations: Option<usize>,
    neighbors: Option<usize>,
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
    Ok(Some(RefineConfig {
        method: m,
        correspondence: match max_distance {
            Some(d) => CorrespondenceDistance::Fixed(d),
            None => CorrespondenceDistance::Quantile(quantile),
        },
        kernel: RobustKernel::None,
        max_iterations: max_iterations.unwrap_or(base.max_iterations),
        neighbors: neighbors.unwrap_or(base.neighbors),
        threads,
        ..base
    }))
}

/// The outcome of a registration or a refinement.
#[pyclass(name = "Result", module = "ggs", frozen)]
struct PyResultObj {
    transform: Rigid,
    registration: Option<Registration>,
    refined: Option<RefineResult>,
    total_ms: f64,
}

impl PyResultObj {
    fn coarse(&self) -> Option<&SearchResult> {
        self.registration.as_ref().map(|r| &r.search)
    }
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

    /// The chosen hypothesis's grid transform, before polish and ICP (None after `refine`).
    #[getter]
    fn coarse_transformation<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.registration
            .as_ref()
            .map(|r| matrix_array(py, &r.coarse_transform))
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
        self.coarse().map(|c| c.score)
    }

    /// Runner-up match score / best match score, over rotations more than the distinct
    /// radius away (near 1: ambiguous). None if there is no runner-up.
    #[getter]
    fn ambiguity(&self) -> Option<f64> {
        self.coarse().and_then(|c| c.ambiguity)
    }

    /// Index of the best rotation in the rotation set.
    #[getter]
    fn rotation_index(&self) -> Option<usize> {
        self.coarse().map(|c| c.rotation_index)
    }

    /// The voxel size used by the coarse search.
    #[getter]
    fn voxel(&self) -> Option<f64> {
        self.coarse().map(|c| c.voxel)
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
        if let Some(r) = &self.registration {
            let t = &r.search.timings;
            d.set_item("coarse_ms", t.total_ms)?;
            d.set_item("target_ms", t.target_ms)?;
            d.set_item("extents_ms", t.extents_ms)?;
            d.set_item("search_ms", t.search_ms)?;
            d.set_item("verify_ms", r.timings.verify_ms)?;
        }
        if let Some(r) = &self.refined {
            d.set_item("refine_ms", r.total_ms)?;
        }
        d.set_item("total_ms", self.total_ms)?;
        Ok(d)
    }

    /// How sure the result is, in [0, 1]: 1 − (verification score of the best distinct
    /// runner-up) / (the chosen one's); without a verified runner-up, 1 − the coarse ambiguity.
    /// None after `refine`.
    #[getter]
    fn confidence(&self) -> Option<f64> {
        self.registration.as_ref().map(|r| r.confidence)
    }

    /// True when two distinct poses explain the data about equally well (symmetric data,
    /// small overlap): the answer may be the wrong one of them.
    #[getter]
    fn ambiguous(&self) -> Option<bool> {
        self.registration.as_ref().map(|r| r.ambiguous)
    }

    /// Warnings of the registration (ambiguity, low evidence); also issued as Python warnings.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.registration
            .as_ref()
            .map_or_else(Vec::new, |r| r.warnings.clone())
    }

    /// Rank of the chosen coarse hypothesis (0: the coarse winner); None after `refine`.
    #[getter]
    fn chosen_rank(&self) -> Option<usize> {
        self.registration.as_ref().map(|r| r.chosen_rank)
    }

    /// The verified hypotheses in coarse rank order: dicts with rank, rotation_index,
    /// match_score, polished_match_score, score, fitness_source, fitness_target, iterations,
    /// rejected_early, chosen, runner_up, coarse_transformation and transformation.
    #[getter]
    fn verified<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        let Some(v) = self
            .registration
            .as_ref()
            .and_then(|r| r.verification.as_ref())
        else {
            return Ok(list);
        };
        for (k, h) in v.hypotheses.iter().enumerate() {
            let d = PyDict::new(py);
            d.set_item("rank", h.rank)?;
            d.set_item("rotation_index", h.rotation_index)?;
            d.set_item("match_score", h.match_score)?;
            d.set_item("polished_match_score", h.polished_match_score)?;
            d.set_item("score", h.evidence.score)?;
            d.set_item("fitness_source", h.evidence.fitness_source)?;
            d.set_item("fitness_target", h.evidence.fitness_target)?;
            d.set_item("iterations", h.iterations)?;
            d.set_item("rejected_early", h.rejected_early)?;
            d.set_item("chosen", k == v.chosen)?;
            d.set_item("runner_up", Some(k) == v.runner_up)?;
            d.set_item(
                "coarse_transformation",
                matrix_array(py, &h.coarse_transform)?,
            )?;
            d.set_item("transformation", matrix_array(py, &h.transform)?)?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// The best distinct hypotheses of the coarse search, best first: dicts
    /// with rotation_index, score, match_score, offset and transformation.
    #[getter]
    fn hypotheses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        if let Some(c) = self.coarse() {
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
        if let Some(c) = self.coarse() {
            s += &format!(
                "rotation_index={}, score={}, ambiguity={}, ",
                c.rotation_index,
                c.score,
                c.ambiguity.map_or("None".into(), |a| format!("{a:.3}"))
            );
        }
        if let Some(r) = &self.registration {
            s += &format!(
                "confidence={:.3}, ambiguous={}, ",
                r.confidence,
                if r.ambiguous { "True" } else { "False" }
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

/// The pipeline configuration of `register`'s arguments.
#[allow(clippy::too_many_arguments)]
fn pipeline_config(
    voxel: Option<f64>,
    preset: &str,
    rotations: Option<&str>,
    refine: Option<&str>,
    threads: usize,
    top_k: Option<usize>,
    search: Option<&str>,
    precision: &str,
    max_hypotheses: Option<usize>,
    verify: bool,
    polish: bool,
) -> PyResult<RegistrationConfig> {
    let value_err = |e: GgsError| PyValueError::new_err(e.to_string());
    let preset: Preset = preset.parse().map_err(value_err)?;
    let mut cfg = RegistrationConfig::preset(preset);
    cfg.threads = threads;
    if let Some(v) = voxel {
        cfg.voxel = VoxelSize::Fixed(v);
    }
    if let Some(name) = rotations {
        cfg.rotations = RotationSet::named(name).map_err(to_py_err)?;
    }
    if let Some(name) = search {
        cfg.search.mode = search::SearchMode::from_name(name, search::CoarseToFine::default())
            .map_err(value_err)?;
    }
    cfg.search.precision = precision.parse().map_err(value_err)?;
    if let Some(k) = top_k {
        if k == 0 {
            return Err(PyValueError::new_err("top_k must be at least 1"));
        }
        cfg.search.top_k = k;
    }
    if !verify {
        cfg.verify = None;
    }
    match (&mut cfg.verify, max_hypotheses) {
        (_, Some(0)) => return Err(PyValueError::new_err("max_hypotheses must be at least 1")),
        (Some(v), Some(n)) => v.max_hypotheses = n,
        (None, Some(_)) => {
            return Err(PyValueError::new_err(
                "max_hypotheses needs verification (not with verify=False or preset='paper')",
            ))
        }
        _ => {}
    }
    if polish {
        cfg.polish = Some(pipeline::PolishConfig::default());
    }
    if let Some(method) = refine {
        cfg.refine = parse_refine(method, None, None, None, None, threads)?;
    }
    Ok(cfg)
}

/// Register `source` onto `target` with no initial guess: coarse grid search over a rotation
/// set, polish and verification of the distinct hypotheses, refinement of the best.
#[pyfunction]
#[pyo3(signature = (source, target, voxel=None, *, preset="default", rotations=None, refine=None, threads=None, top_k=None, search=None, precision="mixed", max_hypotheses=None, verify=true, polish=false))]
#[allow(clippy::too_many_arguments)]
fn register(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    voxel: Option<f64>,
    preset: &str,
    rotations: Option<&str>,
    refine: Option<&str>,
    threads: Option<usize>,
    top_k: Option<usize>,
    search: Option<&str>,
    precision: &str,
    max_hypotheses: Option<usize>,
    verify: bool,
    polish: bool,
) -> PyResult<PyResultObj> {
    let t0 = Instant::now();
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let mut cfg = pipeline_config(
        voxel,
        preset,
        rotations,
        refine,
        threads.unwrap_or(0),
        top_k,
        search,
        precision,
        max_hypotheses,
        verify,
        polish,
    )?;
    let cancel = Arc::new(AtomicBool::new(false));
    cfg.search.cancel = Some(cancel.clone());
    let reg = run_interruptible(py, &cancel, || pipeline::register(&source, &target, &cfg))?
        .map_err(to_py_err)?;
    for w in &reg.warnings {
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &std::ffi::CString::new(format!("ggs: {w}")).expect("no NUL in warnings"),
            1,
        )?;
    }
    Ok(PyResultObj {
        transform: reg.transform,
        refined: reg.refine.clone(),
        registration: Some(reg),
        total_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// Refine an initial 4×4 transform `init` (`p_target = init · p_source`) by ICP.
#[pyfunction(name = "refine")]
#[pyo3(signature = (source, target, init, method="gicp", max_distance=None, distance_quantile=None, max_iterations=None, neighbors=None, threads=None))]
#[allow(clippy::too_many_arguments)]
fn refine_py(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    init: &Bound<'_, PyAny>,
    method: &str,
    max_distance: Option<f64>,
    distance_quantile: Option<f64>,
    max_iterations: Option<usize>,
    neighbors: Option<usize>,
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
        registration: None,
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
    m.add("PRESETS", Preset::NAMES.to_vec())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
