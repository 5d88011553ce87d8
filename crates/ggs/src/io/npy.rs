//! NumPy `.npy` arrays (format versions 1.0, 2.0 and 3.0), numeric dtypes only.

use crate::error::{GgsError, Result};
use std::path::Path;

/// A numeric array converted to f64, in C (row-major) order.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<usize>,
    pub data: Vec<f64>,
}

/// Read a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray> {
    let bytes = std::fs::read(path).map_err(|e| GgsError::io(path, e))?;
    parse_npy(path, &bytes)
}

/// Parse the bytes of a `.npy` file; `path` is used in error messages only.
pub fn parse_npy(path: &Path, bytes: &[u8]) -> Result<NpyArray> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(GgsError::at_byte(
            path,
            0,
            "not a .npy file (magic \\x93NUMPY missing)",
        ));
    }
    let major = bytes[6];
    let (header_len, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(GgsError::at_byte(path, 8, "truncated header length"));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12usize,
            )
        }
        v => {
            return Err(GgsError::at_byte(
                path,
                6,
                format!("unsupported .npy format version {v}"),
            ))
        }
    };
    let end = start
        .checked_add(header_len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| GgsError::at_byte(path, start as u64, "truncated header"))?;
    let header = std::str::from_utf8(&bytes[start..end])
        .map_err(|_| GgsError::at_byte(path, start as u64, "header is not text"))?;
    let descr = dict_value(header, "descr")
        .ok_or_else(|| GgsError::at_byte(path, start as u64, "header has no 'descr'"))?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    let fortran = dict_value(header, "fortran_order")
        .map(|v| v.trim().starts_with("True"))
        .unwrap_or(false);
    let shape_text = dict_value(header, "shape")
        .ok_or_else(|| GgsError::at_byte(path, start as u64, "header has no 'shape'"))?;
    let shape = parse_shape(shape_text).ok_or_else(|| {
        GgsError::at_byte(path, start as u64, format!("bad shape {shape_text:?}"))
    })?;
    let (little, kind, size) = parse_descr(descr).ok_or_else(|| {
        GgsError::at_byte(
            path,
            start as u64,
            format!("unsupported dtype '{descr}' (expected a float or integer type)"),
        )
    })?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &b| a.checked_mul(b))
        .ok_or_else(|| GgsError::at_byte(path, start as u64, "shape too large"))?;
    let need = count
        .checked_mul(size)
        .ok_or_else(|| GgsError::at_byte(path, start as u64, "shape too large"))?;
    let body = &bytes[end..];
    if body.len() < need {
        return Err(GgsError::at_byte(
            path,
            (end + body.len()) as u64,
            format!(
                "truncated data: shape {shape:?} needs {need} bytes, found {}",
                body.len()
            ),
        ));
    }
    let mut data = Vec::with_capacity(count);
    for chunk in body[..need].chunks_exact(size) {
        data.push(decode(chunk, little, kind));
    }
    if fortran && shape.len() > 1 {
        data = fortran_to_c(&data, &shape);
    }
    Ok(NpyArray { shape, data })
}

