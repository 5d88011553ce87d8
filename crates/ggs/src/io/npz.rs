//! NumPy `.npz` archives (zip files of `.npy` arrays, stored or deflated) through the
//! maintained `zip` crate; each array is parsed by [`super::npy`].

use super::npy::{self, NpyArray};
use crate::cloud::Point;
use crate::error::{GgsError, Result};
use std::io::{Read, Seek};
use std::path::Path;

/// Array names taken, in this order, when several arrays have the shape of a cloud.
pub const PREFERRED_NAMES: [&str; 6] = ["points", "xyz", "pcd", "pc", "coords", "arr_0"];

/// Every array of an archive, by name (without `.npy`), in archive order.
pub fn read_npz<R: Read + Seek>(path: &Path, r: R) -> Result<Vec<(String, NpyArray)>> {
    let zip_err = |what: &str, e: zip::result::ZipError| {
        GgsError::in_file(path, format!("NPZ archive {what}: {e}"))
    };
    let mut archive = zip::ZipArchive::new(r).map_err(|e| zip_err("directory", e))?;
    let mut arrays = Vec::with_capacity(archive.len().min(1024));
    for i in 0..archive.len() {
        let mut entry = archive
            .by_index(i)
            .map_err(|e| zip_err(&format!("entry {i}"), e))?;
        if entry.is_dir() {
            continue;
        }
        let name = entry
            .name()
            .map_err(|e| zip_err(&format!("entry {i} name"), e))?
            .to_string();
        let key = name.strip_suffix(".npy").unwrap_or(&name).to_string();
        let mut bytes = Vec::with_capacity(entry.size().min(1 << 24) as usize);
        entry
            .read_to_end(&mut bytes)
            .map_err(|e| GgsError::in_file(path, format!("NPZ entry '{name}': {e}")))?;
        let inner = path.join(&name);
        let array = npy::parse_npy(&inner, &bytes)?;
        arrays.push((key, array));
    }
    Ok(arrays)
}

