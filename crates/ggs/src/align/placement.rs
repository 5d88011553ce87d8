//! Placing scans one by one: the growing model.
//!
//! The seed is placed first, at the identity. Then, repeatedly, waiting scans are
//! registered (ggs's verified global registration, no initial guess) onto a model: placed
//! scans moved into the common frame, merged and thinned. A scan is tried quickly first (the
//! registration's first look only, onto the `align_model_scans` placed scans whose shape
//! descriptors ([`Prepared::descriptor`]) are nearest to its own); when no quick try is
//! left, the scans still waiting get the whole search onto every placed scan. A registration
//! places its scan when it is not ambiguous, its confidence is at least
//! `align_min_confidence`, and at least `align_min_overlap` of the scan's points (at least
//! [`QUICK_MIN_OVERLAP`] for a quick try, and at least [`MIN_OVERLAP_POINTS`] points) then
//! lie within the overlap distance of the model; otherwise the scan waits, and is tried
//! again only onto another model. When no scan is left to try, the placements are checked
//! against each other (the caller measures the pose graph's edges): of two placed scans
//! whose placements contradict each other, the one placed later is withdrawn
//! ([`Growth::withdraw`]) and waits again, up to [`MAX_WITHDRAWALS`] times. The run ends
//! when no scan is left to try and no placement is contradicted: the scans never placed are
//! reported unplaced, not forced in.
//!
//! Every choice depends on the scans and the settings only: the jobs of a batch are fixed
//! before any of them runs and their outcomes are recorded in job order, so running a
//! batch's registrations one after the other, on threads or as Ray tasks gives the same
//! placements.

use super::overlap::{overlap_share, OVERLAP_SAMPLE};
use super::scan::{descriptor_distance, Prepared, THIN_SPACINGS};
use crate::cloud::Point;
use crate::pipeline::Registration;
use crate::transform::Rigid;
use serde::Serialize;

/// A quick try verified only its first look's few poses, so it places a scan on strong
/// evidence only: at least this share of the scan's points on the model (and
/// `align_min_overlap` if that is more). Weaker ones wait for the whole search.
pub const QUICK_MIN_OVERLAP: f64 = 0.6;
/// A placement needs at least this many of the scan's (thinned) points on the model: a scan
/// of a handful of points fits anywhere.
pub const MIN_OVERLAP_POINTS: f64 = 100.0;
/// A scan withdrawn this many times is not tried again: it is reported unplaced.
pub const MAX_WITHDRAWALS: usize = 2;

/// What decides the placements (from the settings, see [`crate::Settings`]'s `align_*` keys).
#[derive(Debug, Clone, Copy)]
pub struct PlacementRules {
    /// The least share of a scan's points within the overlap distance of the model.
    pub min_overlap: f64,
    /// The least confidence of the registration.
    pub min_confidence: f64,
    /// The model a scan is registered onto holds at most this many placed scans.
    pub model_scans: usize,
    /// Registrations decided together (see the module documentation).
    pub batch: usize,
    /// Try each scan quickly first (the registration's first look only), and with the whole
    /// search only when no quick try is left.
    pub quick_first: bool,
}

/// One registration to run: scan `scan` onto the merged placed scans `model`.
#[derive(Debug, Clone)]
pub struct PlacementJob {
    pub scan: usize,
    /// A quick try: the registration stops after its first look, settled or not
    /// ([`FirstLook::stop_unsettled`](crate::pipeline::FirstLook::stop_unsettled)).
    pub quick: bool,
    pub model: Vec<usize>,
    /// The model's points in the common frame.
    pub model_points: Vec<Point>,
}

/// What a placement needs to know of a registration.
#[derive(Debug, Clone)]
pub struct PlacementOutcome {
    /// `p_model = T · p_scan`.
    pub transform: Rigid,
    pub confidence: f64,
    pub ambiguous: bool,
    pub warnings: Vec<String>,
    /// False for a quick try whose first look did not settle the pair.
    pub settled: bool,
    /// Wall time of the registration, in milliseconds.
    pub ms: f64,
}

