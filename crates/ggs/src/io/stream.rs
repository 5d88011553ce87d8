//! Streaming helpers for large binary files: fixed-size records decoded chunk by chunk, so a
//! 50-million-point file is read with a few MB of buffer beside the output points.

use crate::cloud::{Point, PointStore};
use crate::error::{GgsError, Result};
use std::io::{BufRead, Read};
use std::path::Path;

/// Bytes read per chunk (rounded down to whole records).
pub const CHUNK_BYTES: usize = 4 << 20;

/// Read until `buf` is full or the source ends; returns the bytes read.
pub fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// Read buffers of [`read_records`] (of `CHUNK_BYTES` each).
const BUFFERS: usize = 4;

/// Records decoded per parallel task.
const TASK_RECORDS: usize = 1 << 14;

/// Decode `count` records of `stride` bytes each from `r`, whose next byte is byte `start` of
/// the file, into points. A reader thread fills buffers of `chunk_bytes` (≥ `stride`, whole
/// records) while the previous one is decoded in parallel (rayon) into a chunk of points,
/// then handed to the store `S` (a plain list, or a [`crate::cloud::Cloud`] that keeps 12
/// bytes a point), so the disk and the decoding overlap; the store reserves
/// `min(count, reserve)` points up front (`reserve`: how many records the file's size can
/// hold, so an overstated count costs nothing). The result does not depend on the thread
/// count. A source that ends early is an error at the byte where it ended, naming `what`.
#[allow(clippy::too_many_arguments)]
pub fn read_records<S: PointStore, R: Read + Send>(
    path: &Path,
    r: &mut R,
    start: u64,
    stride: usize,
    count: u64,
    what: &str,
    chunk_bytes: usize,
    decode: impl Fn(&[u8]) -> Point + Sync,
    reserve: u64,
) -> Result<S::Out> {
    use rayon::prelude::*;
    use std::sync::mpsc;
    if stride == 0 {
        return Err(GgsError::in_file(
            path,
            format!("{what}: records of 0 bytes"),
        ));
    }
    let mut out = S::with_capacity(count.min(reserve) as usize);
    let per_chunk = (chunk_bytes / stride).max(1);
    let mut points = vec![[0.0f64; 3]; (count.min(per_chunk as u64)) as usize];
    // BUFFERS buffers circulate: being filled by the reader, queued, or being decoded.
    let (full_tx, full_rx) = mpsc::sync_channel::<(Vec<u8>, std::io::Result<usize>)>(BUFFERS - 1);
    let (empty_tx, empty_rx) = mpsc::channel::<Vec<u8>>();
    for _ in 0..BUFFERS {
        let _ = empty_tx.send(vec![0u8; per_chunk * stride]);
    }
    std::thread::scope(|scope| {
        // Owned here, so that an early return (or a panic) drops them and frees the reader.
        let (empty_tx, full_rx) = (empty_tx, full_rx);
        scope.spawn(move || {
            let mut done = 0u64;
            while done < count {
                let Ok(mut buf) = empty_rx.recv() else { return };
                let want = (count - done).min(per_chunk as u64) as usize * stride;
                let got = read_full(r, &mut buf[..want]);
                let last = !matches!(got, Ok(g) if g == want);
                if full_tx.send((buf, got)).is_err() || last {
                    return;
                }
                done += (want / stride) as u64;
            }
        });
        let mut done = 0u64;
        while done < count {
            let k = (count - done).min(per_chunk as u64) as usize;
            let want = k * stride;
            let (buf, got) = full_rx
                .recv()
                .expect("the reader sends until the end or an error");
            let got = got.map_err(|e| GgsError::io(path, e))?;
            let whole = got / stride;
            points[..whole]
                .par_chunks_mut(TASK_RECORDS)
                .zip(buf[..whole * stride].par_chunks(TASK_RECORDS * stride))
                .for_each(|(o, b)| {
                    for (p, rec) in o.iter_mut().zip(b.chunks_exact(stride)) {
                        *p = decode(rec);
                    }
                });
            out.extend_from(&points[..whole]);
            if got < want {
                let at = start + (done + whole as u64) * stride as u64;
                return Err(GgsError::at_byte(
                    path,
                    start + done * stride as u64 + got as u64,
                    format!(
                        "truncated: {what} declares {count} records of {stride} bytes; record {} (at byte {at}) runs past the end of the file",
                        done + whole as u64
                    ),
                ));
            }
            let _ = empty_tx.send(buf);
            done += k as u64;
        }
        Ok(out.finish())
    })
}

/// Skip `len` bytes of `r` (at byte `start` of the file), or fail naming `what`.
/// Append the rest of `r` to `buf` (holding the file's first bytes) in one allocation when
/// the file's length is known, instead of growing it by doubling, which copies the text
/// read so far at each step (not measured to matter on the 1.4 MB bunny scans; it saves
/// those copies on large files).
pub fn read_rest<R: Read>(
    path: &Path,
    r: &mut R,
    buf: &mut Vec<u8>,
    file_len: Option<u64>,
) -> Result<()> {
    let rest = file_len.map_or(0, |n| n.saturating_sub(buf.len() as u64));
    buf.reserve(usize::try_from(rest).unwrap_or(0));
    r.read_to_end(buf).map_err(|e| GgsError::io(path, e))?;
    Ok(())
}

