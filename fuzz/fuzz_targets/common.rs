//! Shared by the fuzz targets: read `data` as `format` through the same entry point as
//! `ggs` itself, and check what holds for every input.

use ggs::io::{parse_bytes, Format, ReadOptions};
use std::path::Path;

/// Parse `data` as `format`; an error is a fine outcome, a panic, a hang or an abort is not.
/// Every parsed point must be three numbers (NaN allowed: the caller drops those).
pub fn parse(format: Format, data: &[u8], opts: ReadOptions) -> Option<Vec<ggs::Point>> {
    let opts = ReadOptions {
        format: Some(format),
        ..opts
    };
    match parse_bytes(Path::new("fuzz.input"), data, &opts) {
        Ok(points) => Some(points),
        Err(e) => {
            // Errors name the file.
            assert!(e.to_string().contains("fuzz.input"), "{e}");
            None
        }
    }
}

/// Points equal bit for bit (NaN included).
#[allow(dead_code)]
pub fn same(a: &[ggs::Point], b: &[ggs::Point]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(p, q)| (0..3).all(|k| p[k].to_bits() == q[k].to_bits()))
}
