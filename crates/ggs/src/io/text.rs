//! Numbers from text, fast: the shared core of the ascii readers (PLY, PCD, delimited text).
//!
//! Lines are found with `memchr` (a vectorized byte search), and each row is read in one pass
//! over its bytes: skip delimiters, parse a number where it starts with `fast-float2`, check
//! that the number ends at a delimiter. `fast-float2` parses from bytes with the algorithm the
//! standard library's `f64::from_str` adopted (Eisel–Lemire, with an exact fallback), so
//! every value is the correctly rounded one, bit for bit what `str::parse` gives; what it
//! saves is the UTF-8 check, the string splitting and the token vector around each call
//! (the bunny scans' 40 256-line ascii PLYs: about 8 ms a file before).
//!
//! The fast row readers answer `None` for anything they do not take in stride (a missing
//! value, a word that is not a number, a non-ascii byte); the readers then read that line
//! with their general code, which gives the value or the error with its line number, so a
//! file reads exactly as before, only faster.
//!
//! Bodies of more than [`CHUNK_BYTES`] are parsed in chunks on the thread pool
//! ([`parse_lines`]); each chunk starts at a line, and the values do not depend on where the
//! chunks fall or how many threads there are.

use crate::cloud::Point;
use crate::error::Result;
use rayon::prelude::*;

/// Bytes of text a chunk of [`parse_lines`] holds, about (whole lines): small enough that
/// a few megabytes of text keep two threads busy, large enough that a chunk's bookkeeping
/// is noise.
pub const CHUNK_BYTES: usize = 1 << 19;

/// A set of delimiter bytes, as a table (one lookup a byte, inlined).
pub struct Delims([bool; 256]);

impl Delims {
    /// The bytes of `list`.
    const fn of(list: &[u8]) -> Self {
        let mut t = [false; 256];
        let mut i = 0;
        while i < list.len() {
            t[list[i] as usize] = true;
            i += 1;
        }
        Delims(t)
    }

    /// Whether `b` is one of the set.
    #[inline(always)]
    pub fn has(&self, b: u8) -> bool {
        self.0[b as usize]
    }
}

/// The whitespace of `str::split_ascii_whitespace` and `u8::is_ascii_whitespace`: space,
/// tab, line feed, form feed, carriage return.
pub static ASCII_SPACE: Delims = Delims::of(b" \t\n\x0C\r");

/// The ascii bytes `char::is_whitespace` takes: [`ASCII_SPACE`] and the vertical tab.
pub static SPACE: Delims = Delims::of(b" \t\n\x0B\x0C\r");

/// Delimited text's delimiters: comma, semicolon and [`SPACE`].
pub static SPACE_COMMA_SEMICOLON: Delims = Delims::of(b" \t\n\x0B\x0C\r,;");

/// The lines of `text` as `split(b'\n')` gives them (the last one after the final line feed
/// too, empty or not), each with its position in `text` counted from 0.
pub fn lines(text: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let mut rest = Some(text);
    std::iter::from_fn(move || {
        let r = rest?;
        match memchr::memchr(b'\n', r) {
            Some(at) => {
                rest = Some(&r[at + 1..]);
                Some(&r[..at])
            }
            None => {
                rest = None;
                Some(r)
            }
        }
    })
    .enumerate()
}

/// A cursor over one line's values, separated by the bytes `delim` accepts.
pub struct Row<'a> {
    line: &'a [u8],
    at: usize,
    delim: &'static Delims,
}

impl<'a> Row<'a> {
    pub fn new(line: &'a [u8], delim: &'static Delims) -> Self {
        Row { line, at: 0, delim }
    }

    /// What is left of the line after the values read so far.
    pub fn rest(&self) -> &'a [u8] {
        &self.line[self.at..]
    }

    #[inline]
    fn skip_delims(&mut self) {
        while self.at < self.line.len() && self.delim.has(self.line[self.at]) {
            self.at += 1;
        }
    }

    /// The next value as a number: `None` at the end of the line, or when the next value is
    /// not a whole number (`1.5x`, `abc`).
    #[inline]
    pub fn number(&mut self) -> Option<f64> {
        self.skip_delims();
        let s = &self.line[self.at..];
        let (v, n) = match short_decimal(s) {
            Some(found) => found,
            None => fast_float2::parse_partial::<f64, _>(s).ok()?,
        };
        self.at += n;
        match self.line.get(self.at) {
            Some(&b) if !self.delim.has(b) => None,
            _ => Some(v),
        }
    }

    /// Step over the next value without reading it; `false` at the end of the line.
    #[inline]
    pub fn skip(&mut self) -> bool {
        self.skip_delims();
        if self.at == self.line.len() {
            return false;
        }
        while self.at < self.line.len() && !self.delim.has(self.line[self.at]) {
            self.at += 1;
        }
        true
    }
}

