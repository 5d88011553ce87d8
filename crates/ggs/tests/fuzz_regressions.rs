//! Inputs that crashed a fuzz target (see fuzz/README.md), kept so that the fixes stay
//! fixed: `tests/data/fuzz/<target>/<name>` is read as the target's format, and each must
//! give an error (or points), never a panic or an abort. `<format>-edge/` folders hold
//! hand-made edge cases of the mesh readers (faces indexing past the vertices, zero-area and
//! non-finite triangles, a binary STL whose count exceeds its data), read as points and
//! sampled as meshes, as the fuzz targets do.

use ggs::io::{parse_bytes, Format, ReadOptions};
use std::path::{Path, PathBuf};

/// The format of a folder `<target>` or `<target>-<finding>`.
fn format_of(folder: &str) -> Format {
    let target = folder.split('-').next().unwrap_or(folder);
    match target {
        "text" => Format::Text,
        "stl" => Format::Stl,
        "kitti" => Format::KittiBin,
        t => Format::from_name(t).unwrap_or_else(|| panic!("unknown fuzz target folder {t}")),
    }
}

fn cases() -> Vec<(String, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/fuzz");
    let mut out = Vec::new();
    for t in std::fs::read_dir(&root).expect("tests/data/fuzz") {
        let t = t.unwrap().path();
        for f in std::fs::read_dir(&t).unwrap() {
            out.push((
                t.file_name().unwrap().to_string_lossy().to_string(),
                f.unwrap().path(),
            ));
        }
    }
    out.sort();
    out
}

#[test]
fn every_crash_input_is_a_clean_result() {
    let cases = cases();
    assert!(!cases.is_empty());
    let mut sampled_meshes = 0;
    for (target, file) in cases {
        let bytes = std::fs::read(&file).unwrap();
        let opts = ReadOptions {
            format: Some(format_of(&target)),
            mesh_samples: None,
            ..Default::default()
        };
        let r = parse_bytes(&file, &bytes, &opts);
        if let Err(e) = &r {
            assert!(e.to_string().contains(&*file.to_string_lossy()), "{e}");
        }
        // Meshes are also sampled by the fuzz targets.
        if matches!(format_of(&target), Format::Obj | Format::Stl | Format::Ply) {
            let sampled = ReadOptions {
                mesh_samples: Some(32),
                ..opts
            };
            if let Err(e) = parse_bytes(&file, &bytes, &sampled) {
                assert!(e.to_string().contains(&*file.to_string_lossy()), "{e}");
            }
            sampled_meshes += 1;
        }
    }
    // The mesh branch runs on the kept mesh inputs (it had none before the edge cases).
    assert!(sampled_meshes >= 7, "{sampled_meshes} mesh inputs sampled");
}

/// The LAS header findings (`las/`): every one is a header the `las` or `laz` crate
/// mishandles (an overflowing point-data size, an extended VLR longer than the file, a LAZ
/// chunk table larger than the file, a LASzip VLR without items); ggs refuses each with an
/// error before the crates see it. (`las-decoder/`: corrupt LAZ data that trips a debug
/// assertion of the `laz` arithmetic decoder, or a panic of the crate that ggs catches;
/// replayed above, where only "no panic escapes" holds.)
#[test]
fn las_crash_inputs_are_refused_with_located_errors() {
    let mut n = 0;
    for (target, file) in cases() {
        if target != "las" {
            continue;
        }
        let bytes = std::fs::read(&file).unwrap();
        let opts = ReadOptions {
            format: Some(Format::Las),
            ..Default::default()
        };
        let e = parse_bytes(&file, &bytes, &opts).unwrap_err();
        let s = e.to_string();
        assert!(
            s.contains("overflow any file size")
                || s.contains("extended VLR")
                || s.contains("chunk table")
                || s.contains("LASzip VLR: 0 compressed items"),
            "{s}"
        );
        assert!(matches!(e.location(), Some(ggs::Location::Byte(_))), "{s}");
        n += 1;
    }
    assert!(n >= 100, "{n} LAS inputs");
}

#[test]
fn corrupt_laz_chunk_count_is_refused_before_allocating() {
    let file =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/fuzz/las/laz-chunk-count-oom");
    let bytes = std::fs::read(&file).unwrap();
    let e = parse_bytes(
        &file,
        &bytes,
        &ReadOptions {
            format: Some(Format::Las),
            ..Default::default()
        },
    )
    .unwrap_err();
    let s = e.to_string();
    assert!(
        s.contains("chunk table") && s.contains("chunks declared"),
        "{s}"
    );
    assert!(matches!(e.location(), Some(ggs::Location::Byte(_))));
}

/// Corrupt LAZ data on which the `laz` crate panics in release builds too (an index past an
/// empty variable-size chunk table; a record decompressor without items): the panic is
/// caught at the crate boundary and reported as a parse error naming the file.
#[test]
fn laz_decoder_panics_become_errors() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/fuzz/las-decoder");
    for name in [
        "crash-096984928af19240f77ab18651abf61f28148635",
        "crash-ec7922c3577fdc648fe9795ee6d6d1bc0a77c4ce",
    ] {
        let file = dir.join(name);
        let bytes = std::fs::read(&file).unwrap();
        let opts = ReadOptions {
            format: Some(Format::Las),
            ..Default::default()
        };
        let e = parse_bytes(&file, &bytes, &opts).unwrap_err().to_string();
        assert!(
            e.contains(name) && e.contains("corrupt LAS/LAZ data"),
            "{e}"
        );
    }
}