/// The points of an array of shape [N, 3] (or [N, k≥3]: the first three columns).
pub fn points_of(path: &Path, a: &NpyArray) -> Result<Vec<crate::cloud::Point>> {
    if a.shape.len() != 2 || a.shape[1] < 3 {
        return Err(GgsError::in_file(
            path,
            format!(
                "expected an array of shape [N, 3] or [N, k≥3], found {:?}",
                a.shape
            ),
        ));
    }
    Ok(a.data
        .chunks_exact(a.shape[1])
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

/// Write a 2-D float64 array (C order, little endian, format 1.0), atomically.
pub fn write_npy_f64(path: &Path, rows: usize, cols: usize, data: &[f64]) -> Result<()> {
    assert_eq!(rows * cols, data.len());
    write_npy_shape(path, &format!("({rows}, {cols})"), data)
}

/// Write a float64 array of shape [n, 3, 3] (rotation matrices), atomically.
pub fn write_npy_3d(path: &Path, n: usize, data: &[f64]) -> Result<()> {
    assert_eq!(n * 9, data.len());
    write_npy_shape(path, &format!("({n}, 3, 3)"), data)
}

fn write_npy_shape(path: &Path, shape: &str, data: &[f64]) -> Result<()> {
    super::write_atomic(path, &npy_f64_bytes(shape, data))
}

/// The bytes of a float64 `.npy` file (format 1.0, C order) of shape `shape` (Python tuple
/// syntax, e.g. `(5, 3)`).
pub fn npy_f64_bytes(shape: &str, data: &[f64]) -> Vec<u8> {
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
    // Pad so that magic + version + length + header + '\n' is a multiple of 64.
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 8);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[derive(Clone, Copy)]
enum Kind {
    Float,
    Int,
    Uint,
}

fn parse_descr(d: &str) -> Option<(bool, Kind, usize)> {
    let mut chars = d.chars();
    let order = chars.next()?;
    let little = match order {
        '<' | '|' | '=' => true,
        '>' => false,
        _ => return None,
    };
    let kind = match chars.next()? {
        'f' => Kind::Float,
        'i' => Kind::Int,
        'u' => Kind::Uint,
        _ => return None,
    };
    let size: usize = chars.as_str().parse().ok()?;
    match (kind, size) {
        (Kind::Float, 4 | 8) | (Kind::Int | Kind::Uint, 1 | 2 | 4 | 8) => {
            Some((little, kind, size))
        }
        _ => None,
    }
}

fn decode(b: &[u8], little: bool, kind: Kind) -> f64 {
    let mut buf = [0u8; 8];
    buf[..b.len()].copy_from_slice(b);
    if !little {
        buf[..b.len()].reverse();
    }
    match (kind, b.len()) {
        (Kind::Float, 4) => f32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]]) as f64,
        (Kind::Float, _) => f64::from_le_bytes(buf),
        (Kind::Int, 1) => buf[0] as i8 as f64,
        (Kind::Int, 2) => i16::from_le_bytes([buf[0], buf[1]]) as f64,
        (Kind::Int, 4) => i32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]]) as f64,
        (Kind::Int, _) => i64::from_le_bytes(buf) as f64,
        (Kind::Uint, _) => u64::from_le_bytes(buf) as f64,
    }
}

/// The text after `'key':` in a Python dict literal, up to the matching delimiter.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pat1 = format!("'{key}':");
    let pat2 = format!("\"{key}\":");
    let pos = header
        .find(&pat1)
        .map(|p| p + pat1.len())
        .or_else(|| header.find(&pat2).map(|p| p + pat2.len()))?;
    let rest = header[pos..].trim_start();
    if rest.starts_with('(') {
        let close = rest.find(')')?;
        Some(&rest[..=close])
    } else {
        let end = rest.find([',', '}']).unwrap_or(rest.len());
        Some(&rest[..end])
    }
}

fn parse_shape(s: &str) -> Option<Vec<usize>> {
    let inner = s.trim().strip_prefix('(')?.strip_suffix(')')?;
    inner
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| t.parse().ok())
        .collect()
}

