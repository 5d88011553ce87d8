//! Generated rotation sets equal the reference `.npy` files row for row.

mod common;

use ggs::io::npy::read_npy;
use ggs::rotations::{dedup, hopf, RotationSet};

fn compare(name: &str, file: &str) {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let reference = read_npy(&shared.join("reference/rotations").join(file)).unwrap();
    let set = RotationSet::named(name).unwrap();
    assert_eq!(reference.shape, vec![set.len(), 3, 3], "{name}: row count");
    let mut worst = 0.0f64;
    for (i, (m, r)) in set
        .matrices
        .iter()
        .zip(reference.data.chunks_exact(9))
        .enumerate()
    {
        for row in 0..3 {
            for col in 0..3 {
                let d = (m[(row, col)] - r[row * 3 + col]).abs();
                worst = worst.max(d);
                assert!(
                    d <= 1e-12,
                    "{name} row {i} entry ({row},{col}) differs by {d:e}"
                );
            }
        }
    }
    eprintln!("{name}: {} rows equal {file} to {worst:.1e}", set.len());
}

#[test]
fn limited15_equals_reference() {
    compare("limited15", "R_limited_15_15_15_removed_duplicates.npy");
}

#[test]
fn full15_equals_reference() {
    compare("full15", "R_15_15_15_removed_duplicates.npy");
}

#[test]
fn hopf15_equals_reference() {
    compare("hopf15", "R_Hopf_15_15_15.npy");
}

#[test]
fn set_sizes() {
    // limited10: 19·18·19 = 6498 grid rotations, 6173 distinct (the authors' file has 6177,
    // 4 of them float-noise duplicates at gimbal lock).
    assert_eq!(RotationSet::named("limited10").unwrap().len(), 6173);
    assert_eq!(RotationSet::named("ico162-s10").unwrap().len(), 2836);
    let hd = RotationSet::named("hopf15-dedup").unwrap();
    assert_eq!(hd.len(), 6360);
    // Deduplicating the reference sets cleanly leaves the truly distinct rotations.
    let l15 = RotationSet::named("limited15").unwrap();
    assert_eq!(dedup::dedup_geodesic(&l15.matrices, 1e-6).len(), 1883);
    let f15 = RotationSet::named("full15").unwrap();
    assert_eq!(dedup::dedup_geodesic(&f15.matrices, 1e-6).len(), 6360);
    assert_eq!(hopf::hopf_grid(15.0).len(), 6912);
}

#[test]
fn npy_rotation_file_round_trip() {
    let dir = std::env::temp_dir().join(format!("ggs-rot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let set = RotationSet::named("ico162-s10").unwrap();
    let data: Vec<f64> = set
        .matrices
        .iter()
        .flat_map(|m| (0..3).flat_map(move |r| (0..3).map(move |c| m[(r, c)])))
        .collect();
    let p = dir.join("ico.npy");
    ggs::io::npy::write_npy_3d(&p, set.len(), &data).unwrap();
    let back = ggs::io::npy::read_rotation_set(&p).unwrap();
    assert_eq!(back.matrices, set.matrices);
    assert!((back.step_deg - 10.0).abs() < 1e-9, "{}", back.step_deg);
    // A non-rotation is rejected with its row number.
    let mut bad = data.clone();
    bad[9 * 5] = 2.0;
    ggs::io::npy::write_npy_3d(&p, set.len(), &bad).unwrap();
    let e = ggs::io::npy::read_rotation_set(&p).unwrap_err().to_string();
    assert!(e.contains("row 5"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
