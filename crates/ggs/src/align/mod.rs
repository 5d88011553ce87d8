//! Aligning a set of scans into one frame with no initial guess (`ggs align`).
//!
//! 1. **Prepare** ([`scan`]): each scan is thinned, indexed and summarized by a shape
//!    descriptor that does not change when it moves.
//! 2. **Place** ([`placement`]): starting from a seed (the scan whose shape descriptor is
//!    nearest to all the others', so that a stray scan is not the start), scans are
//!    registered onto a model of placed scans by ggs's verified global registration
//!    ([`crate::register`]); a registration that is ambiguous, unsure or leaves too little
//!    of the scan on the model does not place it. Scans left over are unplaced. About
//!    `N − 1` registrations, plus one per retry of a scan that did not fit the model yet,
//!    instead of the `N(N − 1)/2` of every pair.
//! 3. **Pose graph** ([`graph`]): every pair of placed scans that overlap gets an edge
//!    measured by ICP; edges that disagree with the placements (a cycle that does not close)
//!    are rejected. An edge between scans that overlap much and whose ICP turns their
//!    relative pose by a degree or more contradicts a placement: the later placed of its two
//!    scans is withdrawn and step 2 resumes. Then the poses are optimized over the accepted
//!    edges with a robust kernel.
//! 4. **Joint refinement** ([`joint`]): each scan refined against all its neighbours at once.
//!
//! Every step is deterministic and independent of the thread count; the batch of
//! registrations of step 2 is fixed before it runs, so a parallel executor (Ray, from Python)
//! gives the same result as running them one by one ([`Aligner`]).

pub mod folder;
pub mod graph;
pub mod icp;
pub mod joint;
pub mod overlap;
pub mod placement;
pub mod result;
pub mod scan;

pub use folder::write_folder;
pub use placement::{PlacementJob, PlacementOutcome, PlacementRules};
pub use result::{AlignTimes, Alignment, ScanPose, ALIGNMENT_FORMAT};
pub use scan::AlignScan;

use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use crate::pipeline::RegistrationConfig;
use crate::refine::RefineConfig;
use crate::settings::{Runtime, Settings};
use crate::transform::Rigid;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Align `scans` into the frame of scan `anchor` (0 when `None`; when that scan cannot be
/// placed, the frame is the seed's and the result says so), running each registration here
/// with `runtime`'s threads. (A `Vec` passes without a copy.)
pub fn align(
    scans: impl Into<Arc<[AlignScan]>>,
    settings: &Settings,
    anchor: Option<usize>,
    runtime: &Runtime,
) -> Result<Alignment> {
    Aligner::new(scans, settings, anchor, runtime)?.run(runtime, |_, _| {})
}

/// The verification score a placement's pose needs, per unit of `align_min_overlap`: the
/// score is the mean of the two sides' shares of points within `D`; a placed scan has at
/// least `align_min_overlap` of its points on the model, so its side alone gives about
/// half that (the model's side, a small part of a larger model, may give nearly nothing).
/// A hypothesis stops at its check only below `reject_ratio` × this, which leaves room for
/// an ICP not yet converged there. On the bunny and human-view sets every placement is the
/// same with it as without; a distractor's whole search costs a fifth.
pub const LEAST_SCORE_PER_OVERLAP: f64 = 0.5;

/// The registration a placement runs, planned once for a whole alignment: `settings`' plan
/// on `runtime`, without the final refinement when it verifies its hypotheses (the pose
/// graph and the joint refinement refine every scan by ICP afterwards; where no
/// verification runs, the final refinement stays: it is then the registration's only ICP),
/// with a verification that drops, at their checks, the poses too weak to place a scan
/// ([`LEAST_SCORE_PER_OVERLAP`] × `align_min_overlap`), and with a coarse-to-fine search that
/// stops widening once a doubling of its kept rotations leaves the winner unchanged
/// ([`CoarseToFine::stop_when_winner_holds`](crate::search::CoarseToFine)): a scan that fits
/// nowhere (another object's) would otherwise have every rotation scored at the voxel size.
pub fn placement_plan(settings: &Settings, runtime: &Runtime) -> Result<RegistrationConfig> {
    let mut cfg = settings.plan_with(runtime)?;
    if let Some(v) = cfg.verify.as_mut() {
        v.least_score = LEAST_SCORE_PER_OVERLAP * settings.align_min_overlap;
        cfg.refine = None;
    }
    if let crate::search::SearchMode::CoarseToFine(c) = &mut cfg.search.mode {
        c.stop_when_winner_holds = true;
    }
    Ok(cfg)
}

/// Run one placement's registration here: `scan` onto the job's model with `plan` (the
/// [`placement_plan`] of `settings`), stopping after its first look for a quick try.
pub fn register_job(
    scan: &Cloud,
    job: &PlacementJob,
    plan: &RegistrationConfig,
    settings: &Settings,
) -> Result<PlacementOutcome> {
    let mut cfg = plan.clone();
    if let Some(look) = cfg.first_look.as_mut() {
        look.stop_unsettled = job.quick;
    }
    let model = Cloud::new(job.model_points.clone());
    let r = crate::settings::register_planned(scan, &model, settings, &cfg)?;
    Ok(PlacementOutcome::of(&r, job.quick, settings.reject_ratio))
}

/// Run a batch's registrations here and return their outcomes in job order, side by side on
/// one pool of `plan.threads` threads that their own parallel work shares (a thread that
/// finishes its registration helps the others'). The outcomes do not depend on how the
/// threads are shared, since a registration's result does not depend on its thread count.
pub fn register_batch(
    scans: &[AlignScan],
    jobs: &[PlacementJob],
    plan: &RegistrationConfig,
    settings: &Settings,
) -> Result<Vec<PlacementOutcome>> {
    let mut cfg = plan.clone();
    cfg.threads = crate::threads::resolve(plan.threads);
    let runs: Vec<Result<PlacementOutcome>> = crate::threads::in_pool(cfg.threads, || {
        jobs.par_iter()
            .map(|job| {
                let scan = &scans[job.scan];
                let run = || register_job(&scan.cloud, job, &cfg, settings);
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(run))
                    .unwrap_or_else(|_| Err(stopped(&scan.name)))
            })
            .collect()
    })?;
    runs.into_iter().collect()
}

