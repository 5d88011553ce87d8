//! The default pipeline on the real pairs of `shared/data/pairs.tsv`: as they are at the
//! pair's voxel, as they are with no voxel given (the automatic rule, what a user who types
//! no flag gets), and with every source moved by a seeded random rigid motion (automatic
//! voxel): every pair but the known failures must be solved each way (10° and 3 of the
//! pair's voxels, the manifest protocol). Also: a correct hypothesis 15° off ends
//! correct (the verification's ICP schedule), and the whole pipeline is bit-identical on 1
//! and 2 threads.
//!
//! Prints, per pair, whether it was solved, the chosen hypothesis's rank, the confidence and
//! the rank of the right pose among the verified hypotheses (`cargo test --release -p ggs
//! --test pipeline -- --nocapture`).

#[path = "../../ggs/tests/common/mod.rs"]
mod common;

use ggs::io::read_cloud;
use ggs::metrics::{is_success, rre, rte};
use ggs::pipeline::{point_spacing, register, verify, Registration, RegistrationConfig, VoxelSize};
use ggs::refine::{refine, PreparedPair, RefineConfig};
use ggs::transform::Rigid;
use ggs::Cloud;
use ggs_bench::benchmark::motion::random_motion;
use ggs_bench::manifest::read_manifest;
use nalgebra::{Rotation3, Vector3};

/// The two ≈ 20 %-overlap pairs (see docs/pipeline.md).
const LOW_OVERLAP: &[&str] = &["bunny_ear_back_bun270", "bunny_top2_bun045"];

/// The pair the defaults do not solve, at the pair's voxel and at the automatic one: its
/// right pose is among no verified hypotheses. ear_back is solved each way, narrowly
/// (confidence 0.007 at its manifest voxel, 0.12 at the automatic one: docs/pipeline.md).
const UNSOLVED: &[&str] = &["bunny_top2_bun045"];

fn config(voxel: f64, threads: usize) -> RegistrationConfig {
    config_with(VoxelSize::Fixed(voxel), threads)
}

fn config_with(voxel: VoxelSize, threads: usize) -> RegistrationConfig {
    RegistrationConfig {
        voxel,
        threads,
        ..RegistrationConfig::default()
    }
}

/// Rank (in coarse order) of the first verified hypothesis within 10° and 3 voxels.
fn right_rank(reg: &Registration, truth: &Rigid) -> Option<usize> {
    reg.verification.as_ref()?;
    ggs_bench::benchmark::right_pose_rank(reg, truth, 10.0, 3.0 * reg.voxel)
}