/// `10^k` for `k` in `0..=22`: every one exact in an `f64`.
const POWERS_OF_TEN: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The decimal digits of `s` from `*i` on, appended to `*m` (`digits` counts them): false
/// when they would make more than 15 in all.
#[inline(always)]
fn digits_into(s: &[u8], i: &mut usize, m: &mut u64, digits: &mut usize) -> bool {
    while let Some(&c @ b'0'..=b'9') = s.get(*i) {
        if *digits == 15 {
            return false;
        }
        *m = *m * 10 + u64::from(c - b'0');
        *digits += 1;
        *i += 1;
    }
    true
}

/// The number at the start of `s` and its length, when it is a short decimal: an optional
/// sign, at most 15 digits with an optional point among them, an optional exponent of at most
/// three digits, with `m · 10^e` (`m` the digits as an integer) in `|e| ≤ 22`. Such a value is
/// `m × 10^e` or `m / 10^−e` with both operands exact in an `f64` (`m < 10^15 < 2^53`), so one
/// correctly rounded operation gives the correctly rounded value (Clinger's fast path, the
/// first step of every exact parser). `None` for anything else (longer mantissas, `inf`,
/// `nan`, a dangling exponent), which the full parser takes.
#[inline]
fn short_decimal(s: &[u8]) -> Option<(f64, usize)> {
    let mut i = usize::from(matches!(s.first(), Some(b'-' | b'+')));
    let (mut m, mut digits) = (0u64, 0usize);
    if !digits_into(s, &mut i, &mut m, &mut digits) {
        return None;
    }
    let mut scale = 0i32;
    if s.get(i) == Some(&b'.') {
        i += 1;
        let before = digits;
        if !digits_into(s, &mut i, &mut m, &mut digits) {
            return None;
        }
        scale = -((digits - before) as i32);
    }
    if digits == 0 {
        return None;
    }
    if let Some(b'e' | b'E') = s.get(i) {
        i += 1;
        let negative = s.get(i) == Some(&b'-');
        i += usize::from(matches!(s.get(i), Some(b'-' | b'+')));
        let (mut x, mut n) = (0i32, 0);
        while let Some(&c @ b'0'..=b'9') = s.get(i) {
            x = x * 10 + i32::from(c - b'0');
            n += 1;
            i += 1;
            if n > 3 {
                return None;
            }
        }
        if n == 0 {
            return None;
        }
        scale += if negative { -x } else { x };
    }
    let v = match scale {
        0..=22 => m as f64 * POWERS_OF_TEN[scale as usize],
        -22..=-1 => m as f64 / POWERS_OF_TEN[(-scale) as usize],
        _ => return None,
    };
    Some((if s[0] == b'-' { -v } else { v }, i))
}

/// The values at columns `cols` (x, y, z; 0-based, any order) of a row of ascii values
/// separated by `delim`, when every column up to the last wanted one holds a value and the
/// wanted ones are numbers, and the line is ascii throughout; `None` otherwise (the caller's
/// general code then reads the line and says what is wrong).
#[inline]
pub fn xyz_columns(line: &[u8], cols: &[usize; 3], delim: &'static Delims) -> Option<Point> {
    if !line.is_ascii() {
        return None;
    }
    let mut row = Row::new(line, delim);
    let mut p = [0.0; 3];
    let last = cols[0].max(cols[1]).max(cols[2]);
    for c in 0..=last {
        if !cols.contains(&c) {
            if !row.skip() {
                return None;
            }
            continue;
        }
        let v = row.number()?;
        for d in (0..3).filter(|&d| cols[d] == c) {
            p[d] = v;
        }
    }
    Some(p)
}

/// The values at columns `cols` (x, y, z) of a line's tokens `toks` (line `line_no` of
/// `path`), parsed by `str::parse`; a missing column is an error saying `expected` (given
/// the column's index and the token count), a word that is not a number an error naming it.
pub fn token_columns(
    path: &std::path::Path,
    line_no: usize,
    toks: &[&str],
    cols: &[usize; 3],
    expected: impl Fn(usize, usize) -> String,
) -> Result<Point> {
    let mut p = [0.0; 3];
    for d in 0..3 {
        let tok = toks.get(cols[d]).ok_or_else(|| {
            crate::GgsError::at_line(path, line_no, expected(cols[d], toks.len()))
        })?;
        p[d] = tok.parse::<f64>().map_err(|_| {
            crate::GgsError::at_line(path, line_no, format!("'{tok}' is not a number"))
        })?;
    }
    Ok(p)
}