/// A placement's registration ended without a result (a panic: a bug, reported as an error).
fn stopped(scan: &str) -> GgsError {
    GgsError::param(
        "align",
        format!("the registration placing {scan} stopped unexpectedly"),
    )
}

/// An alignment in steps, for a caller that runs the registrations itself (a progress
/// display, a Ray cluster): [`Aligner::next_jobs`] gives the registrations to run (all of a
/// batch can run at once), [`Aligner::record`] takes their outcomes, in job order, until no
/// job is left; then [`Aligner::finish`] builds the pose graph, refines and reports. The
/// result does not depend on how or where the jobs ran.
pub struct Aligner {
    scans: Arc<[AlignScan]>,
    settings: Settings,
    /// The registration of every placement run here ([`placement_plan`]).
    plan: RegistrationConfig,
    growth: placement::Growth,
    seed: usize,
    anchor: usize,
    /// Threads of the edges' ICP.
    threads: usize,
    /// The scans' ICP clouds, shared by the edges and the joint refinement.
    icp: icp::IcpClouds,
    /// The pose graph's edges measured when no job was left, if no placement changed since.
    checked: Option<Vec<graph::Edge>>,
    started: Instant,
    times: AlignTimes,
}

impl Aligner {
    /// Check and prepare the scans (see [`align`]).
    pub fn new(
        scans: impl Into<Arc<[AlignScan]>>,
        settings: &Settings,
        anchor: Option<usize>,
        runtime: &Runtime,
    ) -> Result<Self> {
        let scans = scans.into();
        let started = Instant::now();
        settings.validate()?;
        let anchor = anchor.unwrap_or(0);
        if anchor >= scans.len() {
            let n = scans.len();
            return Err(GgsError::param(
                "anchor",
                format!("no scan {anchor} in a set of {n}"),
            ));
        }
        let prepared = crate::threads::in_pool(runtime.threads, || {
            scan::prepare_all(&scans, settings.verify_distance_range)
        })??;
        let seed = scan::medoid(&prepared);
        let plan = placement_plan(settings, runtime)?;
        let rules = PlacementRules {
            min_overlap: settings.align_min_overlap,
            min_confidence: settings.align_min_confidence,
            model_scans: settings.align_model_scans,
            batch: settings.align_batch,
            quick_first: plan.first_look.is_some(),
        };
        let times = AlignTimes {
            prepare_ms: ms(started),
            ..AlignTimes::default()
        };
        let icp = icp::IcpClouds::new(
            scans.len(),
            &alignment_refine_config(settings, runtime.threads),
        );
        Ok(Aligner {
            icp,
            scans,
            settings: settings.clone(),
            plan,
            growth: placement::Growth::new(prepared, seed, rules),
            seed,
            anchor,
            threads: runtime.threads,
            checked: None,
            started,
            times,
        })
    }