fn fortran_to_c(data: &[f64], shape: &[usize]) -> Vec<f64> {
    let n = data.len();
    let mut out = vec![0.0; n];
    let nd = shape.len();
    let mut idx = vec![0usize; nd];
    for v in data {
        // `idx` walks Fortran order (first axis fastest).
        let mut c = 0usize;
        for d in 0..nd {
            c = c * shape[d] + idx[d];
        }
        out[c] = *v;
        for d in 0..nd {
            idx[d] += 1;
            if idx[d] < shape[d] {
                break;
            }
            idx[d] = 0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy_bytes(descr: &str, shape: &str, fortran: bool, body: &[u8]) -> Vec<u8> {
        let h = format!(
            "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}\n",
            if fortran { "True" } else { "False" }
        );
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend_from_slice(&(h.len() as u16).to_le_bytes());
        b.extend_from_slice(h.as_bytes());
        b.extend_from_slice(body);
        b
    }

    #[test]
    fn reads_f4_and_f8() {
        let body: Vec<u8> = [1.0f32, 2.0, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = parse_npy(
            Path::new("a.npy"),
            &npy_bytes("<f4", "(1, 3)", false, &body),
        )
        .unwrap();
        assert_eq!(a.shape, vec![1, 3]);
        assert_eq!(a.data, vec![1.0, 2.0, 3.0]);
        let body: Vec<u8> = [1.5f64, -2.0]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        let a = parse_npy(Path::new("a.npy"), &npy_bytes(">f8", "(2,)", false, &body)).unwrap();
        assert_eq!(a.data, vec![1.5, -2.0]);
    }

    #[test]
    fn fortran_order_is_transposed() {
        // 2×3 matrix [[1,2,3],[4,5,6]] stored column-major: 1 4 2 5 3 6.
        let body: Vec<u8> = [1.0f64, 4.0, 2.0, 5.0, 3.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = parse_npy(Path::new("a.npy"), &npy_bytes("<f8", "(2, 3)", true, &body)).unwrap();
        assert_eq!(a.data, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    }

    #[test]
    fn errors_name_the_problem() {
        let p = Path::new("bad.npy");
        let e = parse_npy(p, b"hello world").unwrap_err().to_string();
        assert!(e.contains("bad.npy") && e.contains("magic"), "{e}");
        let e = parse_npy(p, &npy_bytes("<f8", "(2, 3)", false, &[0u8; 8]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated data"), "{e}");
        let e = parse_npy(p, &npy_bytes("<c16", "(2,)", false, &[0u8; 32]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("unsupported dtype"), "{e}");
    }

    #[test]
    fn write_then_read() {
        let dir = std::env::temp_dir().join(format!("ggs-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.npy");
        write_npy_f64(&p, 2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5]).unwrap();
        let a = read_npy(&p).unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.5]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// One unit test per error path.
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::{Byte, File};

    /// A version-1 file with this header text and body.
    fn npy(header: &str, body: &[u8]) -> Vec<u8> {
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend((header.len() as u16).to_le_bytes());
        b.extend(header.as_bytes());
        b.extend(body);
        b
    }

    fn points(path: &Path, b: &[u8]) -> Result<Vec<crate::cloud::Point>> {
        points_of(path, &parse_npy(path, b)?)
    }

    error_cases! { points;
        no_magic: b"\x93NUMPX\x01\x00\x00\x00" => Byte(0), "magic";
        v2_length_truncated: b"\x93NUMPY\x02\x00\x10\x00" => Byte(8), "truncated header length";
        unknown_version: b"\x93NUMPY\x07\x00\x00\x00" => Byte(6), "unsupported .npy format version 7";
        header_truncated: npy("{'descr': '<f8'", b"")[..20].to_vec() => Byte(10), "truncated header";
        header_not_text: { let mut b = npy("x", b""); b[10] = 0xff; b } => Byte(10), "not text";
        no_descr: npy("{'shape': (1, 3), }", b"") => Byte(10), "no 'descr'";
        no_shape: npy("{'descr': '<f8', }", b"") => Byte(10), "no 'shape'";
        bad_shape: npy("{'descr': '<f8', 'shape': (1, -3), }", b"") => Byte(10), "bad shape";
        unsupported_dtype: npy("{'descr': '<c16', 'shape': (1, 3), }", b"") => Byte(10), "unsupported dtype '<c16'";
        element_count_overflows: npy("{'descr': '<f8', 'shape': (4294967296, 4294967296, 2), }", b"") => Byte(10), "shape too large";
        byte_count_overflows: npy("{'descr': '<f8', 'shape': (4611686018427387904,), }", b"") => Byte(10), "shape too large";
        data_truncated: npy("{'descr': '<f8', 'shape': (1, 3), }", &[0u8; 20]) => Byte(65), "needs 24 bytes, found 20";
        not_a_cloud: npy("{'descr': '<f8', 'shape': (3,), }", &[0u8; 24]) => File, "shape [N, 3]";
    }
}

/// A rotation set from a `.npy` file of shape `[N, 3, 3]` (float32 or float64), named after
/// the file; see [`RotationSet::from_row_major`](crate::rotations::RotationSet::from_row_major).
pub fn read_rotation_set(path: &Path) -> Result<crate::rotations::RotationSet> {
    let arr = read_npy(path)?;
    if arr.shape.len() != 3 || arr.shape[1] != 3 || arr.shape[2] != 3 {
        return Err(GgsError::in_file(
            path,
            format!(
                "expected an array of shape [N, 3, 3], found {:?}",
                arr.shape
            ),
        ));
    }
    if arr.shape[0] == 0 {
        return Err(GgsError::in_file(path, "the rotation array has no rows"));
    }
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    crate::rotations::RotationSet::from_row_major(&name, &arr.data)
        .map_err(|m| GgsError::in_file(path, m))
}
