//! `register`, `refine` and `settings`: the pipeline and ICP, configured by the library's
//! settings ([`ggs::Settings`]) laid over a preset from a settings file and the keyword
//! arguments; no rule of its own.

use crate::arrays::{matrix_of, points_of, rotations_of, to_py_err};
use crate::interrupt::{run_interruptible, Progress};
use crate::report;
use ggs::pipeline::{Preset, RefinementDocument, RegistrationDocument};
use ggs::refine;
use ggs::settings::{Changes, SettingsFile};
use ggs::{Cloud, Settings};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The settings as the Python layer passes them: a preset name (None: the settings file's,
/// else default), a settings file, layers of changes (origin, JSON object) and the threads.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub(crate) struct Options {
    preset: Option<String>,
    file: Option<PathBuf>,
    layers: Vec<[String; 2]>,
    pub(crate) threads: usize,
}

impl Options {
    /// The preset and the settings: `preset`, changed by the file, then by each layer.
    pub(crate) fn settings(&self) -> PyResult<(Preset, Settings)> {
        layered(
            self.preset.as_deref(),
            self.file.as_ref(),
            &self.layers,
            Preset::Default,
        )
    }
}

/// `named` (else the file's preset, else `fallback`) changed by the settings file and the
/// layers, in order.
fn layered(
    named: Option<&str>,
    file: Option<&PathBuf>,
    layers: &[[String; 2]],
    fallback: Preset,
) -> PyResult<(Preset, Settings)> {
    let file = file
        .map(|p| SettingsFile::read(p))
        .transpose()
        .map_err(to_py_err)?;
    let preset = match (named, &file) {
        (Some(name), _) => name.parse().map_err(to_py_err)?,
        (None, Some(f)) => f.preset.unwrap_or(fallback),
        (None, None) => fallback,
    };
    let mut changes: Vec<Changes> = file.map(|f| f.changes).into_iter().collect();
    for [origin, json] in layers {
        let table = serde_json::from_str(json)
            .map_err(|e| PyValueError::new_err(format!("{origin}: {e}")))?;
        let layer = SettingsFile::of_table(origin.clone(), table).map_err(to_py_err)?;
        changes.push(layer.changes);
    }
    let settings = Settings::layered(preset, &changes).map_err(to_py_err)?;
    Ok((preset, settings))
}

/// The settings a run would use, as JSON (`ggs.settings`).
#[pyfunction]
pub(crate) fn settings(options: Options) -> PyResult<String> {
    let (_, s) = options.settings()?;
    Ok(s.to_json().to_string())
}

/// Register `source` onto `target` (the pipeline); returns the result's document
/// ([`RegistrationDocument`], JSON) and its report page.
#[pyfunction]
#[pyo3(signature = (source, target, options, rotation_matrices=None, progress=None))]
pub(crate) fn register<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    options: Options,
    rotation_matrices: Option<&Bound<'py, PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(String, report::Report)> {
    let t0 = Instant::now();
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let (preset, mut settings) = options.settings()?;
    let mut cfg = settings.plan(options.threads).map_err(to_py_err)?;
    if let Some(m) = rotation_matrices {
        let set = rotations_of("rotations", m)?;
        cfg.rotations = match settings.dedup {
            Some(tol) => set.without_duplicates_within(tol).map_err(to_py_err)?,
            None => set,
        };
        settings.rotations = format!("{} rotations given as matrices", cfg.rotations.len());
    }
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
        ggs::settings::register_planned(&source, &target, &settings, &cfg)
    })?
    .map_err(to_py_err)?;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let doc = RegistrationDocument {
        preset: Some(preset.name()),
        ..RegistrationDocument::new(&reg, total_ms)
    };
    let text = serde_json::to_string(&doc).expect("a registration serializes");
    let mut inner = ggs::html::registration::RegistrationReport::new(&source, &target, reg);
    inner.total_ms = Some(total_ms);
    Ok((text, report::Report { inner }))
}

/// Refine `init` by ICP with the reference GICP's settings (the paper preset's) changed by
/// `changes` (a JSON object of settings keys); returns the result's document
/// ([`RefinementDocument`], JSON).
#[pyfunction(name = "refine")]
#[pyo3(signature = (source, target, init, changes, threads))]
pub(crate) fn refine_py<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    init: &Bound<'py, PyAny>,
    changes: String,
    threads: usize,
) -> PyResult<String> {
    let t0 = Instant::now();
    let source = Cloud::new(points_of("source", source)?);
    let target = Cloud::new(points_of("target", target)?);
    let init = matrix_of("init", init)?;
    let layers = [["refine".to_string(), changes]];
    let (_, settings) = layered(Some("paper"), None, &layers, Preset::Paper)?;
    let cfg = settings
        .refine_config(threads)
        .ok_or_else(|| PyValueError::new_err("refine: method must be gicp, p2plane or p2p"))?;
    let cancel = Arc::new(AtomicBool::new(false));
    let r = run_interruptible(py, &cancel, None, || {
        refine::refine(&source, &target, &init, &cfg)
    })?
    .map_err(to_py_err)?;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let doc = RefinementDocument::new(init, &r, total_ms);
    Ok(serde_json::to_string(&doc).expect("a refinement serializes"))
}
