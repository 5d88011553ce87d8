#![no_main]
//! Fuzz the PCD readers (ascii, binary, binary_compressed/LZF): the streamed reader must
//! agree with the in-memory parser.

#[path = "common.rs"]
mod common;

use ggs::io::{pcd, Format, ReadOptions};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let streamed = common::parse(Format::Pcd, data, ReadOptions::default());
    let whole = pcd::parse_pcd(Path::new("fuzz.input"), data).ok();
    match (&streamed, &whole) {
        (Some(a), Some(b)) => assert!(common::same(a, b), "streamed and in-memory reads differ"),
        (None, None) => {}
        _ => panic!("the streamed reader and the in-memory parser disagree on success"),
    }
});
