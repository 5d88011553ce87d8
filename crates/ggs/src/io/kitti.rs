//! KITTI velodyne scans (`.bin`): little-endian float32 records `x y z reflectance`, 16
//! bytes per point, no header.

use super::stream;
use crate::cloud::{Point, PointStore};
use crate::error::{GgsError, Result};
use std::io::Read;
use std::path::Path;

/// Bytes per point.
pub const RECORD: usize = 16;

/// Parse a KITTI `.bin` scan held in memory (reflectance dropped).
pub fn parse_kitti_bin(path: &Path, bytes: &[u8]) -> Result<Vec<Point>> {
    read_kitti_bin(path, &mut std::io::Cursor::new(bytes), bytes.len() as u64)
}

/// Read a KITTI `.bin` scan of `len` bytes from a stream, [`stream::CHUNK_BYTES`] at a
/// time (reflectance dropped).
pub fn read_kitti_bin<R: Read + Send>(path: &Path, r: &mut R, len: u64) -> Result<Vec<Point>> {
    read_kitti_into::<Vec<Point>, R>(path, r, len)
}

/// [`read_kitti_bin`] into any [`PointStore`].
pub fn read_kitti_into<S: PointStore, R: Read + Send>(
    path: &Path,
    r: &mut R,
    len: u64,
) -> Result<S::Out> {
    let rec = RECORD as u64;
    if !len.is_multiple_of(rec) {
        return Err(GgsError::at_byte(
            path,
            len - len % rec,
            format!(
                "expected 16-byte records (float32 x y z reflectance); {len} bytes leave {} over",
                len % rec
            ),
        ));
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64;
    stream::read_records::<S, R>(
        path,
        r,
        0,
        RECORD,
        len / rec,
        "the file size",
        stream::CHUNK_BYTES,
        |r| [f(&r[0..4]), f(&r[4..8]), f(&r[8..12])],
        len / rec,
    )
}

/// Write a KITTI `.bin` scan (reflectance 0) atomically; for tests and fixtures.
pub fn write_kitti_bin(path: &Path, points: &[Point]) -> Result<()> {
    let mut bytes = Vec::with_capacity(points.len() * RECORD);
    for p in points {
        for v in [p[0], p[1], p[2], 0.0] {
            bytes.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    super::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_truncation() {
        let dir = std::env::temp_dir().join(format!("ggs-kitti-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("000001.bin");
        let pts = vec![[1.5, -2.0, 0.25], [100.0, 3.0, -1.75]];
        write_kitti_bin(&p, &pts).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(parse_kitti_bin(&p, &bytes).unwrap(), pts);
        let e = parse_kitti_bin(&p, &bytes[..20]).unwrap_err().to_string();
        assert!(e.contains("byte 16") && e.contains("4 over"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// One unit test per error path.
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::Byte;

    fn short_stream(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        // The file size says 3 records, the stream holds fewer (a file cut while reading).
        read_kitti_bin(path, &mut std::io::Cursor::new(b), 48)
    }

    error_cases! { parse_kitti_bin;
        partial_record: [0u8; 40] => Byte(32), "16-byte records";
    }

    error_cases! { short_stream;
        stream_ends_early: [0u8; 20] => Byte(20), "record 1 (at byte 16) runs past the end";
    }
}
