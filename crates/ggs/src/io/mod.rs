//! Reading and writing point clouds.
//!
//! Formats are detected by extension, then checked against the file's magic bytes; a forced
//! [`Format`] skips the extension. Every reader returns a typed [`GgsError`] that names the
//! file and the line or byte offset of the problem.

/// `error_cases! { read_fn; name: input => Location, "expected text"; … }`: one unit test
/// per error path of a parser. `read_fn(path, &[u8])` must fail on `input` at that location
/// (a [`crate::Location`]), with a message that names the file and contains the text.
#[cfg(test)]
macro_rules! error_cases {
    ($read:expr; $($name:ident: $input:expr => $loc:expr, $want:expr;)+) => {
        $(
            #[test]
            fn $name() {
                let path = std::path::Path::new("bad.input");
                let input = $input;
                let bytes: &[u8] = AsRef::<[u8]>::as_ref(&input);
                #[allow(clippy::redundant_closure_call)]
                let r = ($read)(path, bytes);
                $crate::io::check_error(r, $loc, $want);
            }
        )+
    };
}

/// `bytes` with the bytes at positions `start + at % (len − start)` replaced by the junk,
/// for tests that compare two readers on damaged files.
#[cfg(test)]
pub(crate) fn with_junk(mut bytes: Vec<u8>, start: usize, junk: &[(usize, &[u8])]) -> Vec<u8> {
    for &(at, j) in junk {
        let body = bytes.len() - start;
        if body == 0 {
            break;
        }
        let at = start + at % body;
        bytes.splice(at..at + 1, j.iter().copied());
    }
    bytes
}

/// The assertion behind `error_cases!`.
#[cfg(test)]
pub(crate) fn check_error<T: std::fmt::Debug>(
    r: Result<T>,
    loc: crate::error::Location,
    want: &str,
) {
    let e = r.expect_err("expected an error");
    let s = e.to_string();
    assert!(
        s.contains("bad.input"),
        "the message does not name the file: {s}"
    );
    assert!(s.contains(want), "expected '{want}' in: {s}");
    assert_eq!(e.location(), Some(loc), "{s}");
}

#[cfg(feature = "e57")]
pub mod e57;
pub mod kitti;
#[cfg(feature = "las")]
pub mod las;
pub mod mesh;
pub mod npy;
#[cfg(feature = "npz")]
pub mod npz;
pub mod pcd;
pub mod ply;
pub mod scans;
pub mod stream;
pub mod text;
pub mod xyz;

use crate::cloud::{Cloud, CloudBuilder, Point, PointStore};
use crate::error::{GgsError, Result};
use std::io::{BufRead, BufReader, Read, Seek, Write};
use std::path::Path;

/// Point-cloud file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Ply,
    Pcd,
    /// Delimited text: `.xyz`, `.txt`, `.csv`, `.pts`.
    Text,
    Npy,
    /// NumPy `.npz` archive (one of its arrays).
    Npz,
    /// KITTI velodyne `.bin` (float32 x y z reflectance).
    KittiBin,
    /// ASPRS LAS or LAZ (scale and offset applied).
    Las,
    /// ASTM E57 (all scans with their poses, or one scan).
    E57,
    /// Wavefront OBJ mesh (its vertices, or points sampled on its faces).
    Obj,
    /// STL mesh, binary or ASCII (its distinct vertices, or points sampled on its faces).
    Stl,
}

/// Names `--format` accepts.
pub const FORMAT_NAMES: &str =
    "ply, pcd, xyz, txt, csv, pts, npy, npz, bin, las, laz, e57, obj, stl";