/// The points of the lines of `body`, the first of which is line `first_line` of the file
/// (1-based): `row(line_no, line)` reads one line (`Ok(None)`: a line to skip). In file
/// order; the error is the one of the earliest failing line. Bodies over [`CHUNK_BYTES`]
/// are read in chunks of whole lines on the thread pool.
pub fn parse_lines<F>(body: &[u8], first_line: usize, row: F) -> Result<Vec<Point>>
where
    F: Fn(usize, &[u8]) -> Result<Option<Point>> + Sync,
{
    let chunks = chunk_starts(body);
    // Line numbers at each chunk's start: the line feeds before it.
    let feeds: Vec<usize> = chunks
        .par_windows(2)
        .map(|w| memchr::memchr_iter(b'\n', &body[w[0]..w[1]]).count())
        .collect();
    // Each chunk writes its points into its own part of the output, one place a line
    // (zeroed memory is mapped lazily: untouched places cost nothing), then they are closed up.
    let mut out = vec![[0.0f64; 3]; feeds.iter().sum::<usize>() + 1];
    let mut parts = Vec::with_capacity(feeds.len());
    let (mut rest, mut line) = (&mut out[..], first_line);
    for (k, w) in chunks.windows(2).enumerate() {
        let last = k + 1 == feeds.len();
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(feeds[k] + usize::from(last));
        rest = tail;
        parts.push((w[0], w[1], line, part));
        line += feeds[k];
    }
    let filled: Vec<Result<usize>> = parts
        .into_par_iter()
        .map(|(start, end, line0, part)| {
            // A chunk but the last ends with its last line's line feed.
            let end = if end < body.len() { end - 1 } else { end };
            let mut n = 0;
            for (i, l) in lines(&body[start..end]) {
                if let Some(p) = row(line0 + i, l)? {
                    part[n] = p;
                    n += 1;
                }
            }
            Ok(n)
        })
        .collect();
    let mut len = 0;
    let mut at = 0;
    for (k, n) in filled.into_iter().enumerate() {
        let n = n?;
        out.copy_within(at..at + n, len);
        len += n;
        at += feeds[k] + usize::from(k + 1 == feeds.len());
    }
    out.truncate(len);
    Ok(out)
}

/// Bytes of text read from a stream at a time ([`TextChunks`]).
pub const STREAM_BYTES: usize = 4 << 20;

/// A chunk of whole lines of a text stream: its bytes (the last line's line feed included,
/// but at the end of the stream), the file offset of its first byte and the file's line
/// number (1-based) of its first line.
pub struct TextChunk<'a> {
    pub bytes: &'a [u8],
    pub offset: u64,
    pub line: usize,
}

/// A text stream read [`STREAM_BYTES`] at a time and handed out in chunks of whole lines, so
/// a large text file is parsed with a few MB beside its points (a line longer than the
/// buffer grows it).
pub struct TextChunks<R> {
    r: R,
    /// Bytes read and not yet handed out (the first `handed` of them handed out by the last
    /// chunk).
    buf: Vec<u8>,
    /// File offset and line number of `buf[0]`.
    offset: u64,
    line: usize,
    handed: usize,
    /// Bytes of the first read: the rest of the file when its size is known and small.
    first_read: usize,
    eof: bool,
}

impl<R: std::io::Read> TextChunks<R> {
    /// Chunks of `r`, whose next byte is byte `offset` of the file, on line `line`;
    /// `remaining`: the bytes left in the file, when known (a small file is then read in one
    /// allocation of its size).
    pub fn new(r: R, offset: u64, line: usize, remaining: Option<u64>) -> Self {
        let first_read = remaining.map_or(STREAM_BYTES, |n| {
            usize::try_from(n).unwrap_or(usize::MAX).min(STREAM_BYTES) + 1
        });
        TextChunks {
            r,
            buf: Vec::new(),
            offset,
            line,
            handed: 0,
            first_read,
            eof: false,
        }
    }