impl PlacementOutcome {
    /// The outcome of `r`, the registration of a job (`quick` as the job's). A quick try is
    /// settled when its first look accepted its pose, or when the first look's runner-up
    /// scores below `reject_ratio` times the chosen pose: the first look's own rule without
    /// its least score, which asks half of both clouds to meet and so cannot hold for a
    /// scan onto a model larger than the scan (the placement's overlap rule asks it of the
    /// scan instead).
    pub fn of(r: &Registration, quick: bool, reject_ratio: f64) -> Self {
        let clear = |f: &crate::pipeline::FirstLookReport| {
            f.accepted || f.runner_up_score.is_none_or(|s| s < reject_ratio * f.score)
        };
        PlacementOutcome {
            transform: r.transform,
            confidence: r.confidence,
            ambiguous: r.ambiguous,
            warnings: r.warnings.clone(),
            settled: !quick || r.first_look.as_ref().is_none_or(clear),
            ms: r.timings.total_ms,
        }
    }
}

/// One registration tried, and what came of it.
#[derive(Debug, Clone, Serialize)]
pub struct Attempt {
    /// Index of the scan registered.
    pub scan: usize,
    /// Indices of the placed scans that made the model.
    pub model: Vec<usize>,
    /// A quick try (see [`PlacementJob::quick`]).
    pub quick: bool,
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    pub confidence: f64,
    pub ambiguous: bool,
    /// Share of the scan's points within the overlap distance of the model.
    pub overlap: f64,
    pub placed: bool,
    /// Why the scan was not placed by this registration.
    pub reason: Option<String>,
    pub warnings: Vec<String>,
    pub ms: f64,
}

/// The state of the growing model (see the module documentation).
pub struct Growth {
    /// The scans, prepared.
    pub prepared: Vec<Prepared>,
    rules: PlacementRules,
    /// Pose of each scan in the common frame (`p_model = pose · p_scan`), once placed.
    pub poses: Vec<Option<Rigid>>,
    /// The number of placed scans when each scan was last tried quickly, and with the whole
    /// search (0: never).
    quick_tried_with: Vec<usize>,
    full_tried_with: Vec<usize>,
    /// The model of each scan's last quick and whole try: a try onto the same model is not
    /// run again.
    quick_model: Vec<Option<Vec<usize>>>,
    full_model: Vec<Option<Vec<usize>>>,
    /// Tries that did not place each scan.
    failures: Vec<usize>,
    /// When each placed scan was placed (0: the anchor), for [`Growth::later_placed`].
    placed_at: Vec<usize>,
    placements: usize,
    /// Times each scan was withdrawn, and why it was last (while it waits).
    withdrawals: Vec<usize>,
    pub withdrawn: Vec<Option<String>>,
    /// One line per withdrawal, for the alignment's warnings.
    pub withdrawal_notes: Vec<String>,
    pub attempts: Vec<Attempt>,
    /// The last model built ([`Growth::model_points`]) and its scans, while no placement
    /// changed: tries onto the same scans share it.
    last_model: Option<(Vec<usize>, Vec<Point>)>,
}

impl Growth {
    /// The anchor placed at the identity, every other scan waiting.
    pub fn new(prepared: Vec<Prepared>, anchor: usize, rules: PlacementRules) -> Self {
        let n = prepared.len();
        let mut poses = vec![None; n];
        poses[anchor] = Some(Rigid::identity());
        Growth {
            prepared,
            rules,
            poses,
            quick_tried_with: vec![0; n],
            full_tried_with: vec![0; n],
            quick_model: vec![None; n],
            full_model: vec![None; n],
            failures: vec![0; n],
            placed_at: vec![0; n],
            placements: 1,
            withdrawals: vec![0; n],
            withdrawn: vec![None; n],
            withdrawal_notes: Vec::new(),
            attempts: Vec::new(),
            last_model: None,
        }
    }

    fn placed(&self) -> Vec<usize> {
        (0..self.poses.len())
            .filter(|&i| self.poses[i].is_some())
            .collect()
    }

