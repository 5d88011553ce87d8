//! ASPRS LAS and LAZ (LASzip-compressed LAS) through the maintained `las` crate (pure Rust,
//! `laz` feature). Coordinates come back with each file's scale and offset applied, in f64.

use super::stream;
use super::stream::stream_len;
use crate::cloud::{Point, PointStore};
use crate::error::{GgsError, Result};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// Points decoded per call into the `las` crate (bounds the memory beside the output).
const BATCH: u64 = 1 << 16;

/// Read every point of a LAS or LAZ file (the format is in the header, not the extension)
/// from a stream positioned at its first byte. Points are decoded `BATCH` at a time, so
/// the memory beside the output is one batch of `las::Point`s.
pub fn read_las<R: Read + Seek + Send + Sync + 'static>(path: &Path, r: R) -> Result<Vec<Point>> {
    read_las_into::<Vec<Point>, R>(path, r)
}

/// [`read_las`] into any [`PointStore`].
pub fn read_las_into<S: PointStore, R: Read + Seek + Send + Sync + 'static>(
    path: &Path,
    mut r: R,
) -> Result<S::Out> {
    check_header(path, &mut r)?;
    check_laz_chunk_table(path, &mut r)?;
    let file_len = stream_len(&mut r).map_err(|e| GgsError::io(path, e))?;
    if let Some(points) = read_uncompressed::<S, R>(path, &mut r, file_len)? {
        return Ok(points);
    }
    // The `laz` crate (0.12) panics on some corrupt LAZ data (found by fuzzing: an index
    // past an empty chunk table, a LASzip VLR whose items it cannot use); its state is
    // dropped with the panic, so the panic is caught here and reported as a parse error.
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        read_with_crate(path, r, file_len)
    }));
    let points = decoded.unwrap_or_else(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(GgsError::in_file(
            path,
            format!("corrupt LAS/LAZ data: the las/laz decoder gave up ({why})"),
        ))
    })?;
    Ok(S::from_vec(points))
}