    /// The next chunk (`None` at the end of the stream).
    pub fn next_chunk(&mut self, path: &std::path::Path) -> Result<Option<TextChunk<'_>>> {
        // Drop what the last chunk handed out.
        let handed = std::mem::take(&mut self.handed);
        self.line += memchr::memchr_iter(b'\n', &self.buf[..handed]).count();
        self.offset += handed as u64;
        self.buf.drain(..handed);
        loop {
            let end = if self.eof {
                self.buf.len()
            } else {
                match memchr::memrchr(b'\n', &self.buf) {
                    Some(nl) if self.buf.len() >= STREAM_BYTES / 2 => nl + 1,
                    _ => {
                        self.fill(path)?;
                        continue;
                    }
                }
            };
            if end == 0 {
                return Ok(None);
            }
            self.handed = end;
            return Ok(Some(TextChunk {
                bytes: &self.buf[..end],
                offset: self.offset,
                line: self.line,
            }));
        }
    }

    /// Read up to [`STREAM_BYTES`] more (into spare capacity: nothing is zeroed first).
    fn fill(&mut self, path: &std::path::Path) -> Result<()> {
        use std::io::Read;
        let want = std::mem::replace(&mut self.first_read, STREAM_BYTES);
        let before = self.buf.len();
        self.buf.reserve(want);
        (&mut self.r)
            .take(want as u64)
            .read_to_end(&mut self.buf)
            .map_err(|e| crate::GgsError::io(path, e))?;
        self.eof = self.buf.len() - before < want;
        Ok(())
    }
}