impl Format {
    /// Parse a `--format` value.
    pub fn from_name(name: &str) -> Option<Format> {
        Some(match name.to_ascii_lowercase().as_str() {
            "ply" => Format::Ply,
            "pcd" => Format::Pcd,
            "xyz" | "txt" | "csv" | "pts" | "text" => Format::Text,
            "npy" => Format::Npy,
            "npz" => Format::Npz,
            "bin" | "kitti" => Format::KittiBin,
            "las" | "laz" => Format::Las,
            "e57" => Format::E57,
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

    /// Guess from the first bytes of the file (a few hundred are enough). Text formats
    /// without a signature (XYZ, OBJ) and KITTI `.bin` have no magic: their extension
    /// decides.
    pub fn from_magic(bytes: &[u8]) -> Option<Format> {
        let starts = |m: &[u8]| bytes.starts_with(m);
        if starts(b"ply\n") || starts(b"ply\r\n") {
            Some(Format::Ply)
        } else if starts(b"\x93NUMPY") {
            Some(Format::Npy)
        } else if starts(b"PK\x03\x04") || starts(b"PK\x05\x06") {
            Some(Format::Npz)
        } else if starts(b"LASF") {
            Some(Format::Las)
        } else if starts(b"ASTM-E57") {
            Some(Format::E57)
        } else if starts(b"# .PCD") || starts(b"VERSION") {
            Some(Format::Pcd)
        } else if starts(b"solid") && ascii_stl_start(bytes) {
            Some(Format::Stl)
        } else {
            None
        }
    }
}

/// An ASCII STL starts `solid NAME` and then `facet`; binary STLs may start with `solid` too,
/// in their 80-byte free header, but are not text after it.
fn ascii_stl_start(bytes: &[u8]) -> bool {
    let head = &bytes[..bytes.len().min(512)];
    head.windows(5).any(|w| w == b"facet") && head.iter().all(|&b| b.is_ascii())
}

/// How to read a file: its format (or detect it), and the choices some formats need.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// Force the format; `None`: magic bytes, then the extension.
    pub format: Option<Format>,
    /// E57: which scans, and whether their poses are applied.
    pub e57: scans::E57Options,
    /// NPZ: the array to read (`None`: the array shaped like a cloud).
    pub npz_array: Option<String>,
    /// OBJ, STL and PLY meshes: sample this many points uniformly on the faces (seeded,
    /// reproducible) instead of taking the vertices. Point clouds are read as they are.
    pub mesh_samples: Option<usize>,
}

/// Seed of mesh sampling on read (so a mesh read twice gives the same points).
pub const MESH_SAMPLE_SEED: u64 = 0x0067_6773;

/// A cloud read from a file, with what was dropped on the way.
#[derive(Debug, Clone)]
pub struct LoadedCloud {
    pub cloud: Cloud,
    /// Points dropped because a coordinate was NaN or infinite (or, in E57, marked invalid).
    pub dropped_non_finite: usize,
    /// The format the file was read as.
    pub format: Format,
    /// Size of the file in bytes.
    pub file_bytes: u64,
}

/// Read a point cloud. `format` forces the format; otherwise the magic bytes decide, then
/// the extension (a PLY named `.txt` is read as PLY). See [`read_cloud_with`].
pub fn read_cloud(path: &Path, format: Option<Format>) -> Result<LoadedCloud> {
    read_cloud_with(
        path,
        &ReadOptions {
            format,
            ..Default::default()
        },
    )
}

/// A file's points as `f64`, exactly as written: [`read_points_with`] with `format` forced
/// or detected as in [`read_cloud`].
pub fn read_exact_points(path: &Path, format: Option<Format>) -> Result<LoadedPoints> {
    read_points_with(
        path,
        &ReadOptions {
            format,
            ..Default::default()
        },
    )
}

/// Read several point clouds as [`read_cloud_with`] reads each, side by side on the current
/// thread pool; the results are in the order of `paths`.
pub fn read_clouds_with<P: AsRef<Path> + Sync>(
    paths: &[P],
    opts: &ReadOptions,
) -> Vec<Result<LoadedCloud>> {
    use rayon::prelude::*;
    paths
        .par_iter()
        .map(|p| read_cloud_with(p.as_ref(), opts))
        .collect()
}

/// Bytes of the read buffer: large enough that the kernel reads ahead at disk speed.
const READ_BUFFER: usize = 1 << 20;

/// Read a point cloud with options, as [`read_points_with`] reads it, into a [`Cloud`]
/// (`f32` offsets, 12 bytes a point): the streamed formats store each chunk as they decode
/// it, so no `f64` copy of the cloud is ever held.
pub fn read_cloud_with(path: &Path, opts: &ReadOptions) -> Result<LoadedCloud> {
    let (file_bytes, r) = open(path)?;
    let (format, mut cloud) = read_points::<CloudBuilder, _>(path, r, file_bytes, opts)?;
    let dropped_non_finite = cloud.drop_non_finite();
    not_empty(path, cloud.len(), dropped_non_finite)?;
    Ok(LoadedCloud {
        cloud,
        dropped_non_finite,
        format,
        file_bytes,
    })
}

/// A file's points as `f64`, exactly as the file gives them (for tools that write points
/// back out: `ggs convert`, the generator, Python's `read`).
#[derive(Debug, Clone)]
pub struct LoadedPoints {
    pub points: Vec<Point>,
    /// Points dropped because a coordinate was NaN or infinite (or, in E57, marked invalid).
    pub dropped_non_finite: usize,
    /// The format the file was read as.
    pub format: Format,
    /// Size of the file in bytes.
    pub file_bytes: u64,
}

impl LoadedPoints {
    /// The same points held as a [`Cloud`].
    pub fn into_cloud(self) -> LoadedCloud {
        LoadedCloud {
            cloud: Cloud::new(self.points),
            dropped_non_finite: self.dropped_non_finite,
            format: self.format,
            file_bytes: self.file_bytes,
        }
    }
}

/// Read a file's points as `f64`. Binary PLY, binary PCD, KITTI, LAS/LAZ and E57 are
/// streamed (the memory beside the points is a few MB, whatever the file size); the other
/// formats are read whole, then parsed. NaN or infinite points are dropped (and counted); an
/// empty result is an error.
pub fn read_points_with(path: &Path, opts: &ReadOptions) -> Result<LoadedPoints> {
    let (file_bytes, r) = open(path)?;
    let (format, mut points) = read_points::<Vec<Point>, _>(path, r, file_bytes, opts)?;
    let dropped_non_finite = crate::cloud::drop_non_finite(&mut points);
    not_empty(path, points.len(), dropped_non_finite)?;
    Ok(LoadedPoints {
        points,
        dropped_non_finite,
        format,
        file_bytes,
    })
}

/// The file's size and a buffered reader at its start.
fn open(path: &Path) -> Result<(u64, BufReader<std::fs::File>)> {
    let io = |e| GgsError::io(path, e);
    let file = std::fs::File::open(path).map_err(io)?;
    let file_bytes = file.metadata().map_err(io)?.len();
    Ok((file_bytes, BufReader::with_capacity(READ_BUFFER, file)))
}

/// An error naming `path` when no point is left (`dropped` had NaN or infinite coordinates).
fn not_empty(path: &Path, len: usize, dropped: usize) -> Result<()> {
    if len > 0 {
        return Ok(());
    }
    Err(GgsError::EmptyCloud {
        what: path.display().to_string(),
        detail: if dropped > 0 {
            format!(" (all {dropped} points had NaN or infinite coordinates)")
        } else {
            String::new()
        },
    })
}

/// The format of a file: its magic bytes, else its extension.
fn detect<R: BufRead>(path: &Path, r: &mut R) -> Result<Format> {
    let head = r.fill_buf().map_err(|e| GgsError::io(path, e))?;
    if let Some(m) = Format::from_magic(head) {
        return Ok(m);
    }
    Format::from_extension(path).ok_or_else(|| GgsError::UnknownFormat {
        path: path.to_path_buf(),
        what: match path.extension() {
            Some(e) => format!("'.{}'", e.to_string_lossy()),
            None => "(no extension, no known magic bytes)".to_string(),
        },
    })
}

/// The rest of `r`, in one allocation of the file's `len` bytes.
fn read_all<R: Read>(path: &Path, mut r: R, len: u64) -> Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    r.read_to_end(&mut bytes)
        .map_err(|e| GgsError::io(path, e))?;
    Ok(bytes)
}

/// A mesh's vertices, or points sampled on its faces if `opts.mesh_samples` asks.
fn sampled(path: &Path, opts: &ReadOptions, m: mesh::Mesh) -> Result<Vec<crate::cloud::Point>> {
    match opts.mesh_samples {
        None => Ok(m.vertices),
        Some(n) => crate::mesh::sampling::sample_surface(&m, n, MESH_SAMPLE_SEED)
            .map_err(|e| GgsError::in_file(path, format!("cannot sample the mesh: {e}"))),
    }
}

/// Read any supported file held in memory, as [`read_cloud_with`] would read it from disk
/// (the fuzz targets' entry point; `path` names the file in errors and, without a forced
/// format, gives the extension). Points are returned as parsed, NaN included.
pub fn parse_bytes(
    path: &Path,
    bytes: &[u8],
    opts: &ReadOptions,
) -> Result<Vec<crate::cloud::Point>> {
    let r = std::io::Cursor::new(bytes.to_vec());
    Ok(read_points::<Vec<Point>, _>(path, r, bytes.len() as u64, opts)?.1)
}

/// The one dispatch behind [`read_cloud_with`] and [`parse_bytes`]: detect (or take) the
/// format, then stream or read whole as the format allows. `len`: the source's size.
fn read_points<S: PointStore, R: BufRead + Seek + Send + Sync + 'static>(
    path: &Path,
    mut r: R,
    len: u64,
    opts: &ReadOptions,
) -> Result<(Format, S::Out)> {
    let fmt = match opts.format {
        Some(f) => f,
        None => detect(path, &mut r)?,
    };
    // The streamed formats fill the store as they decode; the others give a list.
    let points = match fmt {
        Format::Ply if opts.mesh_samples.is_some() => sampled(
            path,
            opts,
            ply::parse_ply_mesh(path, &read_all(path, r, len)?)?,
        )?,
        Format::Ply => return Ok((fmt, ply::read_ply_into::<S, R>(path, &mut r, Some(len))?)),
        Format::Pcd => return Ok((fmt, pcd::read_pcd_into::<S, R>(path, &mut r, Some(len))?)),
        Format::KittiBin => return Ok((fmt, kitti::read_kitti_into::<S, R>(path, &mut r, len)?)),
        #[cfg(feature = "las")]
        Format::Las => return Ok((fmt, las::read_las_into::<S, R>(path, r)?)),
        #[cfg(feature = "e57")]
        Format::E57 => e57::read_e57(path, r, opts.e57)?,
        #[cfg(feature = "npz")]
        Format::Npz => npz::read_npz_points(path, r, opts.npz_array.as_deref())?,
        Format::Obj => sampled(path, opts, mesh::parse_obj(path, &read_all(path, r, len)?)?)?,
        Format::Stl => sampled(path, opts, mesh::parse_stl(path, &read_all(path, r, len)?)?)?,
        Format::Text => return Ok((fmt, xyz::read_xyz_into::<S, R>(path, r, Some(len))?)),
        Format::Npy => npy::points_of(path, &npy::parse_npy(path, &read_all(path, r, len)?)?)?,
        #[cfg(not(all(feature = "las", feature = "e57", feature = "npz")))]
        other => return Err(not_built(path, other)),
    };
    Ok((fmt, S::from_vec(points)))
}

