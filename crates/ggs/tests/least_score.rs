//! The whole verification's least score ([`VerifyConfig::least_score`]) on the bundled bunny
//! scans: at the chosen pose's own score it changes nothing that is chosen; above any
//! reachable score it stops every hypothesis at its check and settles none.

mod common;

use ggs::io::read_cloud;
use ggs::pipeline::{register, Registration, RegistrationConfig, VerifyConfig, VoxelSize};

/// The whole search (no first look) of bun045 onto bun000 at 5 mm, with `least_score`.
fn whole_search(least_score: f64) -> Registration {
    let data = common::repo_root().join("tests/data");
    let read = |name: &str| read_cloud(&data.join(name), None).unwrap().cloud;
    let cfg = RegistrationConfig {
        voxel: VoxelSize::Fixed(0.005),
        threads: 2,
        first_look: None,
        verify: Some(VerifyConfig {
            least_score,
            ..VerifyConfig::default()
        }),
        ..RegistrationConfig::default()
    };
    register(&read("bun045.ply"), &read("bun000.ply"), &cfg).unwrap()
}

#[test]
fn a_least_score_the_winner_reaches_keeps_the_winner() {
    let free = whole_search(0.0);
    let v = free.verification.as_ref().unwrap();
    let winner = v.hypotheses[v.chosen].evidence.score;
    let held = whole_search(winner);
    assert_eq!(held.transform, free.transform);
    let w = held.verification.as_ref().unwrap();
    assert_eq!(
        w.hypotheses[w.chosen].evidence,
        v.hypotheses[v.chosen].evidence
    );
    let stopped = |r: &Registration| {
        let v = r.verification.as_ref().unwrap();
        v.hypotheses.iter().filter(|h| h.rejected_early).count()
    };
    assert!(stopped(&held) >= stopped(&free));
}

#[test]
fn a_least_score_out_of_reach_stops_every_hypothesis_at_its_check() {
    let r = whole_search(2.0);
    let v = r.verification.as_ref().unwrap();
    let check = VerifyConfig::default().check_iterations;
    assert!(v.hypotheses.len() > 1);
    for h in &v.hypotheses {
        assert!(h.rejected_early || h.same_as.is_some(), "{h:?}");
        assert!(!h.settled && h.iterations <= check, "{h:?}");
    }
}
