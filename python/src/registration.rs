//! `register` and `refine`: the pipeline and ICP, configured from the Python options.

use crate::arrays::{matrix_of, points_of, rotations_of, to_py_err, value_err};
use crate::interrupt::{run_interruptible, Progress};
use crate::report;
use crate::result::result_dict;
use ggs::coarse::SearchMode;
use ggs::pipeline::{self, Preset, RegistrationConfig, VoxelSize};
use ggs::refine::{self, CorrespondenceDistance, Method, RefineConfig, RobustKernel};
use ggs::rotations::RotationSet;
use ggs::Cloud;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

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
pub(crate) struct Options {
    pub(crate) preset: String,
    pub(crate) rotations: Option<String>,
    refine: Option<String>,
    kernel: String,
    threads: usize,
    top_k: Option<usize>,
    search: Option<String>,
    precision: String,
    max_hypotheses: Option<usize>,
    margin: Option<f64>,
    verify_score: Option<String>,
    verify: bool,
    first_look: bool,
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
    fn coarse_to_fine(&self, preset: SearchMode) -> ggs::coarse::CoarseToFine {
        let d = match preset {
            SearchMode::CoarseToFine(c) => c,
            SearchMode::Exhaustive => ggs::coarse::CoarseToFine::default(),
        };
        ggs::coarse::CoarseToFine {
            factor: self.coarse_factor.unwrap_or(d.factor),
            keep_fraction: self.coarse_keep.unwrap_or(d.keep_fraction),
            keep_min: self.coarse_keep_min.unwrap_or(d.keep_min),
            neighbour_deg: d.neighbour_deg,
            hypotheses: d.hypotheses,
        }
    }
}

pub(crate) fn pipeline_config(
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
    apply_rotations(&mut cfg, o, matrices)?;
    apply_search(&mut cfg, o)?;
    apply_verification(&mut cfg, o)?;
    apply_refinement(&mut cfg, o)?;
    Ok(cfg)
}

/// The rotation set: a named one, the caller's matrices, less their near-duplicates.
fn apply_rotations(
    cfg: &mut RegistrationConfig,
    o: &Options,
    matrices: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
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
    Ok(())
}

/// The coarse search: mode, precision, hypotheses, memory, distinct radius.
fn apply_search(cfg: &mut RegistrationConfig, o: &Options) -> PyResult<()> {
    cfg.search.mode = match (&o.search, cfg.search.mode) {
        (Some(name), _) => {
            SearchMode::from_name(name, o.coarse_to_fine(cfg.search.mode)).map_err(value_err)?
        }
        (None, m @ SearchMode::CoarseToFine(_)) => SearchMode::CoarseToFine(o.coarse_to_fine(m)),
        (None, m) => m,
    };
    cfg.search.precision = o.precision.parse().map_err(value_err)?;
    if let Some(k) = o.top_k {
        cfg.search.top_k = k;
        // The K best of the whole search: a first look has only its own few.
        cfg.first_look = None;
    }
    cfg.search.max_memory = o.max_memory;
    cfg.search.distinct_radius_deg = o.distinct_radius;
    Ok(())
}

/// Verification on or off, its hypotheses and margin; the finer rotation grid.
fn apply_verification(cfg: &mut RegistrationConfig, o: &Options) -> PyResult<()> {
    if !o.verify {
        cfg.verify = None;
    }
    if !o.first_look {
        cfg.first_look = None;
    }
    let asked = o.max_hypotheses.is_some() || o.margin.is_some() || o.verify_score.is_some();
    match &mut cfg.verify {
        Some(v) => {
            if let Some(n) = o.max_hypotheses {
                v.max_hypotheses = n;
            }
            if let Some(m) = o.margin {
                v.margin = m;
            }
            if let Some(sc) = &o.verify_score {
                v.score = sc.parse().map_err(value_err)?;
            }
        }
        None if asked => return Err(PyValueError::new_err(
            "max_hypotheses, margin and verify_score need verification (not with verify=False or preset='paper')",
        )),
        None => {}
    }
    if o.polish {
        cfg.polish = Some(pipeline::PolishConfig::default());
    }
    Ok(())
}

/// The final refinement: its thinning cell, iteration cap and method.
fn apply_refinement(cfg: &mut RegistrationConfig, o: &Options) -> PyResult<()> {
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
    Ok(())
}

/// Register `source` onto `target` (the pipeline); returns the result as a dict.
#[pyfunction]
#[pyo3(signature = (source, target, voxel, options, rotation_matrices=None, progress=None))]
pub(crate) fn register<'py>(
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
pub(crate) fn refine_py<'py>(
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