#[test]
fn the_defaults_solve_the_real_pairs_moved_or_not() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let pairs = read_manifest(&shared.join("data/pairs.tsv")).unwrap();
    let mut failures = Vec::new();
    eprintln!("| pair | moved | voxel | solved | RRE ° | RTE / voxel | chosen rank | right pose's rank | verified | confidence | ambiguous |");
    eprintln!("|---|---|---|---|---|---|---|---|---|---|---|");
    for pair in &pairs {
        let source = read_cloud(&pair.source, None).unwrap().cloud;
        let target = read_cloud(&pair.target, None).unwrap().cloud;
        for (moved, auto) in [(false, false), (false, true), (true, true)] {
            let (src, truth) = if moved {
                let m = random_motion(1, &pair.name, &source);
                (
                    source.transformed(&m),
                    pair.ground_truth.compose(&m.inverse()),
                )
            } else {
                (source.clone(), pair.ground_truth)
            };
            let voxel = if auto {
                VoxelSize::AUTO
            } else {
                VoxelSize::Fixed(pair.voxel)
            };
            let reg = register(&src, &target, &config_with(voxel, 0)).unwrap();
            let (e_r, e_t) = (rre(&reg.transform, &truth), rte(&reg.transform, &truth));
            let solved = is_success(e_r, e_t, 10.0, 3.0 * pair.voxel);
            let verified = reg.verification.as_ref().map_or(0, |v| v.hypotheses.len());
            eprintln!(
                "| {} | {moved} | {} | {solved} | {e_r:.2} | {:.2} | {} | {} | {verified} | {:.3} | {} |",
                pair.name,
                reg.voxel,
                e_t / pair.voxel,
                reg.chosen_rank,
                right_rank(&reg, &truth).map_or("absent".into(), |r| r.to_string()),
                reg.confidence,
                reg.ambiguous
            );
            let expected = !UNSOLVED.contains(&pair.name.as_str());
            if solved != expected {
                failures.push(format!(
                    "{} (moved: {moved}, auto voxel: {auto}): solved {solved}, RRE {e_r:.2}°",
                    pair.name
                ));
            }
            // A wrong answer on these pairs is flagged, not silent.
            if !solved && !reg.ambiguous && reg.confidence > 0.2 {
                failures.push(format!(
                    "{}: wrong with confidence {:.3}, not flagged",
                    pair.name, reg.confidence
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The right pose turned by 15° and by 25° about random axes through the source's centroid: the
/// verification's ICP (thinned clouds, the correspondence distance taken anew after the
/// check) and the final GICP bring it to the minimum that GICP reaches from the ground truth
/// itself (within 0.5° and a quarter of a voxel: the GICP minima of these pairs are that flat;
/// measured 0.002–0.32°) on every pair the defaults solve. (GICP alone from the same starts
/// ends 1–24° off on 4 of these 22 starts at 15°, 6 at 25°: docs/pipeline.md.)
#[test]
fn a_correct_hypothesis_15_degrees_off_ends_correct() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let pairs = read_manifest(&shared.join("data/pairs.tsv")).unwrap();
    let vcfg = verify::VerifyConfig::default();
    let mut failures = Vec::new();
    let mut rng = common::Lcg(15);
    for pair in pairs
        .iter()
        .filter(|p| !LOW_OVERLAP.contains(&p.name.as_str()))
    {
        let source = read_cloud(&pair.source, None).unwrap().cloud;
        let target = read_cloud(&pair.target, None).unwrap().cloud;
        let icp = RefineConfig::default();
        let spacing = point_spacing(&target);
        let verifier = verify::Verifier::new(&source, &target, pair.voxel, spacing, &vcfg);
        let cell = vcfg.cell_voxels * pair.voxel;
        let thinned =
            PreparedPair::thinned(&source, &target, cell, icp.neighbors, icp.epsilon).unwrap();
        let c = Vector3::from(source.centroid().unwrap());
        let gt = pair.ground_truth;
        let from_truth = refine(&source, &target, &gt, &RefineConfig::default())
            .unwrap()
            .transform;
        for degrees in [15.0f64, 25.0] {
            let axis = Vector3::new(
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
            );
            let turn = Rotation3::new(axis.normalize() * degrees.to_radians()).into_inner();
            // Turn about the source centroid's image, so the centroid stays where GT puts it.
            let pc = gt.rotation * c + gt.translation;
            let r = turn * gt.rotation;
            let start = Rigid::new(r, pc - r * c);
            let checked = verify::check(
                &thinned,
                &verifier,
                &start,
                &RefineConfig::default(),
                &vcfg,
                0.0,
                &|_| None,
            )
            .unwrap();
            let end = refine(
                &source,
                &target,
                &checked.transform,
                &RefineConfig::default(),
            )
            .unwrap();
            let (e_r, e_t) = (
                rre(&end.transform, &from_truth),
                rte(&end.transform, &from_truth),
            );
            if !(e_r < 0.5 && e_t < 0.25 * pair.voxel) {
                failures.push(format!(
                    "{} from {degrees}° off: ended {e_r:.3}° and {:.3} voxels from GICP's minimum near the truth",
                    pair.name,
                    e_t / pair.voxel
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_pipeline_is_bit_identical_on_1_and_2_threads() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let dir = shared.join("data/stanford_bunny");
    let source: Cloud = read_cloud(&dir.join("chin.ply"), None).unwrap().cloud;
    let target: Cloud = read_cloud(&dir.join("bun000.ply"), None).unwrap().cloud;
    let run = |threads| {
        let mut cfg = config(0.005, threads);
        let v = cfg.verify.as_mut().unwrap();
        v.margin = 0.0;
        v.max_hypotheses = 8;
        register(&source, &target, &cfg).unwrap()
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.transform, b.transform);
    let (va, vb) = (a.verification.unwrap(), b.verification.unwrap());
    // 8 from the voxel size, then the coarse level's poses none of those has.
    let voxel_level = |v: &ggs::pipeline::Verification| {
        v.hypotheses
            .iter()
            .filter(|h| h.level == ggs::pipeline::HypothesisLevel::Voxel)
            .count()
    };
    assert_eq!(voxel_level(&va), 8);
    assert!(
        va.hypotheses.len() > 8,
        "no coarse-level hypothesis verified"
    );
    assert_eq!(va.hypotheses.len(), vb.hypotheses.len());
    assert_eq!(va.chosen, vb.chosen);
    for (ha, hb) in va.hypotheses.iter().zip(&vb.hypotheses) {
        assert_eq!(ha.level, hb.level);
        assert_eq!(ha.settled, hb.settled);
        assert_eq!(ha.same_as, hb.same_as);
        assert_eq!(ha.transform, hb.transform);
        assert_eq!(ha.evidence, hb.evidence);
        assert_eq!(ha.iterations, hb.iterations);
    }
}

/// The bundled PCL pair in georeferenced coordinates (UTM-like: 500 km east, 4000 km north):
/// the same rotation, the same pose relative to the clouds, the same confidence and no
/// ambiguity (near-duplicate poses once counted as distinct through their translations).
#[test]
fn georeferenced_coordinates_change_nothing() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    let o = Vector3::new(5e5, 4e6, 100.0);
    let shift = |c: &Cloud| {
        Cloud::new(
            c.iter()
                .map(|p| [p[0] + o.x, p[1] + o.y, p[2] + o.z])
                .collect(),
        )
    };
    let cfg = RegistrationConfig::default();
    let near = register(&source, &target, &cfg).unwrap();
    let far = register(&shift(&source), &shift(&target), &cfg).unwrap();
    // T_far = Tr(o)·T·Tr(−o).
    let r = near.transform.rotation;
    let expected = Rigid::new(r, near.transform.translation + o - r * o);
    assert!(rre(&far.transform, &expected) < 0.01);
    // Compared where they put the source (the translations themselves carry the rotations'
    // last bits times a 4000 km lever).
    let c = shift(&source).centroid().unwrap();
    let (a, b) = (far.transform.apply(&c), expected.apply(&c));
    let gap = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    assert!(gap < 1e-4, "{gap}");
    assert_eq!(far.ambiguous, near.ambiguous);
    assert!(!far.ambiguous);
    assert!((far.confidence - near.confidence).abs() < 0.05);
}