/// Every point through the `las` crate, [`BATCH`] at a time.
fn read_with_crate<R: Read + Seek + Send + Sync + 'static>(
    path: &Path,
    r: R,
    file_len: u64,
) -> Result<Vec<Point>> {
    let mut reader =
        las::Reader::new(r).map_err(|e| GgsError::in_file(path, format!("LAS header: {e}")))?;
    let header = reader.header();
    let n = header.number_of_points();
    let at = header.point_format().len() as u64;
    // The count comes from the header: reserve no more than one point per byte of file.
    let mut out = Vec::with_capacity(n.min(file_len) as usize);
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

/// Uncompressed LAS, decoded by ggs (about 10× faster than one `las::Point` per record):
/// the header is parsed by the `las` crate, then the records are streamed and X, Y, Z (the
/// 32-bit integers that open every point format) turned into `scale · X + offset` exactly as
/// `las::Transform::direct` does. `None` for LAZ, or a header the crate refuses (the caller
/// then reads through the crate, which reports the error). The stream is rewound first.
fn read_uncompressed<S: PointStore, R: Read + Seek + Send>(
    path: &Path,
    r: &mut R,
    file_len: u64,
) -> Result<Option<S::Out>> {
    let io = |e| GgsError::io(path, e);
    let Ok(raw) = las::raw::Header::read_from(&mut *r) else {
        r.seek(SeekFrom::Start(0)).map_err(io)?;
        return Ok(None);
    };
    r.seek(SeekFrom::Start(0)).map_err(io)?;
    let compressed = raw.point_data_record_format >> 6 != 0;
    let (start, stride) = (
        raw.offset_to_point_data as u64,
        raw.point_data_record_length as usize,
    );
    let Ok(header) = las::Header::from_raw(raw) else {
        return Ok(None);
    };
    if compressed || stride < 12 {
        return Ok(None);
    }
    let n = header.number_of_points();
    let t = *header.transforms();
    stream::skip(path, r, 0, start, "the header and VLRs before the points")?;
    let i32_at = |b: &[u8], o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let decode = |rec: &[u8]| {
        [
            t.x.direct(i32_at(rec, 0)),
            t.y.direct(i32_at(rec, 4)),
            t.z.direct(i32_at(rec, 8)),
        ]
    };
    let room = file_len.saturating_sub(start) / stride as u64;
    let what = "the LAS header's point count";
    stream::read_records::<S, R>(
        path,
        r,
        start,
        stride,
        n,
        what,
        stream::CHUNK_BYTES,
        decode,
        room,
    )
    .map(Some)
}

/// Size of an EVLR's header (before its data).
const EVLR_HEADER_BYTES: u64 = 60;

/// Refuse what the `las` crate (0.9) would not survive, before it sees the file (both found
/// by fuzzing):
/// - a point count × record length that overflows 64 bits
///   (`raw::Header::offset_to_end_of_points` multiplies without a check: a panic in debug
///   builds, a wrapped offset in release ones);
/// - an extended VLR (LAS 1.4) whose declared length runs past the end of the file
///   (`raw::Vlr::read_from` allocates the declared length first: 17 GB for a 600-byte file,
///   and the process aborts).
///
/// A header the crate cannot parse is left for it to report. The stream is rewound.
fn check_header<R: Read + Seek>(path: &Path, r: &mut R) -> Result<()> {
    let io = |e| GgsError::io(path, e);
    let file_len = stream_len(r).map_err(io)?;
    let Ok(raw) = las::raw::Header::read_from(&mut *r) else {
        r.seek(SeekFrom::Start(0)).map_err(io)?;
        return Ok(());
    };
    // As the crate counts them: the legacy field, else the LAS 1.4 64-bit one.
    let n = match (raw.number_of_point_records, raw.large_file) {
        (0, Some(lf)) => lf.number_of_point_records,
        (legacy, _) => legacy as u64,
    };
    let len = raw.point_data_record_length as u64;
    if n.checked_mul(len)
        .and_then(|b| b.checked_add(raw.offset_to_point_data as u64))
        .is_none()
    {
        r.seek(SeekFrom::Start(0)).map_err(io)?;
        return Err(GgsError::at_byte(
            path,
            0,
            format!("LAS header: {n} points of {len} bytes overflow any file size"),
        ));
    }
    let mut result = check_laszip_vlr(path, r, &raw, file_len);
    if let (Ok(()), Some(evlr)) = (&result, raw.evlr) {
        let mut at = evlr.start_of_first_evlr;
        for k in 0..evlr.number_of_evlrs {
            let mut head = [0u8; EVLR_HEADER_BYTES as usize];
            let read = r
                .seek(SeekFrom::Start(at))
                .and_then(|_| r.read_exact(&mut head));
            if read.is_err() {
                break; // the crate reports a missing EVLR itself
            }
            let data = u64::from_le_bytes(head[20..28].try_into().expect("8 bytes"));
            let end = at
                .checked_add(EVLR_HEADER_BYTES)
                .and_then(|e| e.checked_add(data));
            if end.is_none_or(|e| e > file_len) {
                result = Err(GgsError::at_byte(
                    path,
                    at + 20,
                    format!(
                        "LAS extended VLR {k} declares {data} bytes of data, but the file ends at byte {file_len}"
                    ),
                ));
                break;
            }
            at = end.unwrap_or(file_len);
        }
    }
    r.seek(SeekFrom::Start(0)).map_err(io)?;
    result
}

/// Size of a VLR's header (before its data).
const VLR_HEADER_BYTES: u64 = 54;

/// A LASzip VLR (user id `laszip encoded`, record 22204) must describe at least one item:
/// the `laz` crate (0.12) panics on an empty list (`details.rs`: "There should be at least
/// one LazItem"), found by fuzzing. The item count is the u16 at byte 32 of the VLR's data.
fn check_laszip_vlr<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    raw: &las::raw::Header,
    file_len: u64,
) -> Result<()> {
    let mut at = raw.header_size as u64;
    for _ in 0..raw.number_of_variable_length_records {
        let mut head = [0u8; VLR_HEADER_BYTES as usize];
        if r.seek(SeekFrom::Start(at))
            .and_then(|_| r.read_exact(&mut head))
            .is_err()
        {
            return Ok(()); // the crate reports a missing VLR itself
        }
        let user = &head[2..18];
        let record = u16::from_le_bytes([head[18], head[19]]);
        let len = u16::from_le_bytes([head[20], head[21]]) as u64;
        let data = at + VLR_HEADER_BYTES;
        if user.starts_with(b"laszip encoded") && record == 22204 && data + 34 <= file_len {
            let mut items = [0u8; 2];
            if r.seek(SeekFrom::Start(data + 32))
                .and_then(|_| r.read_exact(&mut items))
                .is_ok()
                && u16::from_le_bytes(items) == 0
            {
                return Err(GgsError::at_byte(
                    path,
                    data + 32,
                    "LASzip VLR: 0 compressed items (expected at least one)",
                ));
            }
        }
        at = data + len;
    }
    Ok(())
}

/// Bytes of a LAZ chunk's first point at the least (it is stored raw: point format 0 is 20
/// bytes, the others more).
const MIN_CHUNK_BYTES: u64 = 20;

