#![no_main]
//! Fuzz the E57 reader: all scans with poses, and the first scan in its own frame.

#[path = "common.rs"]
mod common;

use ggs::io::e57::E57Options;
use ggs::io::{Format, ReadOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    common::parse(Format::E57, data, ReadOptions::default());
    let first = ReadOptions {
        e57: E57Options {
            scan: Some(0),
            apply_pose: false,
        },
        ..Default::default()
    };
    common::parse(Format::E57, data, first);
});