    /// Descriptor distance from scan `u` to its nearest placed scan.
    fn nearest_placed(&self, u: usize, placed: &[usize]) -> f64 {
        placed
            .iter()
            .map(|&q| {
                descriptor_distance(&self.prepared[u].descriptor, &self.prepared[q].descriptor)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The next batch (in the order the module documentation gives): quick tries while any
    /// is left, then whole searches; a try onto the same model as the scan's last of its kind
    /// is skipped; empty when the alignment is done.
    pub fn next_jobs(&mut self) -> Vec<PlacementJob> {
        let placed = self.placed();
        loop {
            let quick_order = if self.rules.quick_first {
                self.try_order(true, &placed)
            } else {
                Vec::new()
            };
            let quick = !quick_order.is_empty();
            let order = if quick {
                quick_order
            } else {
                self.try_order(false, &placed)
            };
            if order.is_empty() {
                return Vec::new();
            }
            let mut jobs = Vec::new();
            for u in order.into_iter().take(self.rules.batch.max(1)) {
                let model = self.model_of(u, &placed, quick);
                let (tried, last) = if quick {
                    (&mut self.quick_tried_with, &mut self.quick_model)
                } else {
                    (&mut self.full_tried_with, &mut self.full_model)
                };
                tried[u] = placed.len();
                if last[u].as_ref() != Some(&model) {
                    last[u] = Some(model.clone());
                    let model_points = self.model_points(&model).to_vec();
                    jobs.push(PlacementJob {
                        scan: u,
                        quick,
                        model,
                        model_points,
                    });
                }
            }
            if !jobs.is_empty() {
                return jobs;
            }
        }
    }

    /// The waiting scans not tried (quickly, or by a whole search) since the model last grew,
    /// in the order they are tried: quick tries go to the scans that failed fewer times
    /// first, then to those nearest to a placed scan by descriptor; whole searches, the
    /// costly tries, to the nearest first (so a scan unlike the set, such as another
    /// object's, comes last); ties by index.
    fn try_order(&self, quick: bool, placed: &[usize]) -> Vec<usize> {
        let tried = if quick {
            &self.quick_tried_with
        } else {
            &self.full_tried_with
        };
        let mut order: Vec<(usize, f64, usize)> = (0..self.poses.len())
            .filter(|&u| self.poses[u].is_none() && tried[u] < placed.len())
            .filter(|&u| self.withdrawals[u] < MAX_WITHDRAWALS)
            .map(|u| {
                let failures = if quick { self.failures[u] } else { 0 };
                (failures, self.nearest_placed(u, placed), u)
            })
            .collect();
        order.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
        order.into_iter().map(|(_, _, u)| u).collect()
    }

    /// The model of scan `u` (indices, increasing): the `model_scans` placed scans most alike
    /// to it for a quick try, every placed scan for a whole search.
    fn model_of(&self, u: usize, placed: &[usize], quick: bool) -> Vec<usize> {
        let d = |q: usize| {
            descriptor_distance(&self.prepared[u].descriptor, &self.prepared[q].descriptor)
        };
        let mut model = placed.to_vec();
        if quick {
            model.sort_by(|&a, &b| d(a).total_cmp(&d(b)).then(a.cmp(&b)));
            model.truncate(self.rules.model_scans.max(1));
            model.sort_unstable();
        }
        model
    }

    /// The scans `model` in the common frame, merged and thinned to cells of
    /// [`THIN_SPACINGS`] × their coarsest point spacing (built once while the placements
    /// stay as they are).
    fn model_points(&mut self, model: &[usize]) -> &[Point] {
        if self.last_model.as_ref().is_none_or(|(m, _)| m != model) {
            let mut points = Vec::new();
            let mut spacing: f64 = 0.0;
            for &q in model {
                let pose = self.poses[q].expect("placed");
                points.extend(self.prepared[q].thinned.iter().map(|p| pose.apply(p)));
                spacing = spacing.max(self.prepared[q].spacing);
            }
            if model.len() > 1 && spacing > 0.0 {
                points = crate::thin::cell_centroids(&points, THIN_SPACINGS * spacing);
            }
            self.last_model = Some((model.to_vec(), points));
        }
        &self.last_model.as_ref().expect("just built").1
    }

    /// Record the outcome of `job`'s registration: place the scan or keep it waiting.
    pub fn record(&mut self, job: &PlacementJob, outcome: PlacementOutcome) {
        let u = job.scan;
        let overlap = self.overlap_with(u, &outcome.transform, &job.model);
        let reason = if !outcome.settled {
            Some("a quick try did not settle it".to_string())
        } else if outcome.ambiguous {
            Some("the registration is ambiguous".to_string())
        } else if outcome.confidence < self.rules.min_confidence {
            Some(format!(
                "confidence {:.2}, under the {:.2} required",
                outcome.confidence, self.rules.min_confidence
            ))
        } else if overlap * (self.prepared[u].thinned.len() as f64) < MIN_OVERLAP_POINTS {
            Some(format!(
                "about {:.0} of its points meet the model, under the {MIN_OVERLAP_POINTS} required",
                overlap * self.prepared[u].thinned.len() as f64
            ))
        } else if overlap < self.required_overlap(job.quick) {
            Some(format!(
                "{:.0} % of its points meet the model, under the {:.0} % required{}",
                overlap * 100.0,
                self.required_overlap(job.quick) * 100.0,
                if job.quick { " of a quick try" } else { "" }
            ))
        } else {
            None
        };
        match reason {
            None => {
                self.poses[u] = Some(outcome.transform);
                self.last_model = None;
                self.placed_at[u] = self.placements;
                self.placements += 1;
                self.withdrawn[u] = None;
            }
            Some(_) => self.failures[u] += 1,
        }
        self.attempts.push(Attempt {
            scan: u,
            model: job.model.clone(),
            quick: job.quick,
            transform: outcome.transform,
            confidence: outcome.confidence,
            ambiguous: outcome.ambiguous,
            overlap,
            placed: reason.is_none(),
            reason,
            warnings: outcome.warnings,
            ms: outcome.ms,
        });
    }

    /// Of each pair of placed scans `(a, b)` whose placements contradict each other, the one
    /// placed later: a wrong placement passes to the scans placed onto it afterwards, never
    /// to those placed before it. Increasing, without repeats.
    pub fn later_placed(&self, pairs: &[(usize, usize)]) -> Vec<usize> {
        let mut later: Vec<usize> = pairs
            .iter()
            .filter(|&&(a, b)| self.poses[a].is_some() && self.poses[b].is_some())
            .map(|&(a, b)| {
                if self.placed_at[a] > self.placed_at[b] {
                    a
                } else {
                    b
                }
            })
            .collect();
        later.sort_unstable();
        later.dedup();
        later
    }

    /// Take placed scan `u` out of the model for `reason`: it waits again, to be tried onto
    /// any model (quickly first), unless this is its [`MAX_WITHDRAWALS`]th withdrawal.
    pub fn withdraw(&mut self, u: usize, reason: String) {
        self.poses[u] = None;
        self.last_model = None;
        self.withdrawals[u] += 1;
        self.withdrawn[u] = Some(reason);
        self.quick_tried_with[u] = 0;
        self.full_tried_with[u] = 0;
        self.quick_model[u] = None;
        self.full_model[u] = None;
    }

    /// The least overlap that places a scan: `align_min_overlap`, and at least
    /// [`QUICK_MIN_OVERLAP`] for a quick try.
    fn required_overlap(&self, quick: bool) -> f64 {
        if quick {
            self.rules.min_overlap.max(QUICK_MIN_OVERLAP)
        } else {
            self.rules.min_overlap
        }
    }

    /// Share of scan `u`'s thinned points, moved by `pose`, within the overlap distance of
    /// any of the scans `others` at their poses.
    pub fn overlap_with(&self, u: usize, pose: &Rigid, others: &[usize]) -> f64 {
        let poses: Vec<Rigid> = others
            .iter()
            .map(|&q| self.poses[q].expect("placed"))
            .collect();
        overlap_share(&self.prepared, u, pose, others, &poses, OVERLAP_SAMPLE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::scan::{prepare_all, AlignScan};
    use crate::cloud::Cloud;

    /// Four scans: a plane patch, the same patch again, a larger one and a line.
    fn prepared() -> Vec<Prepared> {
        let patch = |n: usize, step: f64| -> Cloud {
            Cloud::new(
                (0..n * n)
                    .map(|i| [(i % n) as f64 * step, (i / n) as f64 * step, 0.0])
                    .collect(),
            )
        };
        let line = Cloud::new((0..300).map(|i| [i as f64 * 0.01, 0.0, 0.0]).collect());
        let scans = [patch(20, 0.01), patch(20, 0.01), patch(30, 0.01), line];
        let scans: Vec<AlignScan> = scans
            .into_iter()
            .enumerate()
            .map(|(k, cloud)| AlignScan {
                name: format!("s{k}"),
                cloud,
            })
            .collect();
        prepare_all(&scans, 0.15).unwrap()
    }

    fn rules(batch: usize) -> PlacementRules {
        PlacementRules {
            min_overlap: 0.4,
            min_confidence: 0.3,
            model_scans: 8,
            batch,
            quick_first: true,
        }
    }

    fn outcome(settled: bool, confidence: f64) -> PlacementOutcome {
        PlacementOutcome {
            transform: Rigid::identity(),
            confidence,
            ambiguous: false,
            warnings: Vec::new(),
            settled,
            ms: 0.0,
        }
    }

    #[test]
    fn quick_tries_come_first_and_a_scan_is_tried_again_only_onto_another_model() {
        let mut g = Growth::new(prepared(), 0, rules(8));
        let jobs = g.next_jobs();
        assert!(jobs.iter().all(|j| j.quick) && jobs.len() == 3);
        // The same patch is nearest to the seed by descriptor, the line farthest.
        assert_eq!(jobs[0].scan, 1);
        assert_eq!(jobs.last().unwrap().scan, 3);
        for j in &jobs {
            g.record(j, outcome(false, 0.9));
        }
        let whole = g.next_jobs();
        assert!(whole.iter().all(|j| !j.quick) && whole.len() == 3);
        for j in &whole {
            g.record(j, outcome(true, 0.1));
        }
        assert!(
            g.next_jobs().is_empty(),
            "nothing grew: nothing is tried again"
        );
        assert!(g.attempts.iter().all(|a| !a.placed));
        assert!(g.attempts[3]
            .reason
            .as_deref()
            .unwrap()
            .contains("confidence 0.10"));
    }

    #[test]
    fn the_later_placed_scan_of_a_contradiction_is_withdrawn_and_tried_again_once() {
        // Whole searches only: the same patch and the larger one (44 % of it on the seed)
        // are placed, the line is not.
        let whole = PlacementRules {
            quick_first: false,
            ..rules(1)
        };
        let mut g = Growth::new(prepared(), 0, whole);
        for _ in 0..3 {
            let job = g.next_jobs().remove(0);
            g.record(&job, outcome(true, 0.9));
        }
        let placed: Vec<usize> = g
            .attempts
            .iter()
            .filter(|a| a.placed)
            .map(|a| a.scan)
            .collect();
        assert_eq!(placed.len(), 2, "{:?}", g.attempts);
        let (first, second) = (placed[0], placed[1]);
        // The anchor (0) was placed first, then `first`, then `second`.
        assert_eq!(
            g.later_placed(&[(0, second), (second, first)]),
            vec![second]
        );
        let mut both = vec![first, second];
        both.sort_unstable();
        assert_eq!(g.later_placed(&[(first, 0), (second, first)]), both);
        for round in 1..=MAX_WITHDRAWALS {
            g.withdraw(second, "contradicted".into());
            assert!(g.poses[second].is_none() && g.withdrawn[second].is_some());
            let jobs = g.next_jobs();
            if round < MAX_WITHDRAWALS {
                // Tried again, onto the same model as before.
                assert_eq!(jobs[0].scan, second, "{jobs:?}");
                g.record(&jobs[0], outcome(true, 0.9));
                assert!(g.poses[second].is_some() && g.withdrawn[second].is_none());
            } else {
                assert!(jobs.iter().all(|j| j.scan != second), "{jobs:?}");
            }
        }
    }

    #[test]
    fn a_placed_scan_grows_the_model_and_reopens_the_quick_tries() {
        let mut g = Growth::new(prepared(), 0, rules(1));
        let first = g.next_jobs();
        assert_eq!((first.len(), first[0].scan), (1, 1));
        g.record(&first[0], outcome(true, 0.9));
        assert!(g.poses[1].is_some(), "{:?}", g.attempts[0].reason);
        let next = g.next_jobs();
        assert!(next[0].quick && next[0].model == vec![0, 1]);
    }
}