/// The points of an archive: the array named `key`, or else the one array shaped [N, k≥3]
/// (several: the first of [`PREFERRED_NAMES`] among them).
pub fn read_npz_points<R: Read + Seek>(path: &Path, r: R, key: Option<&str>) -> Result<Vec<Point>> {
    let arrays = read_npz(path, r)?;
    let describe = |list: &[&(String, NpyArray)]| {
        list.iter()
            .map(|(k, a)| format!("{k} {:?}", a.shape))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let all: Vec<&(String, NpyArray)> = arrays.iter().collect();
    let chosen = match key {
        Some(k) => {
            let k = k.strip_suffix(".npy").unwrap_or(k);
            all.iter().find(|(name, _)| name == k).ok_or_else(|| {
                GgsError::in_file(
                    path,
                    format!(
                        "NPZ: no array '{k}' (the archive holds: {})",
                        describe(&all)
                    ),
                )
            })?
        }
        None => {
            let clouds: Vec<&(String, NpyArray)> = all
                .iter()
                .copied()
                .filter(|(_, a)| a.shape.len() == 2 && a.shape[1] >= 3)
                .collect();
            match clouds.len() {
                0 => {
                    return Err(GgsError::in_file(
                        path,
                        format!(
                            "NPZ: no array of shape [N, 3] or [N, k≥3] (the archive holds: {})",
                            if all.is_empty() { "nothing".to_string() } else { describe(&all) }
                        ),
                    ))
                }
                1 => clouds[0],
                _ => PREFERRED_NAMES
                    .iter()
                    .find_map(|want| clouds.iter().copied().find(|(k, _)| k == want))
                    .ok_or_else(|| {
                        GgsError::in_file(
                            path,
                            format!(
                                "NPZ: several arrays could be the cloud ({}); choose one with --array",
                                describe(&clouds)
                            ),
                        )
                    })?,
            }
        }
    };
    npy::points_of(&path.join(format!("{}.npy", chosen.0)), &chosen.1)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use std::io::{Cursor, Write};

    pub(crate) fn npy_bytes(shape: (usize, usize), data: &[f64]) -> Vec<u8> {
        npy::npy_f64_bytes(&format!("({}, {})", shape.0, shape.1), data)
    }

    pub(crate) fn archive(entries: &[(&str, Vec<u8>)], deflate: bool) -> Vec<u8> {
        let mut buf = Cursor::new(Vec::new());
        {
            let mut z = zip::ZipWriter::new(&mut buf);
            let method = if deflate {
                zip::CompressionMethod::Deflated
            } else {
                zip::CompressionMethod::Stored
            };
            let opts = zip::write::SimpleFileOptions::default().compression_method(method);
            for (name, bytes) in entries {
                z.start_file(*name, opts).unwrap();
                z.write_all(bytes).unwrap();
            }
            z.finish().unwrap();
        }
        buf.into_inner()
    }

    #[test]
    fn picks_the_cloud_array() {
        let p = Path::new("c.npz");
        let pts = npy_bytes((2, 3), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let other = npy_bytes((1, 2), &[7.0, 8.0]);
        for deflate in [false, true] {
            let z = archive(
                &[("labels.npy", other.clone()), ("xyz.npy", pts.clone())],
                deflate,
            );
            let got = read_npz_points(p, Cursor::new(&z), None).unwrap();
            assert_eq!(got, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
            let got = read_npz_points(p, Cursor::new(&z), Some("xyz.npy")).unwrap();
            assert_eq!(got.len(), 2);
            let e = read_npz_points(p, Cursor::new(&z), Some("labels"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("labels.npy") && e.contains("[N, 3]"), "{e}");
            let e = read_npz_points(p, Cursor::new(&z), Some("nope"))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("c.npz") && e.contains("no array 'nope'") && e.contains("xyz [2, 3]"),
                "{e}"
            );
        }
        // Two candidates: the preferred name wins; without one, an error asks for --array.
        let z = archive(&[("a.npy", pts.clone()), ("points.npy", pts.clone())], true);
        assert_eq!(read_npz_points(p, Cursor::new(&z), None).unwrap().len(), 2);
        let z = archive(&[("a.npy", pts.clone()), ("b.npy", pts.clone())], true);
        let e = read_npz_points(p, Cursor::new(&z), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--array") && e.contains("a [2, 3]"), "{e}");
        let z = archive(&[("labels.npy", other)], false);
        let e = read_npz_points(p, Cursor::new(&z), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no array of shape"), "{e}");
    }

    #[test]
    fn broken_archives_are_errors() {
        let p = Path::new("c.npz");
        let e = read_npz_points(p, Cursor::new(b"PK\x03\x04 not really"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.npz") && e.contains("NPZ archive"), "{e}");
        // An entry that is not a .npy array names the entry.
        let z = archive(&[("x.npy", b"hello".to_vec())], true);
        let e = read_npz_points(p, Cursor::new(&z), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.npy") && e.contains("magic"), "{e}");
        // A truncated archive.
        let z = archive(&[("x.npy", npy_bytes((1, 3), &[1.0, 2.0, 3.0]))], true);
        assert!(read_npz_points(p, Cursor::new(&z[..z.len() - 30]), None).is_err());
    }
}

/// One unit test per error path.
#[cfg(test)]
mod error_paths {
    use super::tests::{archive, npy_bytes};
    use super::*;
    use crate::error::Location::{Byte, File};
    use std::io::Cursor;

    fn read(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        read_npz_points(path, Cursor::new(b), None)
    }

    /// A one-entry stored archive with the entry's bytes changed by `f` (local header at 0,
    /// central header found by its signature).
    fn patched(f: impl Fn(&mut Vec<u8>, usize)) -> Vec<u8> {
        let mut z = archive(&[("x.npy", npy_bytes((1, 3), &[1.0, 2.0, 3.0]))], false);
        let central = z.windows(4).position(|w| w == b"PK\x01\x02").unwrap();
        f(&mut z, central);
        z
    }

    error_cases! { read;
        not_a_zip: b"PK\x03\x04 but no directory" => File, "NPZ archive directory";
        unsupported_compression: patched(|z, c| {
            // Method 99 (AES) in both headers.
            z[8] = 99;
            z[c + 10] = 99;
        }) => File, "NPZ entry 'x.npy': compression method not supported";
        local_header_broken: patched(|z, _| z[3] = 9) => File, "NPZ archive entry 0";
        corrupt_deflate_stream: {
            let mut z = archive(&[("x.npy", npy_bytes((50, 3), &[0.5; 150]))], true);
            for b in &mut z[40..60] {
                *b ^= 0x5a;
            }
            z
        } => File, "NPZ entry 'x.npy'";
        entry_not_npy: archive(&[("x.npy", b"\x93NUMPY\x01\x00\x05\x00{'sh".to_vec())], false) => Byte(10), "x.npy";
        no_cloud_array: archive(&[("x.npy", npy_bytes((2, 2), &[0.0; 4]))], false) => File, "no array of shape [N, 3]";
        empty_archive: archive(&[], false) => File, "holds: nothing";
    }
}