pub fn skip<R: Read>(path: &Path, r: &mut R, start: u64, len: u64, what: &str) -> Result<()> {
    let copied =
        std::io::copy(&mut r.take(len), &mut std::io::sink()).map_err(|e| GgsError::io(path, e))?;
    if copied < len {
        return Err(GgsError::at_byte(
            path,
            start + copied,
            format!("truncated: {what} needs {len} bytes, the file ends after {copied}"),
        ));
    }
    Ok(())
}

/// Read header lines up to and including the first line for which `is_last(trimmed line)`
/// holds; returns the header bytes. At most `max_bytes`: a file without that line, or a
/// binary file read as a header, fails there instead of filling memory.
pub fn read_header<R: BufRead>(
    path: &Path,
    r: &mut R,
    max_bytes: usize,
    what_ends_it: &str,
    is_last: impl Fn(&str) -> bool,
) -> Result<Vec<u8>> {
    let mut header = Vec::new();
    let mut line_no = 0usize;
    loop {
        let before = header.len();
        let n = r
            .take((max_bytes - before) as u64 + 1)
            .read_until(b'\n', &mut header)
            .map_err(|e| GgsError::io(path, e))?;
        line_no += 1;
        if n == 0 {
            return Err(GgsError::at_line(
                path,
                line_no,
                format!("the file ends before the header's {what_ends_it} line"),
            ));
        }
        if header.len() > max_bytes {
            return Err(GgsError::at_byte(
                path,
                max_bytes as u64,
                format!("no {what_ends_it} line in the first {max_bytes} bytes: not a header"),
            ));
        }
        let line = String::from_utf8_lossy(&header[before..]);
        if header.last() == Some(&b'\n') && is_last(line.trim()) {
            return Ok(header);
        }
        if header.last() != Some(&b'\n') {
            return Err(GgsError::at_line(
                path,
                line_no,
                format!("the file ends before the header's {what_ends_it} line"),
            ));
        }
    }
}

/// The length of a stream, which is left at its start (LAS and E57 read by seeking).
#[cfg(any(feature = "las", feature = "e57"))]
pub(crate) fn stream_len<R: std::io::Seek>(r: &mut R) -> std::io::Result<u64> {
    let len = r.seek(std::io::SeekFrom::End(0))?;
    r.seek(std::io::SeekFrom::Start(0))?;
    Ok(len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn decode(b: &[u8]) -> Point {
        [b[0] as f64, b[1] as f64, b[2] as f64]
    }

    #[test]
    fn records_across_chunk_boundaries() {
        let bytes: Vec<u8> = (0..30u8).collect();
        for chunk in [1, 3, 4, 7, 100] {
            // A reserve below the count (the output grows) and above it.
            for reserve in [2, 10, 1000] {
                let out = read_records::<Vec<Point>, _>(
                    Path::new("f"),
                    &mut Cursor::new(&bytes),
                    0,
                    3,
                    10,
                    "x",
                    chunk,
                    decode,
                    reserve,
                )
                .unwrap();
                assert_eq!(out.len(), 10, "chunk {chunk}");
                assert_eq!(out[9], [27.0, 28.0, 29.0]);
                assert_eq!(out[4], [12.0, 13.0, 14.0]);
            }
        }
    }

    #[test]
    fn truncated_records_name_the_byte() {
        let bytes = vec![0u8; 10];
        let e = read_records::<Vec<Point>, _>(
            Path::new("f.bin"),
            &mut Cursor::new(&bytes),
            100,
            4,
            3,
            "element 'vertex'",
            8,
            decode,
            3,
        )
        .unwrap_err();
        assert_eq!(e.location(), Some(crate::error::Location::Byte(110)));
        let s = e.to_string();
        assert!(
            s.contains("f.bin") && s.contains("record 2") && s.contains("vertex"),
            "{s}"
        );
    }

    #[test]
    fn skip_and_header_errors() {
        let e = skip(
            Path::new("f"),
            &mut Cursor::new(vec![0u8; 5]),
            7,
            9,
            "element 'camera'",
        )
        .unwrap_err();
        assert_eq!(e.location(), Some(crate::error::Location::Byte(12)));
        let h = read_header(
            Path::new("f"),
            &mut Cursor::new(b"a\nb\nend\nrest"),
            100,
            "'end'",
            |l| l == "end",
        )
        .unwrap();
        assert_eq!(h, b"a\nb\nend\n");
        let e = read_header(
            Path::new("f"),
            &mut Cursor::new(b"a\nb\n"),
            100,
            "'end'",
            |l| l == "end",
        )
        .unwrap_err();
        assert_eq!(e.location(), Some(crate::error::Location::Line(3)));
        let e = read_header(
            Path::new("f"),
            &mut Cursor::new(vec![b'x'; 1000]),
            64,
            "'end'",
            |l| l == "end",
        )
        .unwrap_err();
        assert_eq!(e.location(), Some(crate::error::Location::Byte(64)));
    }
}