    /// The scans, as given.
    pub fn scans(&self) -> &[AlignScan] {
        &self.scans
    }

    /// The scans, shared (no copy).
    pub fn shared_scans(&self) -> Arc<[AlignScan]> {
        self.scans.clone()
    }

    /// The scans placed so far (the seed included).
    pub fn placed_count(&self) -> usize {
        self.growth.poses.iter().flatten().count()
    }

    /// The next batch of registrations; empty when the placement is done. When no
    /// registration is left, the pose graph's edges are measured: the later placed scan of
    /// each edge that contradicts the placements ([`graph::Edge::contradicts`]) is withdrawn
    /// ([`placement::Growth::withdraw`]) and the placement resumes; else the edges are kept
    /// for [`Aligner::finish`].
    pub fn next_jobs(&mut self) -> Result<Vec<PlacementJob>> {
        loop {
            let jobs = self.growth.next_jobs();
            if !jobs.is_empty() {
                self.checked = None;
                return Ok(jobs);
            }
            let t = Instant::now();
            let edges = self.measure_edges()?;
            self.times.graph_ms += ms(t);
            if self.withdraw_contradicted(&edges) == 0 {
                self.checked = Some(edges);
                return Ok(Vec::new());
            }
        }
    }

    fn measure_edges(&self) -> Result<Vec<graph::Edge>> {
        let refine_cfg = alignment_refine_config(&self.settings, self.threads);
        let (prepared, poses) = (&self.growth.prepared, &self.growth.poses);
        crate::threads::in_pool(self.threads, || {
            graph::measure_edges(prepared, &self.icp, poses, &refine_cfg)
        })?
    }

    /// Withdraw the later placed scan of each contradicting edge; returns how many.
    fn withdraw_contradicted(&mut self, edges: &[graph::Edge]) -> usize {
        let contradicting: Vec<&graph::Edge> = edges.iter().filter(|e| e.contradicts()).collect();
        let pairs: Vec<(usize, usize)> = contradicting.iter().map(|e| (e.from, e.to)).collect();
        let later = self.growth.later_placed(&pairs);
        for &u in &later {
            let e = contradicting
                .iter()
                .find(|e| e.from == u || e.to == u)
                .expect("a contradicting edge of u");
            let other = &self.scans[if e.from == u { e.to } else { e.from }].name;
            let why = format!("its placement contradicted {other}'s: {}", contradiction(e));
            let note = format!(
                "{} was withdrawn and tried again: {why} (a near-symmetric object can fit turned)",
                self.scans[u].name
            );
            self.growth.withdrawal_notes.push(note);
            self.growth.withdraw(u, why);
        }
        later.len()
    }

    /// The outcomes of `jobs` (as [`Aligner::next_jobs`] gave them), in job order.
    pub fn record(&mut self, jobs: &[PlacementJob], outcomes: Vec<PlacementOutcome>) -> Result<()> {
        if outcomes.len() != jobs.len() {
            let what = format!("{} outcomes for {} jobs", outcomes.len(), jobs.len());
            return Err(GgsError::param("outcomes", what));
        }
        for (job, outcome) in jobs.iter().zip(outcomes) {
            self.growth.record(job, outcome);
        }
        Ok(())
    }

    /// Run every placement here ([`register_batch`]), calling `on_batch(the scans of the
    /// batch, scans placed so far)` before each batch, then [`Aligner::finish`].
    pub fn run(
        &mut self,
        runtime: &Runtime,
        mut on_batch: impl FnMut(&[&AlignScan], usize),
    ) -> Result<Alignment> {
        loop {
            let jobs = self.next_jobs()?;
            if jobs.is_empty() {
                return self.finish(runtime);
            }
            let batch: Vec<&AlignScan> = jobs.iter().map(|j| &self.scans[j.scan]).collect();
            on_batch(&batch, self.placed_count());
            let outcomes = register_batch(&self.scans, &jobs, &self.plan, &self.settings)?;
            self.record(&jobs, outcomes)?;
        }
    }

