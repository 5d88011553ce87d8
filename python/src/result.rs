//! A registration or refinement as a plain dict (the Python `ggs.Result` wraps it): every key
//! present in every mode, `None` or 0.0 where a stage did not run.

use crate::arrays::matrix_array;
use ggs::coarse::Hypothesis;
use ggs::pipeline::Registration;
use ggs::refine::RefineResult;
use ggs::Rigid;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// Timing keys, in milliseconds, always present.
const TIMING_KEYS: [&str; 7] = [
    "coarse_ms",
    "target_ms",
    "extents_ms",
    "search_ms",
    "verify_ms",
    "refine_ms",
    "total_ms",
];

fn hypothesis_dict<'py>(py: Python<'py>, h: &Hypothesis) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rotation_index", h.rotation_index)?;
    d.set_item("score", h.score)?;
    d.set_item("match_score", h.match_score)?;
    d.set_item("offset", h.offset.to_vec())?;
    d.set_item("transformation", matrix_array(py, &h.transform)?)?;
    Ok(d)
}

fn report_dict<'py>(py: Python<'py>, r: &RefineResult) -> PyResult<Bound<'py, PyDict>> {
    let q = &r.report;
    let d = PyDict::new(py);
    d.set_item("method", r.method.name())?;
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
    Ok(d)
}

fn verified_list<'py>(py: Python<'py>, reg: &Registration) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    let Some(v) = &reg.verification else {
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
        d.set_item("at_a_glance", h.at_a_glance)?;
        d.set_item("evidence_points", h.evidence.points.to_vec())?;
        d.set_item("free_space_violations", h.evidence.free_space_violations)?;
        let level = match h.level {
            ggs::pipeline::HypothesisLevel::Voxel => "voxel",
            ggs::pipeline::HypothesisLevel::Coarse => "coarse",
        };
        d.set_item("level", level)?;
        d.set_item("settled", h.settled)?;
        d.set_item("same_as", h.same_as)?;
        d.set_item("screened", h.screened)?;
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

fn first_look_dict<'py>(
    py: Python<'py>,
    f: &ggs::pipeline::FirstLookReport,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rotations", f.rotations)?;
    d.set_item("verified", f.verified)?;
    d.set_item("score", f.score)?;
    d.set_item("runner_up_score", f.runner_up_score)?;
    d.set_item("accept_score", f.accept_score)?;
    d.set_item("accepted", f.accepted)?;
    Ok(d)
}

/// The dict of a result: `registration` for `register`, `None` for `refine`.
pub fn result_dict<'py>(
    py: Python<'py>,
    transform: &Rigid,
    registration: Option<&Registration>,
    refined: Option<&RefineResult>,
    total_ms: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("transformation", matrix_array(py, transform)?)?;
    let q = refined.map(|r| &r.report);
    d.set_item("fitness", q.map(|q| q.fitness_source))?;
    d.set_item("fitness_target", q.map(|q| q.fitness_target))?;
    d.set_item("inlier_rmse", q.map(|q| q.inlier_rmse))?;
    d.set_item("converged", q.map(|q| q.converged))?;
    d.set_item("report", refined.map(|r| report_dict(py, r)).transpose()?)?;
    let c = registration.map(|r| &r.search);
    d.set_item(
        "coarse_transformation",
        registration
            .map(|r| matrix_array(py, &r.coarse_transform))
            .transpose()?,
    )?;
    d.set_item("score", c.map(|c| c.winner().score))?;
    d.set_item("ambiguity", c.and_then(|c| c.ambiguity))?;
    d.set_item("rotation_index", c.map(|c| c.winner().rotation_index))?;
    d.set_item("voxel", registration.map(|r| r.voxel))?;
    d.set_item("confidence", registration.map(|r| r.confidence))?;
    d.set_item("ambiguous", registration.map(|r| r.ambiguous))?;
    d.set_item("chosen_rank", registration.map(|r| r.chosen_rank))?;
    d.set_item(
        "warnings",
        registration.map_or_else(Vec::new, |r| r.warnings.clone()),
    )?;
    let hyps = PyList::empty(py);
    for h in c.map_or(&[][..], |c| &c.hypotheses[..]) {
        hyps.append(hypothesis_dict(py, h)?)?;
    }
    d.set_item("hypotheses", hyps)?;
    d.set_item(
        "verified",
        match registration {
            Some(r) => verified_list(py, r)?,
            None => PyList::empty(py),
        },
    )?;
    let look = registration.and_then(|r| r.first_look);
    d.set_item(
        "first_look",
        look.map(|f| first_look_dict(py, &f)).transpose()?,
    )?;
    let t = PyDict::new(py);
    for k in TIMING_KEYS {
        t.set_item(k, 0.0)?;
    }
    if let Some(r) = registration {
        let s = &r.search.timings;
        t.set_item("coarse_ms", s.total_ms)?;
        t.set_item("target_ms", s.target_ms)?;
        t.set_item("extents_ms", s.extents_ms)?;
        t.set_item("search_ms", s.search_ms)?;
        t.set_item("verify_ms", r.timings.verify_ms)?;
    }
    if let Some(r) = refined {
        t.set_item("refine_ms", r.total_ms)?;
    }
    t.set_item("total_ms", total_ms)?;
    d.set_item("timings", t)?;
    let settings = registration.and_then(|r| r.settings.as_ref());
    let settings = match settings {
        Some(s) => Some(py.import("json")?.call_method1("loads", (s.to_string(),))?),
        None => None,
    };
    d.set_item("settings", settings)?;
    Ok(d)
}