/// Write a point cloud in the format of `format`, or of the path's extension: PLY (binary
/// little endian, doubles), PCD (binary, doubles), XYZ/TXT/PTS (text, round-trip precision),
/// NPY (float64 N×3), KITTI `.bin` (float32, reflectance 0), LAS/LAZ (32-bit integers
/// with a per-file scale: see [`las::write_las`]) or E57 (one scan, f64). CSV gets a
/// comma-free text layout too (`x y z` per line), which ggs and most tools read. Atomic.
pub fn write_cloud(
    path: &Path,
    points: &[crate::cloud::Point],
    format: Option<Format>,
) -> Result<()> {
    let fmt = format
        .or_else(|| Format::from_extension(path))
        .ok_or_else(|| GgsError::UnknownFormat {
            path: path.to_path_buf(),
            what: format!("(writable: {WRITABLE})"),
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
        #[cfg(feature = "las")]
        Format::Las => las::write_las(path, points),
        #[cfg(feature = "e57")]
        Format::E57 => e57::write_e57(path, &[e57::E57Scan { points, pose: None }]),
        Format::Obj | Format::Stl | Format::Npz => Err(GgsError::UnknownFormat {
            path: path.to_path_buf(),
            what: format!("(meshes and .npz are read, not written; writable: {WRITABLE})"),
        }),
        #[cfg(not(all(feature = "las", feature = "e57")))]
        other => Err(not_built(path, other)),
    }
}

/// The error for a format whose support this build of ggs leaves out (a cargo feature off).
#[cfg(not(all(feature = "las", feature = "e57", feature = "npz")))]
fn not_built(path: &Path, format: Format) -> GgsError {
    let (what, feature) = match format {
        Format::Las => ("LAS/LAZ", "las"),
        Format::E57 => ("E57", "e57"),
        _ => (".npz", "npz"),
    };
    GgsError::in_file(
        path,
        format!("{what} support is not built into this ggs (cargo feature `{feature}`)"),
    )
}

/// Colour of the target in an overlay: blue.
pub const OVERLAY_TARGET_RGB: [u8; 3] = [40, 110, 255];
/// Colour of the moved source in an overlay: orange.
pub const OVERLAY_SOURCE_RGB: [u8; 3] = [255, 140, 0];

/// Writes the target and the source moved by `transform` into one coloured PLY (target
/// blue, source orange), to look at the alignment in any viewer. Atomic.
pub fn write_overlay(
    path: &Path,
    source: &crate::cloud::Cloud,
    target: &crate::cloud::Cloud,
    transform: &crate::transform::Rigid,
) -> Result<()> {
    let mut pts = target.to_points();
    pts.extend(source.iter().map(|p| transform.apply(&p)));
    let mut colors = vec![OVERLAY_TARGET_RGB; target.len()];
    colors.extend(std::iter::repeat_n(OVERLAY_SOURCE_RGB, source.len()));
    ply::write_ply(path, &pts, Some(&colors), Default::default())
}

/// Extensions [`write_cloud`] writes.
pub const WRITABLE: &str = ".ply, .pcd, .xyz/.txt/.pts/.csv, .npy, .bin, .las, .laz, .e57";

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
    fn a_streamed_cloud_is_the_cloud_of_the_exact_points() {
        // 200k points: binary PLY of doubles takes two read chunks, the text file none.
        let dir = std::env::temp_dir().join(format!("ggs-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut r = crate::test_rng::uniform(3);
        let pts: Vec<Point> = (0..200_000)
            .map(|_| [6e5 + 50.0 * r(), 4.2e6 + 30.0 * r(), 10.0 * r()])
            .collect();
        for ext in ["ply", "pcd", "bin", "las", "xyz"] {
            let p = dir.join(format!("s.{ext}"));
            write_cloud(&p, &pts, None).unwrap();
            let exact = read_exact_points(&p, None).unwrap().points;
            let cloud = read_cloud(&p, None).unwrap().cloud;
            assert_eq!(cloud, Cloud::new(exact), "{ext}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn every_writable_format_round_trips() {
        let dir = std::env::temp_dir().join(format!("ggs-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pts = vec![
            [0.1, -2.5e-7, 1234.5678901234567],
            [-3.0, 1.0 / 3.0, 0.0],
            [6e5, 4.2e6, -12.25],
        ];
        for ext in ["ply", "pcd", "xyz", "txt", "pts", "csv", "npy", "e57"] {
            let p = dir.join(format!("c.{ext}"));
            write_cloud(&p, &pts, None).unwrap();
            let back = read_exact_points(&p, None).unwrap().points;
            assert_eq!(back, pts, "{ext}");
        }
        // KITTI stores float32.
        let p = dir.join("c.bin");
        write_cloud(&p, &pts, None).unwrap();
        let back = read_exact_points(&p, None).unwrap().points;
        for (a, b) in back.iter().zip(&pts) {
            for k in 0..3 {
                assert_eq!(a[k], b[k] as f32 as f64);
            }
        }
        // LAS/LAZ store integers with a power-of-ten scale spanning the box in 2^31 steps.
        for ext in ["las", "laz"] {
            let p = dir.join(format!("c.{ext}"));
            write_cloud(&p, &pts, None).unwrap();
            let back = read_exact_points(&p, None).unwrap().points;
            let b = crate::cloud::bounds(&pts).unwrap();
            for (p, q) in back.iter().zip(&pts) {
                for k in 0..3 {
                    let tol = 0.5 * las::las_scale(b.max[k] - b.min[k]) * (1.0 + 1e-12);
                    assert!((p[k] - q[k]).abs() <= tol, "{ext}: {p:?} vs {q:?}");
                }
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
    fn a_failed_atomic_write_keeps_the_file_that_was_there() {
        let d = tmpdir("atomic-failure");
        let path = d.join("keep.txt");
        std::fs::write(&path, "old").unwrap();
        // The temporary file cannot be created (a folder is in its place): the write fails,
        // names the file, and the old content stays.
        let blocker = d.join(format!(".keep.txt.{}.tmp", std::process::id()));
        std::fs::create_dir(&blocker).unwrap();
        let e = write_atomic(&path, b"new").unwrap_err().to_string();
        assert!(e.contains("keep.txt"), "{e}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        std::fs::remove_dir(&blocker).unwrap();
        // The rename fails (a non-empty folder is the destination): no temporary file is
        // left behind, the folder is untouched.
        let dest = d.join("dest");
        std::fs::create_dir_all(dest.join("inside")).unwrap();
        assert!(write_atomic(&dest, b"new").is_err());
        assert!(dest.join("inside").is_dir());
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .filter(|n| n.ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        // And a successful write replaces the file.
        write_atomic(&path, b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        std::fs::remove_dir_all(&d).unwrap();
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
    fn magic_bytes_of_every_format_with_one() {
        let cases: [(&[u8], Option<Format>); 10] = [
            (b"ply\nformat ascii 1.0\n", Some(Format::Ply)),
            (b"ply\r\nformat ascii 1.0\r\n", Some(Format::Ply)),
            (b"\x93NUMPY\x01\x00", Some(Format::Npy)),
            (b"PK\x03\x04\x14\x00", Some(Format::Npz)),
            (b"LASF\x00\x00", Some(Format::Las)),
            (b"ASTM-E57\x00\x00", Some(Format::E57)),
            (b"# .PCD v0.7\nVERSION 0.7\n", Some(Format::Pcd)),
            (b"solid part\n  facet normal 0 0 1\n", Some(Format::Stl)),
            // A binary STL whose 80-byte header starts with "solid": not text after it.
            (b"solid exported by a CAD tool\0\0\x10\xff facet", None),
            (b"1.0 2.0 3.0\n", None),
        ];
        for (bytes, want) in cases {
            assert_eq!(
                Format::from_magic(bytes),
                want,
                "{:?}",
                String::from_utf8_lossy(bytes)
            );
        }
        // The extension decides for text, OBJ and KITTI; --format names every format.
        for name in FORMAT_NAMES.split(", ") {
            assert!(Format::from_name(name).is_some(), "{name}");
        }
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
            read_exact_points(&p, None).unwrap().points,
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
