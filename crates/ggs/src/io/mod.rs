//! Reading and writing point clouds.
//!
//! Formats are detected by extension, then checked against the file's magic bytes; a forced
//! [`Format`] skips the extension. Every reader returns a typed [`GgsError`] that names the
//! file and the line or byte offset of the problem.

pub mod kitti;
pub mod las;
pub mod mesh;
pub mod npy;
pub mod pcd;
pub mod ply;
pub mod xyz;

use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use std::io::Write;
use std::path::Path;

/// Point-cloud file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Ply,
    Pcd,
    /// Delimited text: `.xyz`, `.txt`, `.csv`, `.pts`.
    Text,
    Npy,
    /// KITTI velodyne `.bin` (float32 x y z reflectance).
    KittiBin,
    /// ASPRS LAS or LAZ (scale and offset applied).
    Las,
    /// Wavefront OBJ mesh (its vertices).
    Obj,
    /// STL mesh, binary or ASCII (its distinct vertices).
    Stl,
}

impl Format {
    /// Parse a `--format` value.
    pub fn from_name(name: &str) -> Option<Format> {
        Some(match name.to_ascii_lowercase().as_str() {
            "ply" => Format::Ply,
            "pcd" => Format::Pcd,
            "xyz" | "txt" | "csv" | "pts" | "text" => Format::Text,
            "npy" => Format::Npy,
            "bin" | "kitti" => Format::KittiBin,
            "las" | "laz" => Format::Las,
            "obj" => Format::Obj,
            "stl" => Format::Stl,
            _ => return None,
        })
    }

    /// Guess from the file extension.
    pub fn from_extension(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?;
        Format::from_name(ext)
    }

    /// Guess from the first bytes of the file.
    pub fn from_magic(bytes: &[u8]) -> Option<Format> {
        if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
            Some(Format::Ply)
        } else if bytes.starts_with(b"\x93NUMPY") {
            Some(Format::Npy)
        } else if bytes.starts_with(b"LASF") {
            Some(Format::Las)
        } else if bytes.starts_with(b"# .PCD") || bytes.starts_with(b"VERSION") {
            Some(Format::Pcd)
        } else {
            None
        }
    }
}

/// A cloud read from a file, with what was dropped on the way.
#[derive(Debug, Clone)]
pub struct LoadedCloud {
    pub cloud: Cloud,
    /// Points dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
}

/// Read a point cloud. `format` forces the format; otherwise the extension decides, and a
/// file whose magic bytes say otherwise (a PLY named `.txt`) is read by its magic.
/// NaN or infinite points are dropped (and counted); an empty result is an error.
pub fn read_cloud(path: &Path, format: Option<Format>) -> Result<LoadedCloud> {
    let bytes = std::fs::read(path).map_err(|e| GgsError::io(path, e))?;
    let fmt = match format {
        Some(f) => f,
        None => match (Format::from_magic(&bytes), Format::from_extension(path)) {
            (Some(m), _) => m,
            (None, Some(e)) => e,
            (None, None) => {
                return Err(GgsError::UnknownFormat {
                    path: path.to_path_buf(),
                    what: match path.extension() {
                        Some(e) => format!("'.{}'", e.to_string_lossy()),
                        None => "(no extension, no known magic bytes)".to_string(),
                    },
                })
            }
        },
    };
    let points = match fmt {
        Format::Ply => ply::parse_ply(path, &bytes)?,
        Format::Pcd => pcd::parse_pcd(path, &bytes)?,
        Format::KittiBin => kitti::parse_kitti_bin(path, &bytes)?,
        Format::Las => las::parse_las(path, bytes)?,
        Format::Obj => mesh::parse_obj(path, &bytes)?.vertices,
        Format::Stl => mesh::parse_stl(path, &bytes)?.vertices,
        Format::Text => xyz::parse_xyz(path, &bytes)?,
        Format::Npy => {
            let a = npy::parse_npy(path, &bytes)?;
            if a.shape.len() != 2 || a.shape[1] < 3 {
                return Err(GgsError::in_file(
                    path,
                    format!(
                        "expected an array of shape [N, 3] or [N, k≥3], found {:?}",
                        a.shape
                    ),
                ));
            }
            let k = a.shape[1];
            a.data.chunks_exact(k).map(|r| [r[0], r[1], r[2]]).collect()
        }
    };
    let mut cloud = Cloud::new(points);
    let dropped = cloud.drop_non_finite();
    if cloud.is_empty() {
        return Err(GgsError::EmptyCloud {
            what: path.display().to_string(),
            detail: if dropped > 0 {
                format!(" (all {dropped} points had NaN or infinite coordinates)")
            } else {
                String::new()
            },
        });
    }
    Ok(LoadedCloud {
        cloud,
        dropped_non_finite: dropped,
    })
}

