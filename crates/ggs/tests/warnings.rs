//! A result that is probably off says so: a corridor, whose floor and walls leave a slide
//! along it free, is registered with a "weakly constrained" warning; a closed room with
//! furniture is not.

mod common;

use ggs::pipeline::{register, Registration, RegistrationConfig, VoxelSize};
use ggs::Cloud;

/// `n` points uniform on the parallelogram `o + a·u + b·v`, a, b ∈ [0, 1).
fn face(rng: &mut common::Lcg, o: [f64; 3], u: [f64; 3], v: [f64; 3], n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|_| {
            let (a, b) = (rng.next_f64(), rng.next_f64());
            [0, 1, 2].map(|k| o[k] + a * u[k] + b * v[k])
        })
        .collect()
}

/// A corridor 2 m wide and 2.5 m high from x = `x0` to `x0 + 12` (floor and both walls, no
/// end), sampled anew from `seed`.
fn corridor(x0: f64, seed: u64) -> Cloud {
    let mut rng = common::Lcg(seed);
    let along = [12.0, 0.0, 0.0];
    let mut p = Vec::new();
    for (o, v) in [
        ([x0, 0.0, 0.0], [0.0, 2.0, 0.0]),
        ([x0, 0.0, 0.0], [0.0, 0.0, 2.5]),
        ([x0, 2.0, 0.0], [0.0, 0.0, 2.5]),
    ] {
        p.extend(face(&mut rng, o, along, v, 6000));
    }
    Cloud::new(p)
}

/// A closed 6 × 4 × 2.5 m room with three boxes on its floor, sampled anew from `seed`.
fn room(seed: u64) -> Cloud {
    let mut rng = common::Lcg(seed);
    let r = &mut rng;
    let mut p = face(r, [0.0; 3], [6.0, 0.0, 0.0], [0.0, 4.0, 0.0], 6000);
    for (o, u) in [
        ([0.0, 0.0, 0.0], [6.0, 0.0, 0.0]),
        ([0.0, 4.0, 0.0], [6.0, 0.0, 0.0]),
        ([0.0, 0.0, 0.0], [0.0, 4.0, 0.0]),
        ([6.0, 0.0, 0.0], [0.0, 4.0, 0.0]),
    ] {
        p.extend(face(r, o, u, [0.0, 0.0, 2.5], 2500));
    }
    for (x, y, h) in [(1.0, 1.0, 0.8), (4.0, 0.5, 1.2), (2.5, 2.8, 0.5)] {
        p.extend(face(r, [x, y, h], [0.7, 0.0, 0.0], [0.0, 0.7, 0.0], 300));
        p.extend(face(r, [x, y, 0.0], [0.7, 0.0, 0.0], [0.0, 0.0, h], 300));
        p.extend(face(r, [x, y, 0.0], [0.0, 0.7, 0.0], [0.0, 0.0, h], 300));
    }
    Cloud::new(p)
}

fn run(source: &Cloud, target: &Cloud) -> Registration {
    let cfg = RegistrationConfig {
        voxel: VoxelSize::Fixed(0.1),
        threads: 2,
        ..RegistrationConfig::default()
    };
    register(source, target, &cfg).unwrap()
}

fn weakly_constrained(r: &Registration) -> bool {
    r.warnings
        .iter()
        .any(|w| w.starts_with("weakly constrained:"))
}

#[test]
fn a_corridor_warns_that_the_pose_may_slide_along_it() {
    let r = run(&corridor(0.0, 1), &corridor(3.0, 2));
    let report = &r.refine.as_ref().expect("refined").report;
    assert!(report.degenerate, "{:?}", report.information_eigenvalues);
    assert!(weakly_constrained(&r), "{:?}", r.warnings);
}

#[test]
fn a_closed_room_with_furniture_does_not() {
    let r = run(&room(3), &room(4));
    let report = &r.refine.as_ref().expect("refined").report;
    assert!(!report.degenerate, "{:?}", report.information_eigenvalues);
    assert!(!weakly_constrained(&r), "{:?}", r.warnings);
    assert!(report.converged);
}
