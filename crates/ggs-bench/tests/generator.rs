//! The partial-view generator on the bundled SMPL body (tests/data/human_woman.obj):
//! reproducibility, the FPv1 rebuild round trip, and registration of generated pairs.

#[path = "../../ggs/tests/common/mod.rs"]
mod common;

use ggs_bench::generator::{
    self,
    presets::{Level, Preset, Varies},
    GeneratorConfig, SampleSize, ScanInput,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn body() -> PathBuf {
    common::repo_root().join("tests/data/human_woman.obj")
}

fn tmp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ggs-gen-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn config(seed: u64, threads: usize) -> GeneratorConfig {
    GeneratorConfig {
        seed,
        threads,
        sample: SampleSize::Count(20_000),
        ..GeneratorConfig::default()
    }
}

/// Every file under `dir`, by relative path, with its bytes.
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

fn generate(dir: &Path, cfg: &GeneratorConfig) -> generator::Generated {
    generator::output::prepare_out(dir, false).unwrap();
    generator::generate(&[ScanInput::new(body())], cfg, dir, |_, _, _| {}).unwrap()
}

#[test]
fn same_seed_same_bytes_on_any_thread_count() {
    let (a, b, c) = (tmp("a"), tmp("b"), tmp("c"));
    let ga = generate(&a, &config(7, 1));
    generate(&b, &config(7, 2));
    generate(&c, &config(8, 2));
    assert!(ga.pairs.len() >= 5, "{} pairs", ga.pairs.len());
    assert_eq!(ga.hull_skipped, 0);
    let (ta, tb, tc) = (tree(&a), tree(&b), tree(&c));
    assert!(ta.len() > 20);
    assert_eq!(ta.keys().collect::<Vec<_>>(), tb.keys().collect::<Vec<_>>());
    for (k, v) in &ta {
        assert!(
            v == &tb[k],
            "{} differs between 1 and 2 threads",
            k.display()
        );
    }
    // Another seed samples other points and draws other motions.
    let key = PathBuf::from("pairs.tsv");
    assert_ne!(ta[&key], tc[&key]);
    for d in [a, b, c] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

#[test]
fn views_face_their_cameras_and_pairs_respect_the_preset() {
    let cfg = config(3, 0);
    let views = generator::scan_views(&ScanInput::new(body()), &cfg).unwrap();
    assert_eq!(views.cameras.len(), 12);
    let n = views.points.len() as f64;
    let mean = |idx: &mut dyn Iterator<Item = usize>| {
        let mut s = [0.0; 3];
        let mut k = 0.0;
        for i in idx {
            let p = views.points[i];
            for a in 0..3 {
                s[a] += p[a] + views.floor_offset[a];
            }
            k += 1.0;
        }
        s.map(|v| v / k)
    };
    let all = mean(&mut (0..views.points.len()));
    for (cam, vis) in views.cameras.iter().zip(&views.visible) {
        // A view holds a real part of the body, not all of it…
        let share = vis.len() as f64 / n;
        assert!((0.1..0.7).contains(&share), "{share}");
        // …and its centroid lies towards its camera.
        let m = mean(&mut vis.iter().map(|&i| i as usize));
        let to_cam: f64 = (0..3).map(|a| (cam[a] - all[a]) * (m[a] - all[a])).sum();
        assert!(to_cam > 0.0);
    }
    let pairs = generator::scan_pairs(&views, &cfg);
    for p in &pairs {
        assert!(p.overlap >= 60.0 && p.view_i < p.view_j);
        assert!(p.euler_deg.iter().all(|a| a.abs() <= 180.0));
        assert!(p.transform.translation.iter().all(|t| t.abs() <= 0.5));
    }
    let hard = GeneratorConfig {
        preset: Preset::Fp(Varies::Overlap, Level::Hard),
        ..cfg
    };
    for p in generator::scan_pairs(&views, &hard) {
        assert!((10.0..30.0).contains(&p.overlap));
    }
}

#[test]
fn fpv1_rebuild_recomputes_the_generated_overlaps() {
    // Generate, write the pairs as a published-style FPv1 CSV, rebuild from it: the
    // recomputed overlaps and the manifest must match the generated ones exactly.
    let (a, b) = (tmp("fpv1-a"), tmp("fpv1-b"));
    let g = generate(&a, &config(11, 2));
    let cams: BTreeMap<u32, String> = std::fs::read_to_string(a.join("views.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[1].parse().unwrap(),
                format!("[{} {} {}]", f[2], f[3], f[4]),
            )
        })
        .collect();
    let mut csv = String::from("Scan,Viewpoint_i,Viewpoint_j,overlap,T00,T01,T02,T03,T10,T11,T12,T13,T20,T21,T22,T23,T30,T31,T32,T33\n");
    for p in &g.pairs {
        let t: Vec<String> = p
            .transform
            .to_rows()
            .concat()
            .iter()
            .map(|v| v.to_string())
            .collect();
        csv.push_str(&format!(
            "human_woman,viewpoint{}-{},viewpoint{}-{},{},{}\n",
            p.view_i,
            cams[&p.view_i],
            p.view_j,
            cams[&p.view_j],
            p.overlap,
            t.join(",")
        ));
    }
    csv.push_str(
        &csv.lines()
            .nth(1)
            .unwrap()
            .replace("human_woman", "tr_scan_099"),
    );
    csv.push('\n');
    let csv_path = a.join("published.csv");
    std::fs::write(&csv_path, csv).unwrap();
    generator::output::prepare_out(&b, false).unwrap();
    let r = generator::fpv1::rebuild(&csv_path, &a.join("scans"), &config(0, 2), &b, |_, _, _| {})
        .unwrap();
    assert_eq!(r.missing_scans, vec!["tr_scan_099".to_string()]);
    assert_eq!(r.checks.len(), g.pairs.len());
    for c in &r.checks {
        assert_eq!(c.recomputed, c.published, "{}", c.pair);
    }
    let manifest = |d: &Path| -> Vec<String> {
        std::fs::read_to_string(d.join("pairs.tsv"))
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(String::from)
            .collect()
    };
    assert_eq!(manifest(&a), manifest(&b));
    for p in &g.pairs {
        let f = format!("pairs/{}.ply", p.name);
        assert_eq!(
            std::fs::read(a.join(&f)).unwrap(),
            std::fs::read(b.join(&f)).unwrap()
        );
    }
    for d in [a, b] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

#[test]
fn generated_pairs_register() {
    // Arbitrary rotations (fpv1): the full-SO(3) hopf15-dedup grid + GICP must recover them
    // to 10° / 3 cm, as the CI benchmark scores them (scripts/partial_benchmark.sh).
    let dir = tmp("register");
    let cfg = config(5, 0);
    let g = generate(&dir, &cfg);
    let pairs: Vec<_> = ggs_bench::manifest::read_manifest(&dir.join("pairs.tsv"))
        .unwrap()
        .into_iter()
        .take(2)
        .collect();
    assert_eq!(pairs.len(), 2.min(g.pairs.len()));
    let set = ggs::rotations::RotationSet::named("hopf15-dedup").unwrap();
    for p in &pairs {
        let s = ggs::io::read_cloud(&p.source, None).unwrap().cloud;
        let t = ggs::io::read_cloud(&p.target, None).unwrap().cloud;
        let coarse = ggs::search::grid_search(
            &s,
            &t,
            &set,
            &ggs::search::SearchConfig::with_voxel(p.voxel),
        )
        .unwrap();
        let fine = ggs::refine::refine(
            &s,
            &t,
            &coarse.transform(),
            &ggs::refine::RefineConfig::default(),
        )
        .unwrap();
        let rre = ggs::metrics::rre(&fine.transform, &p.ground_truth);
        let rte = ggs::metrics::rte(&fine.transform, &p.ground_truth);
        assert!(rre < 10.0 && rte < 0.03, "{}: RRE {rre}° RTE {rte}", p.name);
    }
    std::fs::remove_dir_all(dir).unwrap();
}

/// A seeded room, 8 × 6 × 3 m: floor, four walls, and a few boxes on the floor, 5 cm apart
/// on average, written as a PLY file.
fn room(dir: &Path) -> PathBuf {
    let mut rng = common::Lcg(41);
    let mut pts = Vec::new();
    let mut face = |o: [f64; 3], u: [f64; 3], v: [f64; 3], n: usize| {
        for _ in 0..n {
            let (a, b) = (rng.next_f64(), rng.next_f64());
            pts.push([0, 1, 2].map(|k| o[k] + a * u[k] + b * v[k]));
        }
    };
    face([0.0; 3], [8.0, 0.0, 0.0], [0.0, 6.0, 0.0], 19_200);
    face([0.0; 3], [8.0, 0.0, 0.0], [0.0, 0.0, 3.0], 9_600);
    face([0.0, 6.0, 0.0], [8.0, 0.0, 0.0], [0.0, 0.0, 3.0], 9_600);
    face([0.0; 3], [0.0, 6.0, 0.0], [0.0, 0.0, 3.0], 7_200);
    face([8.0, 0.0, 0.0], [0.0, 6.0, 0.0], [0.0, 0.0, 3.0], 7_200);
    for (x, y, h) in [
        (1.0, 1.0, 0.8),
        (5.5, 1.5, 1.2),
        (3.0, 4.0, 0.5),
        (6.5, 4.5, 2.0),
    ] {
        face([x, y, h], [0.6, 0.0, 0.0], [0.0, 0.6, 0.0], 150);
        face([x, y, 0.0], [0.6, 0.0, 0.0], [0.0, 0.0, h], 200);
        face([x, y, 0.0], [0.0, 0.6, 0.0], [0.0, 0.0, h], 200);
    }
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("room.ply");
    ggs::io::write_cloud(&path, &pts, None).unwrap();
    path
}

#[test]
fn scene_crops_keep_the_band_and_the_same_bytes_on_any_thread_count() {
    let input_dir = tmp("room-in");
    let scene = ScanInput::new(room(&input_dir));
    let cfg = |threads| GeneratorConfig {
        seed: 5,
        threads,
        preset: Preset::Scene(Level::Hard),
        crops: generator::crops::CropConfig {
            share: 0.25,
            count: 16,
        },
        voxel: 0.1,
        ..GeneratorConfig::default()
    };
    let (a, b) = (tmp("room-a"), tmp("room-b"));
    let gen = |dir: &Path, threads| {
        generator::output::prepare_out(dir, false).unwrap();
        generator::generate(
            std::slice::from_ref(&scene),
            &cfg(threads),
            dir,
            |_, _, _| {},
        )
        .unwrap()
    };
    let g = gen(&a, 1);
    gen(&b, 2);
    assert!(g.pairs.len() >= 3, "{} pairs", g.pairs.len());
    assert_eq!(tree(&a), tree(&b), "1 and 2 threads wrote different files");
    // Every pair in the 3DLoMatch-like band, its overlap the share of view i's points that
    // view j holds, and its target view i moved by T.
    let views = generator::scan_views(&scene, &cfg(1)).unwrap();
    for p in &g.pairs {
        assert!((10.0..30.0).contains(&p.overlap), "{}", p.overlap);
        let slot = |id| views.view_ids.iter().position(|&v| v == id).unwrap();
        let (vi, vj) = (
            &views.visible[slot(p.view_i)],
            &views.visible[slot(p.view_j)],
        );
        let common = vi.iter().filter(|i| vj.binary_search(i).is_ok()).count();
        assert_eq!(p.overlap, common as f64 / vi.len() as f64 * 100.0);
        let target =
            ggs::io::read_exact_points(&a.join("pairs").join(format!("{}.ply", p.name)), None)
                .unwrap()
                .points;
        let first = p.transform.apply(&views.points[vi[0] as usize]);
        assert!((0..3).all(|k| (target[0][k] - first[k]).abs() < 1e-9));
    }
    for d in [a, b, input_dir] {
        std::fs::remove_dir_all(d).unwrap();
    }
}