/// Write a point cloud in the format of `format`, or of the path's extension: PLY (binary
/// little endian, doubles), PCD (binary, doubles), XYZ/TXT/PTS (text, round-trip precision),
/// NPY (float64 N×3), KITTI `.bin` (float32, reflectance 0) or LAS/LAZ (32-bit integers
/// with a per-file scale: see [`las::write_las`]). CSV gets a comma-free text
/// layout too (`x y z` per line), which ggs and most tools read. Atomic.
pub fn write_cloud(
    path: &Path,
    points: &[crate::cloud::Point],
    format: Option<Format>,
) -> Result<()> {
    let fmt = format
        .or_else(|| Format::from_extension(path))
        .ok_or_else(|| GgsError::UnknownFormat {
            path: path.to_path_buf(),
            what: "(writable: .ply, .pcd, .xyz/.txt/.pts/.csv, .npy, .bin, .las, .laz)".to_string(),
        })?;
    match fmt {
        Format::Ply => ply::write_ply(path, points, None, Default::default()),
        Format::Pcd => pcd::write_pcd(path, points),
        Format::Text => xyz::write_xyz(path, points),
        Format::Npy => {
            let flat: Vec<f64> = points.iter().flatten().copied().collect();
            npy::write_npy_f64(path, points.len(), 3, &flat)
        }
        Format::KittiBin => kitti::write_kitti_bin(path, points),
        Format::Las => las::write_las(path, points),
        Format::Obj | Format::Stl => Err(GgsError::UnknownFormat {
            path: path.to_path_buf(),
            what: "(meshes are read, not written; writable: .ply, .pcd, .xyz/.txt/.pts/.csv, .npy, .bin, .las, .laz)".to_string(),
        }),
    }
}

/// Write `bytes` to `path` atomically: a temporary file in the same directory, flushed and
/// synced, then renamed over `path`. A failure leaves no partial `path` behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| GgsError::in_file(path, "not a file path"))?;
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(GgsError::io(path, e));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_writable_format_round_trips() {
        let dir = std::env::temp_dir().join(format!("ggs-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pts = vec![
            [0.1, -2.5e-7, 1234.5678901234567],
            [-3.0, 1.0 / 3.0, 0.0],
            [6e5, 4.2e6, -12.25],
        ];
        for ext in ["ply", "pcd", "xyz", "txt", "pts", "csv", "npy"] {
            let p = dir.join(format!("c.{ext}"));
            write_cloud(&p, &pts, None).unwrap();
            let back = read_cloud(&p, None).unwrap().cloud.points;
            assert_eq!(back, pts, "{ext}");
        }
        // KITTI stores float32.
        let p = dir.join("c.bin");
        write_cloud(&p, &pts, None).unwrap();
        let back = read_cloud(&p, None).unwrap().cloud.points;
        for (a, b) in back.iter().zip(&pts) {
            for k in 0..3 {
                assert_eq!(a[k], b[k] as f32 as f64);
            }
        }
        let e = write_cloud(&dir.join("c.weird"), &pts, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("writable"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn tmpdir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("ggs-io-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn unknown_extension_is_an_error() {
        let d = tmpdir("ext");
        let p = d.join("cloud.abc");
        std::fs::write(&p, "1 2 3\n").unwrap();
        let e = read_cloud(&p, None).unwrap_err();
        assert!(matches!(e, GgsError::UnknownFormat { .. }));
        assert!(e.to_string().contains("cloud.abc"));
        // Forcing the format reads it.
        assert_eq!(read_cloud(&p, Some(Format::Text)).unwrap().cloud.len(), 1);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn magic_beats_extension() {
        let d = tmpdir("magic");
        let p = d.join("cloud.txt");
        std::fs::write(
            &p,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
        )
        .unwrap();
        assert_eq!(
            read_cloud(&p, None).unwrap().cloud.points,
            vec![[1.0, 2.0, 3.0]]
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn non_finite_points_are_dropped_and_empty_is_an_error() {
        let d = tmpdir("nan");
        let p = d.join("a.xyz");
        std::fs::write(&p, "1 2 3\nnan 0 0\n4 inf 6\n").unwrap();
        let l = read_cloud(&p, None).unwrap();
        assert_eq!(l.cloud.len(), 1);
        assert_eq!(l.dropped_non_finite, 2);
        std::fs::write(&p, "nan 0 0\n").unwrap();
        let e = read_cloud(&p, None).unwrap_err().to_string();
        assert!(e.contains("empty") && e.contains("NaN"), "{e}");
        std::fs::write(&p, "").unwrap();
        assert!(matches!(
            read_cloud(&p, None),
            Err(GgsError::EmptyCloud { .. })
        ));
        let missing = d.join("missing.ply");
        let e = read_cloud(&missing, None).unwrap_err().to_string();
        assert!(e.contains("missing.ply"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn atomic_write_replaces_whole_file() {
        let d = tmpdir("atomic");
        let p = d.join("out.bin");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        let leftovers: Vec<_> = std::fs::read_dir(&d).unwrap().collect();
        assert_eq!(leftovers.len(), 1);
        assert!(write_atomic(&d.join("no/such/dir/x"), b"x").is_err());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
