//! The first look on the bundled bunny scans (tests/data): a clear pair is settled by it at
//! the whole search's pose, its alternatives screened on coarser cells change nothing but
//! their own ICP, and a pair it does not settle gets the whole search's answer bit for bit.

mod common;

use ggs::io::read_cloud;
use ggs::metrics::{rre, rte};
use ggs::pipeline::{
    register, FirstLook, HypothesisLevel, Registration, RegistrationConfig, VoxelSize,
};
use ggs::Cloud;

fn bunny() -> (Cloud, Cloud) {
    let data = common::repo_root().join("tests/data");
    let read = |name: &str| read_cloud(&data.join(name), None).unwrap().cloud;
    (read("bun045.ply"), read("bun000.ply"))
}

fn config(first_look: Option<FirstLook>) -> RegistrationConfig {
    RegistrationConfig {
        voxel: VoxelSize::Fixed(0.005),
        threads: 2,
        first_look,
        ..RegistrationConfig::default()
    }
}

fn run(first_look: Option<FirstLook>) -> Registration {
    run_with(first_look, |_| {})
}

/// [`run`] with the configuration changed by `change`.
fn run_with(
    first_look: Option<FirstLook>,
    change: impl Fn(&mut RegistrationConfig),
) -> Registration {
    let (source, target) = bunny();
    let mut cfg = config(first_look);
    change(&mut cfg);
    register(&source, &target, &cfg).unwrap()
}

#[test]
fn a_clear_pair_is_settled_by_the_first_look_at_the_whole_searchs_pose() {
    let first = run(Some(FirstLook::default()));
    let look = first
        .first_look
        .expect("the default preset takes a first look");
    assert!(look.accepted, "{look:?}");
    assert!(look.score >= look.accept_score);
    let stats = &first.search.stats;
    assert_eq!(stats.scored, FirstLook::default().rotations);
    assert_eq!(stats.coarse_level.as_ref().unwrap().rounds, 0);
    let whole = run(None);
    assert!(whole.first_look.is_none());
    assert!(whole.search.stats.scored > stats.scored);
    let v = first.verification.as_ref().unwrap();
    assert_eq!(look.verified, v.hypotheses.len());
    assert!(v.hypotheses.len() < whole.verification.as_ref().unwrap().hypotheses.len());
    // The same pose to a hundredth of a degree and a fiftieth of a voxel.
    let t = &whole.transform;
    assert!(
        rre(&first.transform, t) < 0.01,
        "{}",
        rre(&first.transform, t)
    );
    assert!(
        rte(&first.transform, t) < 0.0001,
        "{}",
        rte(&first.transform, t)
    );
}

#[test]
fn screening_the_alternatives_on_coarser_cells_keeps_the_chosen_pose() {
    let screened = run(Some(FirstLook::default()));
    let unscreened = run(Some(FirstLook {
        screen_cell_voxels: 0.0,
        ..FirstLook::default()
    }));
    let (a, b) = (screened.first_look.unwrap(), unscreened.first_look.unwrap());
    assert!(a.accepted && b.accepted, "{a:?} {b:?}");
    assert_eq!((a.score, a.verified), (b.score, b.verified));
    assert_eq!(screened.transform, unscreened.transform);
    let (v, w) = (
        screened.verification.as_ref().unwrap(),
        unscreened.verification.as_ref().unwrap(),
    );
    assert_eq!(v.chosen, w.chosen);
    for (x, y) in v.hypotheses.iter().zip(&w.hypotheses) {
        // The coarse level's poses, and only they, are screened; the first look's own are
        // verified as before, bit for bit.
        assert_eq!(x.screened, x.level == HypothesisLevel::Coarse, "{x:?}");
        assert!(!y.screened);
        assert_eq!(x.rotation_index, y.rotation_index);
        if !x.screened {
            assert_eq!(
                (x.transform, x.evidence.score),
                (y.transform, y.evidence.score)
            );
        } else {
            // Ruled out: on the chosen pose, or below the reject ratio of its score.
            let bar = 0.6 * a.score;
            assert!(x.same_as.is_some() || x.evidence.score < bar, "{x:?}");
        }
    }
    assert!(v.hypotheses.iter().any(|h| h.screened));
}

/// The whole search's result, field for field where it matters, from a first look with
/// `accept_score` that does not settle the pair.
fn declined_equals_whole(accept_score: f64, whole: &Registration) -> Registration {
    let look = FirstLook {
        accept_score,
        ..FirstLook::default()
    };
    declined_with(run(Some(look)), whole)
}

/// `declined` (a first look that did not settle the pair) against `whole`.
fn declined_with(declined: Registration, whole: &Registration) -> Registration {
    let report = declined.first_look.unwrap();
    assert!(!report.accepted && report.verified >= 1, "{report:?}");
    assert_eq!(declined.transform, whole.transform);
    assert_eq!(declined.coarse_transform, whole.coarse_transform);
    assert_eq!(declined.search.hypotheses, whole.search.hypotheses);
    assert_eq!(declined.search.stats.scored, whole.search.stats.scored);
    let (a, b) = (
        declined.verification.as_ref().unwrap(),
        whole.verification.as_ref().unwrap(),
    );
    assert_eq!(a.chosen, b.chosen);
    assert_eq!(a.hypotheses.len(), b.hypotheses.len());
    for (x, y) in a.hypotheses.iter().zip(&b.hypotheses) {
        assert_eq!(x.transform, y.transform);
        assert_eq!(x.evidence.score, y.evidence.score);
        assert_eq!(x.iterations, y.iterations);
        assert!(!x.screened);
    }
    declined
}

#[test]
fn alternatives_screened_then_declined_leave_the_whole_search_bit_for_bit() {
    // A reject ratio of 0.05 makes any screened pose that scores 5 % of the chosen one's a
    // rival: the first look screens the coarse level's poses, then declines.
    let strict = |cfg: &mut RegistrationConfig| {
        if let Some(v) = cfg.verify.as_mut() {
            v.reject_ratio = 0.05;
        }
    };
    let whole = run_with(None, strict);
    let declined = run_with(Some(FirstLook::default()), strict);
    let report = declined.first_look.unwrap();
    // Its own pose reached the gate, so the coarse level's were screened (more than the
    // pair's two own poses verified) and one of them is the rival.
    assert!(report.score >= report.accept_score, "{report:?}");
    assert!(report.runner_up_score.is_some(), "{report:?}");
    assert!(
        report.verified > 2,
        "the alternatives were screened: {report:?}"
    );
    declined_with(declined, &whole);
}

#[test]
fn a_pair_the_first_look_does_not_settle_gets_the_whole_search_bit_for_bit() {
    let whole = run(None);
    // No pose scores above 1: the first look drops every hypothesis at its check.
    declined_equals_whole(1.5, &whole);
    // Just above the right pose's score: the first hypothesis passes its check and runs to
    // the end, and the whole verification takes that decision from the first look.
    let v = whole.verification.as_ref().unwrap();
    let best = v.hypotheses[v.chosen].evidence.score;
    let declined = declined_equals_whole(best + 1e-3, &whole);
    let report = declined.first_look.unwrap();
    assert!(
        (report.score - best).abs() < 1e-2,
        "{report:?} against {best}"
    );
}
