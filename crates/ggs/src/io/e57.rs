//! E57 (ASTM E2807) laser-scan files through the maintained `e57` crate (pure Rust, no
//! unsafe code). A file holds several scans, each in its own frame with an optional pose
//! (unit quaternion + translation) into the file's frame: `p_file = R(q)·p_scan + t`.
//! Spherical scans are converted to Cartesian by the crate.

use crate::cloud::Point;
use crate::error::{GgsError, Result};
use crate::transform::Rigid;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::io::{Read, Seek};
use std::path::Path;

pub use super::scans::E57Options;

/// What a scan of an E57 file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct E57ScanInfo {
    pub name: Option<String>,
    /// Records (points, valid or not).
    pub records: u64,
    /// The scan's pose into the file's frame; `None` when the file gives none (identity).
    pub pose: Option<Rigid>,
}

fn crate_error(path: &Path, what: &str, e: e57::Error) -> GgsError {
    GgsError::in_file(path, format!("E57 {what}: {e}"))
}

/// The pose of a scan, from its (possibly unnormalized) quaternion; a zero or non-finite
/// quaternion is an error.
fn pose(path: &Path, k: usize, t: &e57::Transform) -> Result<Rigid> {
    let q = Quaternion::new(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z);
    let norm = q.norm();
    if !(norm.is_finite() && norm > 1e-12) {
        return Err(GgsError::in_file(
            path,
            format!(
                "E57 scan {k}: pose quaternion (w {}, x {}, y {}, z {}) is not a rotation (expected a non-zero, finite quaternion)",
                q.w, q.i, q.j, q.k
            ),
        ));
    }
    let tr = Vector3::new(t.translation.x, t.translation.y, t.translation.z);
    if !tr.iter().all(|v| v.is_finite()) {
        return Err(GgsError::in_file(
            path,
            format!("E57 scan {k}: pose translation {tr:?} is not finite"),
        ));
    }
    let r = UnitQuaternion::from_quaternion(q).to_rotation_matrix();
    Ok(Rigid::new(*r.matrix(), tr))
}

/// The scans of an E57 file, in file order.
pub fn e57_scans<R: Read + Seek>(path: &Path, r: R) -> Result<Vec<E57ScanInfo>> {
    let reader = e57::E57Reader::new(r).map_err(|e| crate_error(path, "header", e))?;
    reader
        .pointclouds()
        .iter()
        .enumerate()
        .map(|(k, pc)| {
            Ok(E57ScanInfo {
                name: pc.name.clone(),
                records: pc.records,
                pose: pc
                    .transform
                    .as_ref()
                    .map(|t| pose(path, k, t))
                    .transpose()?,
            })
        })
        .collect()
}

/// Read the points of an E57 file. Points the file marks invalid (no coordinates, or a
/// direction only) come back as NaN, so that [`crate::io::read_cloud`] drops and counts
/// them.
pub fn read_e57<R: Read + Seek>(path: &Path, mut r: R, opts: E57Options) -> Result<Vec<Point>> {
    let file_len = super::stream::stream_len(&mut r).map_err(|e| GgsError::io(path, e))?;
    let mut reader = e57::E57Reader::new(r).map_err(|e| crate_error(path, "header", e))?;
    let clouds = reader.pointclouds();
    let chosen: Vec<usize> = match opts.scan {
        Some(k) if k >= clouds.len() => {
            return Err(GgsError::in_file(
                path,
                format!(
                    "E57: scan {k} asked for, the file holds {} scan(s) (numbered from 0)",
                    clouds.len()
                ),
            ))
        }
        Some(k) => vec![k],
        None => (0..clouds.len()).collect(),
    };
    let total: u64 = chosen.iter().map(|&k| clouds[k].records).sum();
    // The record counts come from the file: reserve no more than one point per byte.
    let mut out = Vec::with_capacity(total.min(file_len) as usize);
    for k in chosen {
        let pc = &clouds[k];
        if !pc.has_cartesian() && !pc.has_spherical() {
            return Err(GgsError::in_file(
                path,
                format!("E57 scan {k}: no Cartesian or spherical coordinates in its prototype"),
            ));
        }
        let pose = match (&pc.transform, opts.apply_pose) {
            (Some(t), true) => Some(pose(path, k, t)?),
            _ => None,
        };
        let what = format!("scan {k}");
        let mut points = reader
            .pointcloud_simple(pc)
            .map_err(|e| crate_error(path, &what, e))?;
        points.apply_pose(false);
        points.spherical_to_cartesian(true);
        points.intensity_to_color(false);
        let before = out.len();
        for (i, p) in points.enumerate() {
            let p = p.map_err(|e| crate_error(path, &format!("{what}, point {i}"), e))?;
            let q = match p.cartesian {
                e57::CartesianCoordinate::Valid { x, y, z } => [x, y, z],
                _ => [f64::NAN; 3],
            };
            out.push(match &pose {
                Some(t) => t.apply(&q),
                None => q,
            });
        }
        let read = (out.len() - before) as u64;
        if read != pc.records {
            return Err(GgsError::in_file(
                path,
                format!(
                    "E57 {what}: the file declares {} records, its data holds {read}",
                    pc.records
                ),
            ));
        }
    }
    Ok(out)
}

