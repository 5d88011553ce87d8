//! Every real file of ../shared/data reads (all its formats).

mod common;

use ggs::io::{mesh::parse_obj, read_cloud};

#[test]
fn every_real_file_reads() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let data = shared.join("data");
    let mut read = 0;
    let mut stack = vec![data.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
            // The .txt files are notes and matrices, gt.npy a 4×4 pose, carCloudList.csv a
            // list of file names (its error is checked below): not clouds.
            if ["ply", "pcd", "csv", "npy", "obj", "xyz", "stl", "bin"].contains(&ext)
                && !p.ends_with("carCloudList.csv")
                && !p.ends_with("gt.npy")
            {
                let c = read_cloud(&p, None).unwrap_or_else(|e| panic!("{e}"));
                assert!(c.cloud.len() > 100, "{}", p.display());
                read += 1;
            }
        }
    }
    assert!(read >= 20, "{read} files");
    let list = data.join("libpointmatcher_car/carCloudList.csv");
    let e = read_cloud(&list, None).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("is not a number"), "{e}");
    // The meshes: vertex counts from their PROVENANCE.txt.
    let m = data.join("human_meshes");
    for (f, n) in [
        ("human_man.obj", 6890),
        ("human_woman.obj", 6890),
        ("demosthenes-low-res.obj", 8394),
        ("nefertiti-lowres.obj", 35002),
        ("base.obj", 19158),
    ] {
        assert_eq!(read_cloud(&m.join(f), None).unwrap().cloud.len(), n, "{f}");
    }
    let base = m.join("base.obj");
    let mesh = parse_obj(&base, &std::fs::read(&base).unwrap()).unwrap();
    let body = mesh.group("body").unwrap();
    assert!(body.vertices.len() > 10_000 && body.vertices.len() < 19_158);
    assert!(body.triangles.len() > 20_000, "{}", body.triangles.len());
}

/// Real clouds written in every writable format read back as they were (exactly, or within
/// the format's precision: float32 for KITTI, the LAS scale), and the streamed PLY/PCD
/// readers agree with the in-memory parsers on the real files.
#[test]
fn real_clouds_round_trip_through_every_writable_format() {
    use ggs::io::{pcd, ply, write_cloud};
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let data = shared.join("data");
    let dir = std::env::temp_dir().join(format!("ggs-real-rt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for rel in [
        "stanford_bunny/bun045.ply",
        "lidar_koide_gicp_pair/251370668.pcd",
        "3dmatch_geotransformer_demo/src.npy",
        "libpointmatcher_car/car_cloud400.csv",
        "pcl_test/bun0.pcd",
    ] {
        let path = data.join(rel);
        let pts = ggs::io::read_exact_points(&path, None).unwrap().points;
        let bytes = std::fs::read(&path).unwrap();
        if rel.ends_with(".ply") {
            assert_eq!(ply::parse_ply(&path, &bytes).unwrap(), pts, "{rel}");
        }
        if rel.ends_with(".pcd") {
            assert_eq!(pcd::parse_pcd(&path, &bytes).unwrap(), pts, "{rel}");
        }
        let b = ggs::cloud::bounds(&pts).unwrap();
        for ext in [
            "ply", "pcd", "xyz", "csv", "pts", "npy", "e57", "bin", "las", "laz",
        ] {
            let out = dir.join(format!("c.{ext}"));
            write_cloud(&out, &pts, None).unwrap();
            let back = ggs::io::read_exact_points(&out, None).unwrap().points;
            assert_eq!(back.len(), pts.len(), "{rel} as {ext}");
            for (p, q) in back.iter().zip(&pts) {
                for k in 0..3 {
                    let tol = match ext {
                        "bin" => q[k].abs() * f32::EPSILON as f64,
                        // Half the scale, plus the rounding of (x − offset) / scale in f64.
                        "las" | "laz" => {
                            0.5 * ggs::io::las::las_scale(b.max[k] - b.min[k])
                                + 8.0 * f64::EPSILON * (q[k].abs() + b.min[k].abs() + 1.0)
                        }
                        _ => 0.0,
                    };
                    assert!((p[k] - q[k]).abs() <= tol, "{rel} as {ext}: {p:?} vs {q:?}");
                }
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
