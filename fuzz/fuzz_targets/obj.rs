#![no_main]
//! Fuzz the OBJ reader: vertices, and points sampled on the faces.

#[path = "common.rs"]
mod common;

use ggs::io::{Format, ReadOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if common::parse(Format::Obj, data, ReadOptions::default()).is_some() {
        let sampled = ReadOptions {
            mesh_samples: Some(32),
            ..Default::default()
        };
        common::parse(Format::Obj, data, sampled);
    }
});
