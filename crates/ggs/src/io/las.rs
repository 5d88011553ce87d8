//! ASPRS LAS and LAZ (LASzip-compressed LAS) through the maintained `las` crate (pure Rust,
//! `laz` feature). Coordinates come back with each file's scale and offset applied, in f64.

use crate::cloud::Point;
use crate::error::{GgsError, Result};
use std::io::{Read, Seek};
use std::path::Path;

/// Points decoded per call into the `las` crate (bounds the memory beside the output).
const BATCH: u64 = 1 << 16;

/// Read every point of a LAS or LAZ file (the format is in the header, not the extension)
/// from a stream positioned at its first byte. Points are decoded [`BATCH`] at a time, so
/// the memory beside the output is one batch of `las::Point`s.
pub fn read_las<R: Read + Seek + Send + Sync + 'static>(path: &Path, r: R) -> Result<Vec<Point>> {
    let mut reader =
        las::Reader::new(r).map_err(|e| GgsError::in_file(path, format!("LAS header: {e}")))?;
    let header = reader.header();
    let n = header.number_of_points();
    let at = header.point_format().len() as u64;
    let mut out = Vec::with_capacity(n.min(1 << 24) as usize);
    let mut batch = Vec::with_capacity(BATCH.min(n) as usize);
    while (out.len() as u64) < n {
        batch.clear();
        let done = out.len() as u64;
        let got = reader
            .read_points_into(BATCH.min(n - done), &mut batch)
            .map_err(|e| {
                GgsError::in_file(
                    path,
                    format!("LAS points {done}.. of {n} (records of {at} bytes): {e}"),
                )
            })?;
        if got == 0 {
            break;
        }
        out.extend(batch.iter().map(|p| [p.x, p.y, p.z]));
    }
    if (out.len() as u64) < n {
        return Err(GgsError::in_file(
            path,
            format!(
                "truncated: the header announces {n} points, the file holds {}",
                out.len()
            ),
        ));
    }
    Ok(out)
}

/// Read a LAS or LAZ file held in memory.
pub fn parse_las(path: &Path, bytes: Vec<u8>) -> Result<Vec<Point>> {
    read_las(path, std::io::Cursor::new(bytes))
}

/// Write points as LAS 1.4 (point format 0), LAZ-compressed when `path` ends in `.laz`,
/// atomically. Coordinates are stored as 32-bit integers: offset = the bounding box's
/// minimum, scale = the smallest power of ten that spans the box in 2^31 steps (at least
/// 1e-9), so each coordinate is kept to half that scale.
pub fn write_las(path: &Path, points: &[Point]) -> Result<()> {
    let b = crate::cloud::bounds(points).unwrap_or(crate::cloud::Aabb {
        min: [0.0; 3],
        max: [0.0; 3],
    });
    let transform = |a: usize| las::Transform {
        scale: las_scale(b.max[a] - b.min[a]),
        offset: b.min[a],
    };
    let mut builder = las::Builder::from((1, 4));
    builder.transforms = las::Vector {
        x: transform(0),
        y: transform(1),
        z: transform(2),
    };
    builder.point_format.is_compressed = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
    let err = |e: las::Error| GgsError::in_file(path, format!("LAS writer: {e}"));
    let header = builder.into_header().map_err(err)?;
    let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).map_err(err)?;
    for p in points {
        writer
            .write_point(las::Point {
                x: p[0],
                y: p[1],
                z: p[2],
                ..Default::default()
            })
            .map_err(err)?;
    }
    let bytes = writer.into_inner().map_err(err)?.into_inner();
    super::write_atomic(path, &bytes)
}

/// The smallest power of ten, at least 1e-9, that spans `extent` in fewer than 2^31 steps.
pub fn las_scale(extent: f64) -> f64 {
    let mut k = -9;
    while extent / 10f64.powi(k) >= 2f64.powi(31) - 1.0 {
        k += 1;
    }
    10f64.powi(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn las_and_laz_round_trip_within_the_scale() {
        let dir = std::env::temp_dir().join(format!("ggs-las-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Georeferenced-style coordinates.
        let pts: Vec<Point> = (0..500)
            .map(|i| {
                let t = i as f64 * 0.37;
                [
                    512_345.678 + t.sin() * 20.0,
                    4_210_000.25 + t,
                    120.5 + t.cos(),
                ]
            })
            .collect();
        for ext in ["las", "laz"] {
            let p = dir.join(format!("c.{ext}"));
            write_las(&p, &pts).unwrap();
            let back = parse_las(&p, std::fs::read(&p).unwrap()).unwrap();
            assert_eq!(back.len(), pts.len());
            for k in 0..3 {
                let (lo, hi) = pts
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p[k]), h.max(p[k])));
                let tol = 0.5 * las_scale(hi - lo) + 1e-9;
                for (a, b) in back.iter().zip(&pts) {
                    assert!((a[k] - b[k]).abs() <= tol, "{ext}: {a:?} vs {b:?}");
                }
            }
        }
        let las_size = std::fs::metadata(dir.join("c.las")).unwrap().len();
        let laz_size = std::fs::metadata(dir.join("c.laz")).unwrap().len();
        assert!(laz_size < las_size, "{laz_size} vs {las_size}");
        let bytes = std::fs::read(dir.join("c.las")).unwrap();
        let e = parse_las(Path::new("t.las"), bytes[..bytes.len() - 30].to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.las") && e.contains("LAS"), "{e}");
        let e = parse_las(Path::new("t.las"), b"LASF".to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("LAS header"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
