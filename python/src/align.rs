//! `align`: many scans into one frame ([`ggs::align`]). Run here (`align`, the GIL released)
//! or in steps by the Python layer (`Aligner`), whose registrations (`place`) may run
//! anywhere, such as Ray tasks: the result is the same.

use crate::arrays::{points_array, points_of, to_py_err};
use crate::interrupt::{run_interruptible, Progress};
use crate::registration::Options;
use ggs::align::{AlignScan, Aligner as Core, Alignment, PlacementJob, PlacementOutcome};
use ggs::{Cloud, Rigid, Runtime};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// A registration's outcome as it travels between Python and the engine: the 16 numbers
/// of `T` (row-major), confidence, ambiguous, warnings, settled, milliseconds.
type Outcome = (Vec<f64>, f64, bool, Vec<String>, bool, f64);

fn to_tuple(o: PlacementOutcome) -> Outcome {
    let rows = o.transform.to_rows().iter().flatten().copied().collect();
    (rows, o.confidence, o.ambiguous, o.warnings, o.settled, o.ms)
}

fn from_tuple(o: Outcome) -> PyResult<PlacementOutcome> {
    let transform = Rigid::from_row_major(&o.0, 1e-6)
        .map_err(|m| PyValueError::new_err(format!("outcome: {m}")))?;
    Ok(PlacementOutcome {
        transform,
        confidence: o.1,
        ambiguous: o.2,
        warnings: o.3,
        settled: o.4,
        ms: o.5,
    })
}