    /// The pose graph, the joint refinement and the result, once no job is left.
    pub fn finish(&self, runtime: &Runtime) -> Result<Alignment> {
        let mut times = self.times;
        times.place_ms = ms(self.started) - times.prepare_ms - times.graph_ms;
        let prepared = &self.growth.prepared;
        let refine_cfg = alignment_refine_config(&self.settings, runtime.threads);
        let t = Instant::now();
        let poses = &self.growth.poses;
        let edges = match &self.checked {
            Some(edges) => edges.clone(),
            None => self.measure_edges()?,
        };
        let optimized = crate::threads::in_pool(runtime.threads, || {
            graph::optimize_poses(prepared, poses, &edges, self.seed)
        })?;
        times.graph_ms += ms(t);
        let t = Instant::now();
        let graph_failed = optimized.is_none();
        let optimized = optimized.unwrap_or_else(|| poses.clone());
        let poses = crate::threads::in_pool(runtime.threads, || {
            joint::refine_jointly(
                prepared,
                &self.icp,
                &optimized,
                &edges,
                self.seed,
                &refine_cfg,
            )
        })??;
        times.joint_ms = ms(t);
        times.total_ms = ms(self.started);
        let outcome = Outcome {
            poses,
            edges,
            seed: self.seed,
            anchor: self.anchor,
            graph_failed,
        };
        Ok(report(
            &self.scans,
            prepared,
            &self.growth,
            outcome,
            &self.settings,
            times,
        ))
    }
}

