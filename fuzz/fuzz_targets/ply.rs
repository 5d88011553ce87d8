#![no_main]
//! Fuzz the PLY readers: the streamed reader must agree with the in-memory parser, and the
//! mesh reader (faces, then surface sampling) must not fail differently on the vertices.

#[path = "common.rs"]
mod common;

use ggs::io::{ply, Format, ReadOptions};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let streamed = common::parse(Format::Ply, data, ReadOptions::default());
    let whole = ply::parse_ply(Path::new("fuzz.input"), data).ok();
    match (&streamed, &whole) {
        (Some(a), Some(b)) => assert!(common::same(a, b), "streamed and in-memory reads differ"),
        // The streamed reader stops after the vertex element: it may accept a file whose
        // later elements are broken. The other way round is a bug.
        (None, Some(_)) => panic!("the streamed reader fails where the in-memory parser reads"),
        _ => {}
    }
    if let Ok(mesh) = ply::parse_ply_mesh(Path::new("fuzz.input"), data) {
        let sampled = ReadOptions {
            mesh_samples: Some(32),
            ..Default::default()
        };
        if !mesh.triangles.is_empty() {
            common::parse(Format::Ply, data, sampled);
        }
    }
});