/// Refuse a LAZ file whose chunk table declares more chunks than its point data can hold.
///
/// The `laz` crate (0.12) reserves memory for the declared number of chunks before reading
/// them (`ChunkTable::with_capacity`), so a corrupt count (found by fuzzing: 0xC320506D
/// chunks in a 2 kB file) asks for tens of GB and aborts the process. Every chunk starts
/// with one raw point, so `chunks ≤ (chunk table offset − point data offset) / 20`. The
/// table is located as the `laz` crate locates it; anything this check cannot read is left
/// for the crate to report. The stream is rewound to its start.
fn check_laz_chunk_table<R: Read + Seek>(path: &Path, r: &mut R) -> Result<()> {
    let io = |e| GgsError::io(path, e);
    let mut head = [0u8; 105];
    let got = super::stream::read_full(r, &mut head).map_err(io)?;
    let found = (|| -> std::io::Result<Option<(u64, u64, u64)>> {
        if got < head.len() || &head[..4] != b"LASF" || head[104] >> 6 == 0 {
            return Ok(None);
        }
        let start = u32::from_le_bytes(head[96..100].try_into().expect("4 bytes")) as u64;
        let mut b8 = [0u8; 8];
        r.seek(SeekFrom::Start(start))?;
        r.read_exact(&mut b8)?;
        let mut table = i64::from_le_bytes(b8);
        if table <= start as i64 {
            r.seek(SeekFrom::End(-8))?;
            r.read_exact(&mut b8)?;
            table = i64::from_le_bytes(b8);
            if table <= start as i64 {
                return Ok(None);
            }
        }
        r.seek(SeekFrom::Start(table as u64))?;
        r.read_exact(&mut b8)?;
        let chunks = u32::from_le_bytes(b8[4..8].try_into().expect("4 bytes")) as u64;
        Ok(Some((start, table as u64, chunks)))
    })();
    r.seek(SeekFrom::Start(0)).map_err(io)?;
    if let Ok(Some((start, table, chunks))) = found {
        let room = (table - start) / MIN_CHUNK_BYTES;
        if chunks > room {
            return Err(GgsError::at_byte(
                path,
                table + 4,
                format!(
                    "corrupt LAZ chunk table: {chunks} chunks declared, but the {} bytes of compressed points (bytes {start}..{table}) hold at most {room}",
                    table - start
                ),
            ));
        }
    }
    Ok(())
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

#[cfg(test)]
mod raw_path {
    use super::*;

    /// ggs's own decoding of uncompressed LAS gives exactly what the `las` crate gives.
    #[test]
    fn uncompressed_records_match_the_crate_bit_for_bit() {
        let dir = std::env::temp_dir().join(format!("ggs-las-raw-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("c.las");
        let pts: Vec<Point> = (0..3000)
            .map(|i| {
                let t = i as f64 * 0.731;
                [
                    651_000.123 + t.sin() * 80.0,
                    -4_000.5 + t,
                    -12.75 + t.cos() * 3.0,
                ]
            })
            .collect();
        write_las(&p, &pts).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let mut cursor = std::io::Cursor::new(bytes.clone());
        let ours = read_uncompressed::<Vec<Point>, _>(&p, &mut cursor, bytes.len() as u64)
            .unwrap()
            .expect("uncompressed LAS takes the raw path");
        let mut reader = las::Reader::new(std::io::Cursor::new(bytes)).unwrap();
        let theirs: Vec<Point> = reader
            .points()
            .map(|q| {
                let q = q.unwrap();
                [q.x, q.y, q.z]
            })
            .collect();
        assert_eq!(ours.len(), 3000);
        for (a, b) in ours.iter().zip(&theirs) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits());
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// One unit test per error path.
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::{Byte, File};

    /// A LAS (or LAZ) file of 10 points, as bytes.
    fn las_bytes(ext: &str) -> Vec<u8> {
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let k = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("ggs-las-e-{ext}-{}-{k}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(format!("c.{ext}"));
        let pts: Vec<Point> = (0..10).map(|i| [i as f64, 2.0 * i as f64, 0.5]).collect();
        write_las(&p, &pts).unwrap();
        let b = std::fs::read(&p).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        b
    }

    fn read(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        parse_las(path, b.to_vec())
    }

    /// Byte offset of a LAZ file's chunk count.
    fn chunk_count_at(b: &[u8]) -> usize {
        let start = u32::from_le_bytes(b[96..100].try_into().unwrap()) as usize;
        i64::from_le_bytes(b[start..start + 8].try_into().unwrap()) as usize + 4
    }

    error_cases! { read;
        header_garbage: b"LASF and nothing else" => File, "LAS header";
        points_cut_off: { let b = las_bytes("las"); b[..b.len() - 25].to_vec() } => Byte(550), "declares 10 records of 20 bytes; record 8 (at byte 535)";
        laz_points_cut_off: { let b = las_bytes("laz"); b[..b.len() - 40].to_vec() } => File, "LAS";
        laz_chunk_count_too_large: {
            let mut b = las_bytes("laz");
            let at = chunk_count_at(&b);
            b[at..at + 4].copy_from_slice(&0xffff_fff0u32.to_le_bytes());
            b
        } => Byte(chunk_count_at(&las_bytes("laz")) as u64), "corrupt LAZ chunk table: 4294967280 chunks declared";
        laz_data_corrupt: {
            let mut b = las_bytes("laz");
            let start = u32::from_le_bytes(b[96..100].try_into().unwrap()) as usize;
            // The chunk table offset, pointed at the file's end.
            let end = b.len() as i64;
            b[start..start + 8].copy_from_slice(&end.to_le_bytes());
            b
        } => File, "LAS";
    }
}