/// The ICP of the pose graph's edges and of the joint refinement: the final refinement's
/// (GICP when `refine` is none), stopped as the final refinement is: when an update turns by
/// less than `refine_min_step` radians and moves by less than `refine_min_step` × the scan's
/// radius.
fn alignment_refine_config(settings: &Settings, threads: usize) -> RefineConfig {
    let r = settings.refine_config(threads).unwrap_or(RefineConfig {
        threads,
        ..RefineConfig::default()
    });
    RefineConfig {
        min_rotation_step: r.min_rotation_step.max(settings.refine_min_step),
        min_translation_step: r.min_translation_step.max(settings.refine_min_step),
        ..r
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The final poses (in the seed's frame) and graph, the seed and the anchor asked for.
struct Outcome {
    poses: Vec<Option<Rigid>>,
    edges: Vec<graph::Edge>,
    seed: usize,
    anchor: usize,
    /// The pose-graph optimization failed: the placements went to the joint refinement.
    graph_failed: bool,
}

/// The [`Alignment`] of the final poses, in the anchor's frame when the anchor is placed
/// (else another placed scan's, with a warning). A placed scan that no accepted edge joins to
/// another (when there are others) is reported unplaced.
fn report(
    scans: &[AlignScan],
    prepared: &[scan::Prepared],
    growth: &placement::Growth,
    o: Outcome,
    settings: &Settings,
    times: AlignTimes,
) -> Alignment {
    let mut warnings = Vec::new();
    if o.graph_failed {
        let what =
            "the pose-graph optimization failed: the poses are the placements, refined jointly";
        warnings.push(what.to_string());
    }
    let confirmed = confirmed_poses(&o);
    let frame = frame_scan(&confirmed, &o);
    if frame != o.anchor {
        warnings.push(format!(
            "{} is not placed: the common frame is that of {}",
            scans[o.anchor].name, scans[frame].name
        ));
    }
    let to_frame = confirmed[frame]
        .expect("the frame scan is placed")
        .inverse();
    let mut poses: Vec<Option<Rigid>> = confirmed
        .iter()
        .map(|p| p.map(|p| to_frame.compose(&p)))
        .collect();
    poses[frame] = Some(Rigid::identity());
    warnings.extend(growth.withdrawal_notes.iter().cloned());
    let out = (0..scans.len())
        .map(|i| scan_pose(i, scans, prepared, growth, &poses, &o))
        .collect();
    Alignment {
        format: ALIGNMENT_FORMAT,
        anchor: scans[frame].name.clone(),
        seed: scans[o.seed].name.clone(),
        scans: out,
        warnings,
        model_cell: scan::THIN_SPACINGS * prepared.iter().map(|p| p.spacing).fold(0.0, f64::max),
        registrations: growth.attempts.len(),
        attempts: growth.attempts.clone(),
        edges: o.edges,
        times,
        settings: settings.to_json(),
    }
}

/// What a contradicting edge measured.
fn contradiction(e: &graph::Edge) -> String {
    format!(
        "they overlap by {:.0} % but ICP moves their relative pose by {:.1}° and {:.3}",
        e.overlap * 100.0,
        e.moved_deg,
        e.moved_distance
    )
}

/// The placed scans that an accepted edge joins to another (all of them when only one is
/// placed; the seed alone when no edge is accepted).
fn confirmed_poses(o: &Outcome) -> Vec<Option<Rigid>> {
    let joined = |i: usize| {
        o.edges
            .iter()
            .any(|e| e.accepted && (e.from == i || e.to == i))
    };
    let placed = o.poses.iter().flatten().count();
    let mut poses: Vec<Option<Rigid>> = (0..o.poses.len())
        .map(|i| o.poses[i].filter(|_| placed < 2 || joined(i)))
        .collect();
    if poses.iter().all(Option::is_none) {
        poses[o.seed] = o.poses[o.seed];
    }
    poses
}

/// The anchor when it is placed, else the seed, else the first placed scan.
fn frame_scan(poses: &[Option<Rigid>], o: &Outcome) -> usize {
    [o.anchor, o.seed]
        .into_iter()
        .chain(0..poses.len())
        .find(|&i| poses[i].is_some())
        .expect("a scan is placed")
}

/// Scan `i`'s outcome: its pose in the common frame with its confidence and overlap, or why
/// it is not placed.
fn scan_pose(
    i: usize,
    scans: &[AlignScan],
    prepared: &[scan::Prepared],
    growth: &placement::Growth,
    poses: &[Option<Rigid>],
    o: &Outcome,
) -> ScanPose {
    let s = &scans[i];
    let Some(pose) = poses[i] else {
        if o.poses[i].is_some() {
            return unplaced(s, "placed, but no other scan's overlap confirms its pose");
        }
        let last = growth.attempts.iter().rev().find(|a| a.scan == i);
        let reason = last
            .and_then(|a| a.reason.clone())
            .or_else(|| growth.withdrawn[i].clone());
        return unplaced(s, &reason.unwrap_or_else(|| "never tried".into()));
    };
    let others: Vec<usize> = (0..poses.len())
        .filter(|&j| j != i && poses[j].is_some())
        .collect();
    let at: Vec<Rigid> = others.iter().map(|&j| poses[j].unwrap()).collect();
    let placing = growth
        .attempts
        .iter()
        .rev()
        .find(|a| a.scan == i && a.placed);
    ScanPose {
        name: s.name.clone(),
        pose: Some(pose),
        confidence: placing.map_or(1.0, |a| a.confidence),
        overlap: overlap::overlap_share(prepared, i, &pose, &others, &at, overlap::OVERLAP_SAMPLE),
        reason: None,
    }
}

fn unplaced(s: &AlignScan, reason: &str) -> ScanPose {
    ScanPose {
        name: s.name.clone(),
        pose: None,
        confidence: 0.0,
        overlap: 0.0,
        reason: Some(reason.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_contradiction_says_what_the_edge_measured() {
        let e = graph::Edge {
            from: 0,
            to: 1,
            relative: Rigid::identity(),
            overlap: 0.45,
            moved_deg: 3.5,
            moved_distance: 0.04,
            accepted: false,
            reason: None,
        };
        assert!(e.contradicts());
        let text = contradiction(&e);
        assert_eq!(
            text,
            "they overlap by 45 % but ICP moves their relative pose by 3.5° and 0.040"
        );
        // An accepted edge contradicts as well; a small overlap or a small turn does not.
        let accepted = graph::Edge {
            accepted: true,
            ..e.clone()
        };
        let small = graph::Edge {
            overlap: 0.2,
            ..e.clone()
        };
        let slight = graph::Edge {
            moved_deg: 0.6,
            ..e
        };
        assert!(accepted.contradicts() && !small.contradicts() && !slight.contradicts());
    }
}