fn scans_of(scans: &[Bound<'_, PyAny>], names: Vec<String>) -> PyResult<Vec<AlignScan>> {
    if names.len() != scans.len() {
        return Err(PyValueError::new_err(format!(
            "names: {} names for {} scans",
            names.len(),
            scans.len()
        )));
    }
    scans
        .iter()
        .zip(names)
        .map(|(s, name)| {
            let cloud = Cloud::new(points_of(&name, s)?);
            Ok(AlignScan { name, cloud })
        })
        .collect()
}

/// A runtime of `threads` whose run stops when the returned flag is set (Ctrl-C).
fn cancellable(threads: usize) -> (Runtime, Arc<AtomicBool>) {
    let cancel = Arc::new(AtomicBool::new(false));
    let runtime = Runtime {
        threads,
        progress: None,
        cancel: Some(cancel.clone()),
    };
    (runtime, cancel)
}

/// An alignment and its scans: the JSON document, and the folder of files.
#[pyclass(frozen, module = "ggs._ggs")]
pub struct AlignmentResult {
    scans: Arc<[AlignScan]>,
    alignment: Alignment,
}

#[pymethods]
impl AlignmentResult {
    /// The alignment as JSON (`ggs-alignment/1`, as `poses.json`).
    fn document(&self) -> String {
        serde_json::to_string(&self.alignment).expect("an alignment serializes")
    }

    /// Write poses.json, poses.txt, scans/, model.ply and report.html into `dir`.
    #[pyo3(signature = (dir, command=None))]
    fn write(&self, dir: PathBuf, command: Option<String>) -> PyResult<()> {
        let (scans, a) = (&self.scans, &self.alignment);
        ggs::html::alignment::write_folder_and_report(&dir, scans, a, command).map_err(to_py_err)
    }

    /// The report page.
    fn report_html(&self) -> String {
        ggs::html::alignment::AlignmentReport::new(&self.scans, &self.alignment).html()
    }
}

/// Align `scans` (arrays) named `names` here, with the GIL released; `progress(placed,
/// total)` is called as scans are placed.
#[pyfunction]
#[pyo3(signature = (scans, names, options, anchor=None, progress=None))]
pub(crate) fn align(
    py: Python<'_>,
    scans: Vec<Bound<'_, PyAny>>,
    names: Vec<String>,
    options: Options,
    anchor: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<AlignmentResult> {
    let scans: Arc<[AlignScan]> = scans_of(&scans, names)?.into();
    let (_, settings) = options.settings()?;
    let (runtime, cancel) = cancellable(options.threads);
    let progress = progress.map(|callback| Progress {
        callback,
        done: Arc::new(AtomicUsize::new(0)),
        total: scans.len(),
    });
    let placed = progress.as_ref().map(|p| p.done.clone());
    let run = || -> ggs::Result<Alignment> {
        let mut aligner = Core::new(scans.clone(), &settings, anchor, &runtime)?;
        let count = |n: usize| {
            if let Some(p) = &placed {
                p.store(n, Ordering::Relaxed);
            }
        };
        let alignment = aligner.run(&runtime, |_, n| count(n))?;
        count(alignment.scans.iter().filter(|s| s.pose.is_some()).count());
        Ok(alignment)
    };
    let alignment = run_interruptible(py, &cancel, progress.as_ref(), run)?.map_err(to_py_err)?;
    Ok(AlignmentResult { scans, alignment })
}

/// The registration of one placement (what a Ray task runs): `scan` onto `model`, quick
/// or whole; returns the outcome `Aligner.record` takes.
#[pyfunction]
pub(crate) fn place(
    py: Python<'_>,
    scan: &Bound<'_, PyAny>,
    model: &Bound<'_, PyAny>,
    options: Options,
    quick: bool,
) -> PyResult<Outcome> {
    let scan = Cloud::new(points_of("scan", scan)?);
    let job = PlacementJob {
        scan: 0,
        quick,
        model: Vec::new(),
        model_points: points_of("model", model)?,
    };
    let (_, settings) = options.settings()?;
    let (runtime, cancel) = cancellable(options.threads);
    let run = || {
        let plan = ggs::align::placement_plan(&settings, &runtime)?;
        ggs::align::register_job(&scan, &job, &plan, &settings)
    };
    let outcome = run_interruptible(py, &cancel, None, run)?.map_err(to_py_err)?;
    Ok(to_tuple(outcome))
}

/// An alignment in steps ([`ggs::align::Aligner`]) for an executor in Python.
#[pyclass(module = "ggs._ggs")]
pub struct Aligner {
    core: Core,
    threads: usize,
    pending: Vec<PlacementJob>,
}

#[pymethods]
impl Aligner {
    #[new]
    #[pyo3(signature = (scans, names, options, anchor=None))]
    fn new(
        scans: Vec<Bound<'_, PyAny>>,
        names: Vec<String>,
        options: Options,
        anchor: Option<usize>,
    ) -> PyResult<Self> {
        let scans = scans_of(&scans, names)?;
        let (_, settings) = options.settings()?;
        let runtime = Runtime {
            threads: options.threads,
            ..Runtime::default()
        };
        let core = Core::new(scans, &settings, anchor, &runtime).map_err(to_py_err)?;
        Ok(Aligner {
            core,
            threads: options.threads,
            pending: Vec::new(),
        })
    }

    /// The next batch: `(scan index, model points, quick)` per registration; empty when
    /// the placement is done (when none is left, the placements are checked against each
    /// other first, and a contradicted one is withdrawn and tried again).
    fn next_jobs<'py>(
        &mut self,
        py: Python<'py>,
    ) -> PyResult<Vec<(usize, Bound<'py, PyAny>, bool)>> {
        self.pending = py.detach(|| self.core.next_jobs()).map_err(to_py_err)?;
        self.pending
            .iter()
            .map(|j| Ok((j.scan, points_array(py, &j.model_points)?, j.quick)))
            .collect()
    }

    /// The outcomes of the last batch (each as `place` returns it), in job order.
    fn record(&mut self, outcomes: Vec<Outcome>) -> PyResult<()> {
        let outcomes = outcomes
            .into_iter()
            .map(from_tuple)
            .collect::<PyResult<Vec<_>>>()?;
        let jobs = std::mem::take(&mut self.pending);
        self.core.record(&jobs, outcomes).map_err(to_py_err)
    }

    /// The pose graph, the joint refinement and the result.
    fn finish(&self, py: Python<'_>) -> PyResult<AlignmentResult> {
        let runtime = Runtime {
            threads: self.threads,
            ..Runtime::default()
        };
        let alignment = py
            .detach(|| self.core.finish(&runtime))
            .map_err(to_py_err)?;
        Ok(AlignmentResult {
            scans: self.core.shared_scans(),
            alignment,
        })
    }
}
