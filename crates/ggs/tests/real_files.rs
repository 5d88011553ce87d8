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
