#![no_main]
//! Fuzz the las reader.

#[path = "common.rs"]
mod common;

use ggs::io::{Format, ReadOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    common::parse(Format::Las, data, ReadOptions::default());
});