/// One scan to write: its points in its own frame, and its pose into the file's frame.
#[derive(Debug, Clone, Copy)]
pub struct E57Scan<'a> {
    pub points: &'a [Point],
    pub pose: Option<&'a Rigid>,
}

/// Write scans as an E57 file (Cartesian f64 coordinates; one data set per scan, with its
/// pose), atomically.
pub fn write_e57(path: &Path, scans: &[E57Scan]) -> Result<()> {
    let err = |e: e57::Error| crate_error(path, "writer", e);
    let mut bytes = std::io::Cursor::new(Vec::new());
    {
        let mut w = e57::E57Writer::new(&mut bytes, "ggs-e57-file").map_err(err)?;
        for (k, scan) in scans.iter().enumerate() {
            let prototype = vec![
                e57::Record::CARTESIAN_X_F64,
                e57::Record::CARTESIAN_Y_F64,
                e57::Record::CARTESIAN_Z_F64,
            ];
            let mut pc = w
                .add_pointcloud(&format!("ggs-scan-{k}"), prototype)
                .map_err(err)?;
            pc.set_name(Some(format!("scan {k}")));
            if let Some(t) = scan.pose {
                let q = UnitQuaternion::from_matrix(&t.rotation);
                pc.set_transform(Some(e57::Transform {
                    rotation: e57::Quaternion {
                        w: q.w,
                        x: q.i,
                        y: q.j,
                        z: q.k,
                    },
                    translation: e57::Translation {
                        x: t.translation.x,
                        y: t.translation.y,
                        z: t.translation.z,
                    },
                }));
            }
            for p in scan.points {
                pc.add_point(p.iter().map(|&v| e57::RecordValue::Double(v)).collect())
                    .map_err(err)?;
            }
            pc.finalize().map_err(err)?;
        }
        w.finalize().map_err(err)?;
    }
    super::write_atomic(path, &bytes.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use std::io::Cursor;

    fn rz90() -> Rigid {
        Rigid::new(
            Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
            Vector3::new(10.0, 0.0, -1.0),
        )
    }

    fn two_scans(dir: &Path) -> std::path::PathBuf {
        let p = dir.join("two.e57");
        let a = [[1.0, 2.0, 3.0], [-0.5, 0.25, 1e-3]];
        let b = [[1.0, 0.0, 0.0]];
        let pose = rz90();
        write_e57(
            &p,
            &[
                E57Scan {
                    points: &a,
                    pose: None,
                },
                E57Scan {
                    points: &b,
                    pose: Some(&pose),
                },
            ],
        )
        .unwrap();
        p
    }

    #[test]
    fn scans_poses_and_selection() {
        let dir = std::env::temp_dir().join(format!("ggs-e57-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = two_scans(&dir);
        let bytes = std::fs::read(&p).unwrap();
        let all = read_e57(&p, Cursor::new(&bytes), E57Options::default()).unwrap();
        assert_eq!(all.len(), 3);
        assert_eq!(all[0], [1.0, 2.0, 3.0]);
        assert_eq!(all[1], [-0.5, 0.25, 1e-3]);
        // (1,0,0) turned 90° about z, then moved by (10, 0, -1).
        let moved = all[2];
        for (v, want) in moved.iter().zip([10.0, 1.0, -1.0]) {
            assert!((v - want).abs() < 1e-12, "{moved:?}");
        }
        let local = read_e57(
            &p,
            Cursor::new(&bytes),
            E57Options {
                scan: Some(1),
                apply_pose: false,
            },
        )
        .unwrap();
        assert_eq!(local, vec![[1.0, 0.0, 0.0]]);
        let info = e57_scans(&p, Cursor::new(&bytes)).unwrap();
        assert_eq!(info.len(), 2);
        assert_eq!(info[0].records, 2);
        assert!(info[0].pose.is_none());
        let r = info[1].pose.unwrap().rotation;
        assert!((r - rz90().rotation).norm() < 1e-12);
        let e = read_e57(
            &p,
            Cursor::new(&bytes),
            E57Options {
                scan: Some(2),
                apply_pose: true,
            },
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("two.e57") && e.contains("scan 2") && e.contains("2 scan"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn corrupt_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("ggs-e57c-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = two_scans(&dir);
        let bytes = std::fs::read(&p).unwrap();
        // Not an E57 file at all.
        let e = read_e57(
            &p,
            Cursor::new(b"ASTM-E57 but short"),
            E57Options::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("two.e57") && e.contains("E57 header"), "{e}");
        // Truncated.
        let cut = &bytes[..bytes.len() / 2];
        assert!(read_e57(&p, Cursor::new(cut), E57Options::default()).is_err());
        // A flipped byte in a page fails its checksum.
        let mut bad = bytes.clone();
        bad[1500] ^= 0xff;
        assert!(read_e57(&p, Cursor::new(&bad), E57Options::default()).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn zero_quaternion_is_refused() {
        let t = e57::Transform {
            rotation: e57::Quaternion {
                w: 0.0,
                x: 0.0,
                y: 0.0,
                z: 0.0,
            },
            translation: e57::Translation::default(),
        };
        let e = pose(Path::new("s.e57"), 3, &t).unwrap_err().to_string();
        assert!(
            e.contains("s.e57") && e.contains("scan 3") && e.contains("quaternion"),
            "{e}"
        );
    }
}

/// One unit test per error path the crate's own checks do not make unreachable.
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::File;
    use std::io::Cursor;

    fn read(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        read_e57(path, Cursor::new(b), E57Options::default())
    }

    fn scan_5(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        read_e57(
            path,
            Cursor::new(b),
            E57Options {
                scan: Some(5),
                apply_pose: true,
            },
        )
    }

    fn one_scan() -> Vec<u8> {
        let dir = std::env::temp_dir().join(format!("ggs-e57e-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(format!("{:?}.e57", std::thread::current().id()));
        let pts: Vec<Point> = (0..2000).map(|i| [i as f64, 1.0, 2.0]).collect();
        write_e57(
            &p,
            &[E57Scan {
                points: &pts,
                pose: None,
            }],
        )
        .unwrap();
        let b = std::fs::read(&p).unwrap();
        let _ = std::fs::remove_file(&p);
        b
    }

    fn translation(path: &Path, _: &[u8]) -> Result<Rigid> {
        let t = e57::Transform {
            rotation: e57::Quaternion {
                w: 1.0,
                x: 0.0,
                y: 0.0,
                z: 0.0,
            },
            translation: e57::Translation {
                x: f64::NAN,
                y: 0.0,
                z: 0.0,
            },
        };
        pose(path, 0, &t)
    }

    error_cases! { read;
        not_e57: b"ASTM-E57 but nothing after" => File, "E57 header";
        page_checksum: { let mut b = one_scan(); b[2000] ^= 0x40; b } => File, "E57";
    }

    error_cases! { scan_5;
        scan_out_of_range: one_scan() => File, "scan 5 asked for, the file holds 1 scan(s)";
    }

    error_cases! { translation;
        translation_not_finite: b"" => File, "scan 0: pose translation";
    }
}
