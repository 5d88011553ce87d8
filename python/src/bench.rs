//! Benchmarks from Python: `ggs.bench.run` drives these with a local loop or a Ray cluster.
//!
//! A [`BenchPlan`] is the library's `benchmark::Plan` (built from the same selection and
//! options as `ggs bench`, validated in the library); [`BenchPlan::run_pair`] runs one pair
//! where it is called (a Ray worker reads its clouds from their paths) and returns the row as
//! its CSV line, which crosses processes bit for bit; a [`RunDirectory`] is the run directory the
//! driver records those lines in, in any order, and finishes with the files `ggs bench` writes.

use crate::arrays::to_py_err;
use crate::interrupt::run_interruptible;
use crate::registration::Options;
use ggs::pipeline::Preset;
use ggs::Settings;
use ggs_bench::benchmark::shard::Shard;
use ggs_bench::benchmark::{run_pair_with_picture, BenchVoxel, PairRow, Plan, RunDir, Selection};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The selection half of `ggs.bench.run`'s arguments, as the Python layer passes them.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct SelectionArgs {
    protocol: String,
    manifest: Option<PathBuf>,
    data: Option<PathBuf>,
    pairs: Option<String>,
    limit: Option<usize>,
    shard: Option<String>,
    voxel: Option<VoxelArg>,
    move_seed: Option<u64>,
    max_rre: Option<f64>,
    max_rte: Option<f64>,
}

/// `voxel=`: a number or `"auto"`.
#[derive(FromPyObject)]
enum VoxelArg {
    Size(f64),
    Name(String),
}

impl VoxelArg {
    fn parse(self) -> PyResult<BenchVoxel> {
        let text = match self {
            VoxelArg::Size(v) => v.to_string(),
            VoxelArg::Name(s) => s,
        };
        text.parse().map_err(to_py_err)
    }
}

/// A validated benchmark run: its pairs and configuration.
#[pyclass(frozen, module = "ggs._ggs")]
pub struct BenchPlan {
    plan: Plan,
}

#[pymethods]
impl BenchPlan {
    #[new]
    fn new(selection: SelectionArgs, options: Options) -> PyResult<Self> {
        let s = selection;
        let sel = Selection {
            protocol: s.protocol,
            manifest: s.manifest,
            data: s.data,
            pairs: s.pairs,
            limit: s.limit,
            shard: s
                .shard
                .as_deref()
                .map(Shard::parse)
                .transpose()
                .map_err(to_py_err)?,
            voxel: s.voxel.map(VoxelArg::parse).transpose()?,
            move_seed: s.move_seed,
            max_rre_deg: s.max_rre,
            max_rte: s.max_rte,
        };
        let (preset, settings) = options.settings()?;
        // A paper run with the paper's rotation set uses the protocol's set of the paper.
        let paper_rotations = preset == Preset::Paper
            && settings.rotations == Settings::preset(Preset::Paper).rotations;
        let plan =
            Plan::new(&sel, settings, options.threads, paper_rotations).map_err(to_py_err)?;
        Ok(BenchPlan { plan })
    }

    /// The protocol's name (`manifest` for a manifest).
    #[getter]
    fn name(&self) -> &'static str {
        self.plan.name
    }

    /// The pairs' ids, in order.
    #[getter]
    fn ids(&self) -> Vec<String> {
        self.plan.pairs.iter().map(|p| p.id.clone()).collect()
    }

    /// The run directory used when none is given.
    fn default_out(&self) -> PathBuf {
        self.plan.default_out()
    }

    /// Run pair `k` here: its `pairs.csv` line and, for a failed pair, its gallery picture
    /// (PNG). Errors of the pair are recorded in the row; Ctrl-C raises KeyboardInterrupt.
    fn run_pair<'py>(
        &self,
        py: Python<'py>,
        k: usize,
    ) -> PyResult<(String, Option<Bound<'py, PyBytes>>)> {
        let pair = self.plan.pairs.get(k).ok_or_else(|| {
            PyValueError::new_err(format!("pair {k}: the plan has {}", self.plan.pairs.len()))
        })?;
        let mut cfg = self.plan.cfg.clone();
        let cancel = Arc::new(AtomicBool::new(false));
        cfg.cancel = Some(cancel.clone());
        let (row, png) =
            run_interruptible(py, &cancel, None, || run_pair_with_picture(pair, &cfg))?;
        Ok((row.to_csv(), png.map(|b| PyBytes::new(py, &b))))
    }

    /// The line of pair `k` when it could not be run at all (`message` says why).
    fn error_row(&self, k: usize, message: &str) -> PyResult<String> {
        let pair = self.plan.pairs.get(k).ok_or_else(|| {
            PyValueError::new_err(format!("pair {k}: the plan has {}", self.plan.pairs.len()))
        })?;
        let mut row = PairRow::new(&pair.id, pair.overlap);
        row.error = Some(message.to_string());
        Ok(row.to_csv())
    }
}

fn parse_row(line: &str) -> PyResult<PairRow> {
    PairRow::from_csv(line).map_err(|e| PyValueError::new_err(format!("not a ggs row: {e}")))
}

/// A row as JSON (the fields of `results.json`'s pairs), for progress callbacks.
#[pyfunction]
pub fn bench_row_json(line: &str) -> PyResult<String> {
    Ok(serde_json::to_string(&parse_row(line)?).expect("rows serialize"))
}

/// An open run directory.
#[pyclass(module = "ggs._ggs")]
pub struct RunDirectory {
    dir: Option<RunDir>,
}

impl RunDirectory {
    fn dir(&mut self) -> PyResult<&mut RunDir> {
        self.dir
            .as_mut()
            .ok_or_else(|| PyRuntimeError::new_err("this run is finished"))
    }
}

#[pymethods]
impl RunDirectory {
    /// Open `out` for `plan` (a directory of another configuration is refused).
    #[new]
    fn new(plan: &BenchPlan, out: PathBuf) -> PyResult<Self> {
        let dir = RunDir::open(&plan.plan, &out).map_err(to_py_err)?;
        Ok(RunDirectory { dir: Some(dir) })
    }

    /// `{id: error or None}` of the given ids that have a row.
    fn recorded(&mut self, ids: Vec<String>) -> PyResult<HashMap<String, Option<String>>> {
        let dir = self.dir()?;
        Ok(ids
            .into_iter()
            .filter_map(|id| dir.row(&id).map(|r| (id, r.error.clone())))
            .collect())
    }

    /// Record a finished pair's line (and picture).
    #[pyo3(signature = (line, picture_png=None))]
    fn record(&mut self, line: &str, picture_png: Option<&[u8]>) -> PyResult<()> {
        let row = parse_row(line)?;
        self.dir()?.record(row, picture_png).map_err(to_py_err)
    }

    /// Write the run's files; every pair must have a row.
    fn finish(&mut self) -> PyResult<()> {
        let dir = self
            .dir
            .take()
            .ok_or_else(|| PyRuntimeError::new_err("this run is finished"))?;
        dir.finish().map(|_| ()).map_err(to_py_err)
    }
}