/// Where the chunks of `body` start, and its length last: every start but the first just
/// after a line feed, about [`CHUNK_BYTES`] apart.
fn chunk_starts(body: &[u8]) -> Vec<usize> {
    let mut starts = vec![0];
    let mut at = 0;
    while body.len() - at > CHUNK_BYTES {
        match memchr::memchr(b'\n', &body[at + CHUNK_BYTES..]) {
            Some(nl) if at + CHUNK_BYTES + nl + 1 < body.len() => {
                at += CHUNK_BYTES + nl + 1;
                starts.push(at);
            }
            _ => break,
        }
    }
    starts.push(body.len());
    starts
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn lines_split_as_the_slice_split_does() {
        for text in [&b""[..], b"\n", b"a", b"a\n", b"a\nb", b"a\n\nb\n", b"\n\n"] {
            let ours: Vec<&[u8]> = lines(text).map(|(_, l)| l).collect();
            let std: Vec<&[u8]> = text.split(|&b| b == b'\n').collect();
            assert_eq!(ours, std, "{text:?}");
        }
    }

    #[test]
    fn a_row_reads_numbers_and_refuses_what_is_not_one() {
        let mut r = Row::new(b"  1.5\t-2e3 nan 4x ", &ASCII_SPACE);
        assert_eq!(r.number(), Some(1.5));
        assert_eq!(r.number(), Some(-2000.0));
        assert!(r.number().unwrap().is_nan());
        assert_eq!(r.number(), None);
        let mut r = Row::new(b"1 2", &ASCII_SPACE);
        assert!(r.skip() && r.number() == Some(2.0) && !r.skip() && r.rest().is_empty());
        assert_eq!(
            xyz_columns(b"9,3;2 1", &[3, 2, 1], &SPACE_COMMA_SEMICOLON),
            Some([1.0, 2.0, 3.0])
        );
        assert_eq!(xyz_columns(b"1 2", &[0, 1, 2], &SPACE), None);
        assert_eq!(xyz_columns("1 2 3 é".as_bytes(), &[0, 1, 2], &SPACE), None);
    }

    #[test]
    fn the_fast_path_edges_read_as_the_standard_parser_reads_them() {
        for tok in [
            "123456789012345",
            "1234567890123456",
            "999999999999999e22",
            "1e22",
            "1e23",
            "1.5e-22",
            "15e-23",
            "0.1",
            "-0",
            "-0.0",
            "+0.5",
            ".5",
            "5.",
            "-.5e1",
            "0.30000000000000004",
            "1e-400",
            "1e400",
            "000000000000001",
            "0000000000000001",
            "7e-3",
            "1E+3",
        ] {
            let ours = Row::new(tok.as_bytes(), &ASCII_SPACE).number();
            let std = tok.parse::<f64>().ok();
            assert_eq!(ours.map(f64::to_bits), std.map(f64::to_bits), "{tok}");
        }
    }

    /// Text with `n` rows of three numbers, blank lines and `\r\n` endings here and there.
    fn body(n: usize) -> (Vec<u8>, Vec<Point>) {
        let mut text = Vec::new();
        let mut want = Vec::new();
        for i in 0..n {
            let p = [i as f64 * 0.25, -(i as f64) / 3.0, 1e-3 * i as f64];
            text.extend_from_slice(format!("{} {} {}", p[0], p[1], p[2]).as_bytes());
            text.extend_from_slice(if i % 7 == 0 { b"\r\n\n" } else { b"\n" });
            want.push(p);
        }
        (text, want)
    }

    fn xyz_row(_: usize, l: &[u8]) -> Result<Option<Point>> {
        if l.iter().all(|&b| ASCII_SPACE.has(b)) {
            return Ok(None);
        }
        match xyz_columns(l, &[0, 1, 2], &ASCII_SPACE) {
            Some(p) => Ok(Some(p)),
            None => Err(crate::GgsError::at_line(
                std::path::Path::new("t"),
                0,
                "bad",
            )),
        }
    }

    #[test]
    fn chunked_reading_keeps_the_order_and_the_line_numbers() {
        let (text, want) = body(120_000);
        assert!(text.len() > 4 * CHUNK_BYTES);
        let got = parse_lines(&text, 1, xyz_row).unwrap();
        assert_eq!(got, want);
        // The earliest bad line is reported with its number, wherever the chunks fall.
        let mut bad = text.clone();
        let (a, b) = (text.len() / 2, 3 * text.len() / 4);
        let want_line = text[..a].iter().filter(|&&c| c == b'\n').count() + 1;
        bad[a] = b'x';
        bad[b] = b'y';
        let e = parse_lines(&bad, 1, |no, l| {
            xyz_row(no, l)
                .map_err(|_| crate::GgsError::at_line(std::path::Path::new("t"), no, "bad"))
        })
        .unwrap_err();
        assert_eq!(e.location(), Some(crate::error::Location::Line(want_line)));
    }

    /// A reader that hands out at most 1000 bytes a call.
    struct Trickle<'a>(&'a [u8]);
    impl std::io::Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.0.len()).min(1000);
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn text_chunks_are_whole_lines_that_make_the_stream() {
        // Lines of every length, one longer than the buffer, and no final line feed.
        let mut text = Vec::new();
        for i in 0..400_000usize {
            text.extend(std::iter::repeat_n(b'a' + (i % 26) as u8, i % 41));
            text.push(b'\n');
        }
        text.extend(std::iter::repeat_n(b'z', STREAM_BYTES + 17));
        text.extend_from_slice(b"\nlast");
        let mut chunks = TextChunks::new(Trickle(&text), 0, 1, None);
        let (mut joined, mut n) = (Vec::new(), 0);
        let path = std::path::Path::new("t");
        while let Some(c) = chunks.next_chunk(path).unwrap() {
            assert_eq!(c.offset, joined.len() as u64);
            let feeds = joined.iter().filter(|&&b| b == b'\n').count();
            assert_eq!(c.line, feeds + 1);
            assert!(c.bytes.ends_with(b"\n") || c.bytes.ends_with(b"last"));
            joined.extend_from_slice(c.bytes);
            n += 1;
        }
        assert_eq!(joined, text);
        assert!(n >= 3, "{n} chunks");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        /// A token reads as `str::parse::<f64>` reads it: the same value, bit for bit, or
        /// refused by both.
        #[test]
        fn numbers_read_as_the_standard_parser_reads_them(
            tok in "[-+]?([0-9]{0,20}(\\.[0-9]{0,20})?([eE][-+]?[0-9]{0,4})?|inf|NaN|infinity|[0-9a-f.xX_]{1,6})"
        ) {
            let ours = Row::new(tok.as_bytes(), &ASCII_SPACE).number();
            let std = tok.parse::<f64>().ok();
            match (ours, std) {
                (Some(a), Some(b)) => prop_assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "{tok}: {a} {b}"),
                (None, None) => {}
                (a, b) => prop_assert!(tok.is_empty() && a.is_none() && b.is_none(), "{tok}: {a:?} {b:?}"),
            }
        }

        /// The short decimals of scanners' files (the fast path), bit for bit as the
        /// standard parser reads them, at the edges of its range too.
        #[test]
        fn short_decimals_read_as_the_standard_parser_reads_them(
            tok in "[-+]?[0-9]{0,9}\\.?[0-9]{0,9}([eE][-+]?[0-9]{1,3})?"
        ) {
            let ours = Row::new(tok.as_bytes(), &ASCII_SPACE).number();
            let std = tok.parse::<f64>().ok();
            prop_assert_eq!(ours.map(f64::to_bits), std.map(f64::to_bits), "{}", tok);
        }
    }
}
