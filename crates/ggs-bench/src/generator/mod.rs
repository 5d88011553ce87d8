//! The FAUST-partial benchmark generator (docs/generator.md): partial views of scans or meshes by
//! hidden point removal from cameras on an icosphere, view pairs filtered by overlap, and a
//! seeded ground-truth motion per pair.
//!
//! Stages, one module each: [`sampling`] (meshes → points), [`viewpoints`] (cameras),
//! [`hpr`] over [`hull`] (visible points), or [`crops`] for the scene presets, [`overlap`],
//! [`presets`] (ground truth), and [`output`] (views, manifest, summary on disk). [`fpv1`]
//! rebuilds the published pairs.
//!
//! Everything random comes from [`rng::Rng::stream`] keyed by the seed and what is drawn
//! (scan, view pair), so a seed gives the same benchmark, byte for byte, on any thread count.

pub mod crops;
pub mod fpv1;
pub mod hpr;
pub mod hull;
pub mod options;
pub mod output;
pub mod overlap;
pub mod presets;
pub use ggs::mesh::sampling;
pub use ggs::rng;
pub mod viewpoints;

use ggs::cloud::Point;
use ggs::error::{GgsError, Result};
use ggs::io::{self, mesh::Mesh, Format};
use ggs::transform::Rigid;
use presets::{OverlapBand, Preset};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use viewpoints::ViewConfig;

/// How many points a mesh is sampled to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SampleSize {
    Count(usize),
    /// Mean spacing in the mesh's units after scaling: `⌈area / spacing²⌉` points.
    Spacing(f64),
}

/// One input scan or mesh and its own settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanInput {
    pub path: PathBuf,
    /// Name used in file names and pair names (default: the file stem).
    pub name: String,
    /// Multiplies the coordinates (0.1 for a mesh in decimetres, 0.001 for millimetres).
    pub scale: f64,
    /// OBJ group to keep (`body` for the MakeHuman base mesh).
    pub group: Option<String>,
    /// Icosphere radius for this scan (else the configuration's).
    pub radius: Option<f64>,
    /// Voxel size written to the manifest for this scan's pairs (else the configuration's).
    pub voxel: Option<f64>,
    /// Sampling for a mesh (else the configuration's).
    pub sample: Option<SampleSize>,
}

impl ScanInput {
    /// A scan with default settings, named after its file stem.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        let path = path.into();
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scan".into());
        ScanInput {
            path,
            name,
            scale: 1.0,
            group: None,
            radius: None,
            voxel: None,
            sample: None,
        }
    }
}

/// Settings of a generated benchmark.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratorConfig {
    pub seed: u64,
    pub preset: Preset,
    /// Overrides the preset's overlap band.
    pub overlap: Option<OverlapBand>,
    pub views: ViewConfig,
    /// Sampling of meshes (point clouds are used as they are).
    pub sample: SampleSize,
    /// Use a mesh's vertices as its points instead of sampling its surface (a FAUST scan
    /// stored as a PLY mesh, used as the published FPv1 used it).
    pub mesh_vertices: bool,
    /// Flip radius factor: R = factor × the scan's bounding-box diagonal (1000 in the FAUST-partial protocol).
    pub flip_factor: f64,
    /// How the scene presets crop their views.
    pub crops: crops::CropConfig,
    /// Voxel size written to the manifest (6 cm for human bodies).
    pub voxel: f64,
    pub threads: usize,
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        GeneratorConfig {
            seed: 0,
            preset: Preset::Fpv1,
            overlap: None,
            views: ViewConfig::default(),
            sample: SampleSize::Count(100_000),
            mesh_vertices: false,
            flip_factor: 1000.0,
            crops: crops::CropConfig::default(),
            voxel: 0.06,
            threads: 0,
        }
    }
}

/// A scan and what its cameras see.
#[derive(Debug, Clone)]
pub struct ScanViews {
    pub name: String,
    /// The scan's points (scaled; sampled if the input was a mesh), in its own frame.
    pub points: Vec<Point>,
    /// True when the points were sampled from a mesh.
    pub sampled: bool,
    /// `p_floor = p + floor_offset`.
    pub floor_offset: Point,
    /// Camera positions, floor frame.
    pub cameras: Vec<Point>,
    /// The id of each view (its index in the camera list, or the published index when
    /// rebuilding FPv1), used in file and pair names.
    pub view_ids: Vec<u32>,
    /// Visible point indices per camera, ascending.
    pub visible: Vec<Vec<u32>>,
    pub voxel: f64,
    /// Hull eyes skipped for rounding trouble, over all views.
    pub hull_skipped: usize,
}

/// One generated pair: target = T · view i, source = view j, so `p_target = T · p_source`.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratedPair {
    pub name: String,
    /// The scan's name.
    pub scan: String,
    /// View ids (see [`ScanViews::view_ids`]).
    pub view_i: u32,
    pub view_j: u32,
    /// `|I_i ∩ I_j| / |I_i| × 100`.
    pub overlap: f64,
    /// Euler 'xyz' angles of T, degrees.
    pub euler_deg: [f64; 3],
    pub transform: Rigid,
    pub voxel: f64,
}

/// Read a scan: a mesh (OBJ, STL, or PLY with faces) is sampled on its surface, a point
/// cloud is used as it is; both are scaled.
pub fn load_scan(input: &ScanInput, cfg: &GeneratorConfig) -> Result<(Vec<Point>, bool)> {
    let path = &input.path;
    if !(input.scale.is_finite() && input.scale > 0.0) {
        return Err(GgsError::param(
            "scale",
            format!("must be positive, got {}", input.scale),
        ));
    }
    let fmt = Format::from_extension(path);
    // A file that may hold a mesh is parsed once; without faces its vertices are the cloud.
    let mut vertices_only: Option<Vec<Point>> = None;
    let mesh: Option<Mesh> = match fmt {
        Some(Format::Obj) | Some(Format::Stl) | Some(Format::Ply) if !cfg.mesh_vertices => {
            let bytes = std::fs::read(path).map_err(|e| GgsError::io(path, e))?;
            let m = match fmt {
                Some(Format::Obj) => io::mesh::parse_obj(path, &bytes)?,
                Some(Format::Stl) => io::mesh::parse_stl(path, &bytes)?,
                _ => io::ply::parse_ply_mesh(path, &bytes)?,
            };
            if m.triangles.is_empty() {
                vertices_only = Some(m.vertices);
                None
            } else {
                Some(m)
            }
        }
        _ => None,
    };
    if input.group.is_some() && mesh.is_none() {
        return Err(GgsError::in_file(
            path,
            if cfg.mesh_vertices {
                "a group cannot be selected when a mesh's vertices are used as they are"
            } else {
                "a group was asked for, but the file is not a mesh with faces"
            },
        ));
    }
    let scale = |p: Point| p.map(|c| c * input.scale);
    match mesh {
        Some(m) => Ok((sample_mesh(input, cfg, m)?, true)),
        None => {
            let points = match vertices_only {
                // As read_cloud does: points with a NaN or infinite coordinate are dropped.
                Some(v) => v
                    .into_iter()
                    .filter(|p| p.iter().all(|c| c.is_finite()))
                    .collect(),
                None => io::read_exact_points(path, None)?.points,
            };
            if points.is_empty() {
                return Err(GgsError::EmptyCloud {
                    what: path.display().to_string(),
                    detail: String::new(),
                });
            }
            Ok((points.into_iter().map(scale).collect(), false))
        }
    }
}

/// Points sampled on a mesh (its group, if one is asked for), scaled, seeded by the scan's
/// name: as many as asked for, or as the spacing asks for.
fn sample_mesh(input: &ScanInput, cfg: &GeneratorConfig, mut m: Mesh) -> Result<Vec<Point>> {
    let path = &input.path;
    if let Some(g) = &input.group {
        m = m.group(g).map_err(|e| GgsError::in_file(path, e))?;
    }
    for v in &mut m.vertices {
        *v = v.map(|c| c * input.scale);
    }
    let count = match input.sample.unwrap_or(cfg.sample) {
        SampleSize::Count(n) => n,
        SampleSize::Spacing(s) => {
            if !(s.is_finite() && s > 0.0) {
                return Err(GgsError::param(
                    "spacing",
                    format!("must be positive, got {s}"),
                ));
            }
            sampling::count_for_spacing(&m, s)
        }
    };
    if count < 4 {
        return Err(GgsError::param(
            "points",
            format!("{count} samples are too few for a view (at least 4)"),
        ));
    }
    let seed = rng::Rng::stream(cfg.seed, &[0x5343_414e, name_tag(&input.name)]).next_u64();
    sampling::sample_surface(&m, count, seed).map_err(|e| GgsError::in_file(path, e))
}

/// A stable 64-bit tag of a name (FNV-1a), so streams depend on the scan's name, not on
/// its position in the input list.
pub fn name_tag(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// Load a scan and compute its views (views in parallel on `cfg.threads`): crops of it for a
/// scene preset, else what the cameras around it see.
pub fn scan_views(input: &ScanInput, cfg: &GeneratorConfig) -> Result<ScanViews> {
    let (points, sampled) = load_scan(input, cfg)?;
    if cfg.preset.is_scene() {
        return scene_views(input, points, sampled, cfg);
    }
    views_of_points(&input.name, points, sampled, input, cfg, None)
}

/// The views of a scene: its crops (an input's `radius` is its crop radius), the crop centres
/// as cameras, no floor offset.
pub fn scene_views(
    input: &ScanInput,
    points: Vec<Point>,
    sampled: bool,
    cfg: &GeneratorConfig,
) -> Result<ScanViews> {
    let radius = crops::crop_radius(&points, input.radius, &cfg.crops).ok_or_else(|| {
        GgsError::in_file(
            &input.path,
            "the crop radius is not a positive number (are all points the same?)",
        )
    })?;
    let mut rng = rng::Rng::stream(cfg.seed, &[0x4352_4f50, name_tag(&input.name)]);
    let c = crops::scene_crops(&points, radius, &cfg.crops, &mut rng);
    if c.indices.len() < 2 {
        return Err(GgsError::in_file(
            &input.path,
            format!(
                "fewer than two of {} crops of radius {radius} hold {} points or more; give a \
                 larger crop (--crop, or radius= in the inputs list)",
                cfg.crops.count,
                crops::MIN_CROP_POINTS
            ),
        ));
    }
    Ok(ScanViews {
        name: input.name.clone(),
        points,
        sampled,
        floor_offset: [0.0; 3],
        cameras: c.centres,
        view_ids: c.ids,
        visible: c.indices,
        voxel: input.voxel.unwrap_or(cfg.voxel),
        hull_skipped: 0,
    })
}

/// Views of given points. `cameras` overrides the configuration's cameras (floor frame).
pub fn views_of_points(
    name: &str,
    points: Vec<Point>,
    sampled: bool,
    input: &ScanInput,
    cfg: &GeneratorConfig,
    cameras: Option<Vec<Point>>,
) -> Result<ScanViews> {
    if points.len() < 4 {
        return Err(GgsError::EmptyCloud {
            what: input.path.display().to_string(),
            detail: format!(" (fewer than 4 points: {})", points.len()),
        });
    }
    let mut vc = cfg.views.clone();
    if let Some(r) = input.radius {
        vc.radius = r;
    }
    if !(vc.radius.is_finite() && vc.radius > 0.0) {
        return Err(GgsError::param(
            "radius",
            format!("must be positive, got {}", vc.radius),
        ));
    }
    let cameras = cameras.unwrap_or_else(|| viewpoints::cameras(&points, &vc));
    if cameras.is_empty() {
        return Err(GgsError::param(
            "views",
            format!("{name}: no camera above the floor"),
        ));
    }
    let offset = viewpoints::floor_offset(&points);
    let floor: Vec<Point> = points
        .iter()
        .map(|p| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]])
        .collect();
    let radius = hpr::flip_radius(&floor, cfg.flip_factor);
    let (pool, _) = ggs::threads::pool(cfg.threads)?;
    let visible: Vec<hpr::Visible> = pool
        .install(|| {
            cameras
                .par_iter()
                .map(|c| hpr::visible_points(&floor, c, radius))
                .collect::<std::result::Result<Vec<_>, String>>()
        })
        .map_err(|e| GgsError::in_file(&input.path, e))?;
    Ok(ScanViews {
        name: name.to_string(),
        points,
        sampled,
        floor_offset: offset,
        view_ids: (0..cameras.len() as u32).collect(),
        cameras,
        hull_skipped: visible.iter().map(|v| v.skipped).sum(),
        visible: visible.into_iter().map(|v| v.indices).collect(),
        voxel: input.voxel.unwrap_or(cfg.voxel),
    })
}

/// The pairs of one scan: every i < j whose overlap lies in the band, each with a ground
/// truth drawn from the stream `(seed, scan name, i, j)`.
pub fn scan_pairs(views: &ScanViews, cfg: &GeneratorConfig) -> Vec<GeneratedPair> {
    let band = cfg.overlap.unwrap_or_else(|| cfg.preset.overlap());
    let mut out = Vec::new();
    for i in 0..views.visible.len() {
        for j in i + 1..views.visible.len() {
            let o = overlap::overlap_percent(&views.visible[i], &views.visible[j]);
            if !band.contains(o) {
                continue;
            }
            let (vi, vj) = (views.view_ids[i], views.view_ids[j]);
            let mut r = rng::Rng::stream(
                cfg.seed,
                &[0x5041_4952, name_tag(&views.name), vi as u64, vj as u64],
            );
            let (angles, t) = cfg.preset.draw(&mut r);
            out.push(GeneratedPair {
                name: format!("{}_{vi}_{vj}", views.name),
                scan: views.name.clone(),
                view_i: vi,
                view_j: vj,
                overlap: o,
                euler_deg: angles,
                transform: presets::rigid(angles, t),
                voxel: views.voxel,
            });
        }
    }
    out
}

/// What [`generate`] produced.
#[derive(Debug, Clone)]
pub struct Generated {
    pub summary: output::Summary,
    pub pairs: Vec<GeneratedPair>,
    /// Hull eyes skipped for rounding trouble, over all views (expected 0).
    pub hull_skipped: usize,
}

/// Generate a benchmark from `inputs` into `out` (which [`output::prepare_out`] should have
/// checked). `progress(done, total, scan name)` is called after each scan.
pub fn generate(
    inputs: &[ScanInput],
    cfg: &GeneratorConfig,
    out: &Path,
    mut progress: impl FnMut(usize, usize, &str),
) -> Result<Generated> {
    check_names(inputs)?;
    let mut all_pairs = Vec::new();
    let mut scans = Vec::new();
    let mut view_csv = String::new();
    let mut hull_skipped = 0;
    for (k, input) in inputs.iter().enumerate() {
        let views = scan_views(input, cfg)?;
        let pairs = scan_pairs(&views, cfg);
        scans.push(output::write_scan(out, &views, &pairs)?);
        view_csv.push_str(&output::view_rows(&views));
        hull_skipped += views.hull_skipped;
        all_pairs.extend(pairs);
        progress(k + 1, inputs.len(), &input.name);
    }
    let summary = output::Summary::of(&cfg.preset.name(), cfg.seed, scans, &all_pairs);
    let band = cfg.overlap.unwrap_or_else(|| cfg.preset.overlap());
    let comment = format!(
        "generated by ggs partial {}: preset {}, seed {}, overlap [{}, {}], {}",
        env!("CARGO_PKG_VERSION"),
        cfg.preset.name(),
        cfg.seed,
        band.min,
        band.max,
        views_comment(cfg)
    );
    output::write_index(out, &comment, &all_pairs, &view_csv, &summary)?;
    Ok(Generated {
        summary,
        pairs: all_pairs,
        hull_skipped,
    })
}

/// How the views were made, for the manifest's comment line.
fn views_comment(cfg: &GeneratorConfig) -> String {
    if cfg.preset.is_scene() {
        return format!(
            "{} crops of radius {} × the scene's extent",
            cfg.crops.count, cfg.crops.share
        );
    }
    let v = &cfg.views;
    format!(
        "icosphere {} subdivisions, radius {}, first {}, flip factor {}",
        v.subdivisions,
        v.radius,
        v.first.map_or("all".to_string(), |k| k.to_string()),
        cfg.flip_factor
    )
}

/// Check that scan names are distinct and usable in file names.
pub fn check_names(inputs: &[ScanInput]) -> Result<()> {
    let mut seen = std::collections::HashSet::new();
    for s in inputs {
        if s.name.is_empty() || s.name.contains(['/', '\\', '\t', '\n']) || s.name.starts_with('.')
        {
            return Err(GgsError::param(
                "inputs",
                format!("{}: unusable scan name '{}'", s.path.display(), s.name),
            ));
        }
        if !seen.insert(s.name.clone()) {
            return Err(GgsError::param(
                "inputs",
                format!(
                    "two inputs are named '{}' (the file stem); rename one with name=",
                    s.name
                ),
            ));
        }
    }
    Ok(())
}

/// Parse an inputs list: one scan per line, `PATH [key=value …]` with keys `name`, `scale`,
/// `group`, `radius`, `voxel`, `points`, `spacing`; `#` starts a comment; paths are relative
/// to the list's folder.
pub fn parse_inputs_list(path: &Path, text: &str) -> Result<Vec<ScanInput>> {
    let base = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let n = k + 1;
        let mut tok = line.split_whitespace();
        let file = tok.next().expect("non-empty line");
        let p = Path::new(file);
        let mut s = ScanInput::new(if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        });
        for kv in tok {
            let (key, value) = kv.split_once('=').ok_or_else(|| {
                GgsError::at_line(path, n, format!("expected key=value, found '{kv}'"))
            })?;
            let num = |what: &str| -> Result<f64> {
                value
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v > 0.0)
                    .ok_or_else(|| {
                        GgsError::at_line(
                            path,
                            n,
                            format!("{what}: '{value}' is not a positive number"),
                        )
                    })
            };
            match key {
                "name" => s.name = value.to_string(),
                "scale" => s.scale = num("scale")?,
                "group" => s.group = Some(value.to_string()),
                "radius" => s.radius = Some(num("radius")?),
                "voxel" => s.voxel = Some(num("voxel")?),
                "spacing" => s.sample = Some(SampleSize::Spacing(num("spacing")?)),
                "points" => {
                    s.sample = Some(SampleSize::Count(value.parse().map_err(|_| {
                        GgsError::at_line(path, n, format!("points: '{value}' is not a count"))
                    })?))
                }
                other => {
                    return Err(GgsError::at_line(
                        path,
                        n,
                        format!(
                            "unknown key '{other}' (name, scale, group, radius, voxel, points, spacing)"
                        ),
                    ))
                }
            }
        }
        out.push(s);
    }
    if out.is_empty() {
        return Err(GgsError::in_file(path, "lists no input"));
    }
    Ok(out)
}

/// Parse a camera file: one `x y z` per line (floor frame), `#` comments.
pub fn parse_cameras(path: &Path, text: &str) -> Result<Vec<Point>> {
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        GgsError::at_line(path, k + 1, format!("'{t}' is not a finite number"))
                    })
            })
            .collect::<Result<_>>()?;
        if v.len() != 3 {
            return Err(GgsError::at_line(
                path,
                k + 1,
                format!("expected 3 numbers (x y z), found {}", v.len()),
            ));
        }
        out.push([v[0], v[1], v[2]]);
    }
    if out.is_empty() {
        return Err(GgsError::in_file(path, "lists no camera"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_list_parses_and_reports_lines() {
        let p = Path::new("/data/list.txt");
        let v = parse_inputs_list(
            p,
            "# bodies\nhuman_man.obj\nbase.obj scale=0.1 group=body  # MakeHuman\n/abs/n.obj name=nef voxel=0.02 spacing=0.004\n",
        )
        .unwrap();
        assert_eq!(v.len(), 3);
        assert_eq!(v[0].path, Path::new("/data/human_man.obj"));
        assert_eq!(v[1].scale, 0.1);
        assert_eq!(v[1].group.as_deref(), Some("body"));
        assert_eq!(v[2].name, "nef");
        assert_eq!(v[2].sample, Some(SampleSize::Spacing(0.004)));
        let e = parse_inputs_list(p, "a.obj\nb.obj scale=-1\n").unwrap_err();
        assert!(e.to_string().contains("line 2") && e.to_string().contains("scale"));
        let e = parse_inputs_list(p, "a.obj colour=red\n").unwrap_err();
        assert!(e.to_string().contains("unknown key 'colour'"));
        assert!(parse_inputs_list(p, "# nothing\n").is_err());
    }

    #[test]
    fn camera_file() {
        let p = Path::new("cams.txt");
        assert_eq!(
            parse_cameras(p, "1 2 3\n# c\n4,5,6\n").unwrap(),
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
        );
        let e = parse_cameras(p, "1 2 3\n1 2\n").unwrap_err();
        assert!(e.to_string().contains("line 2"));
        assert!(parse_cameras(p, "1 2 x\n").is_err());
    }

    #[test]
    fn duplicate_names_are_refused() {
        let a = ScanInput::new("x/a.obj");
        let b = ScanInput::new("y/a.ply");
        assert!(check_names(&[a.clone(), b]).is_err());
        assert!(check_names(&[a]).is_ok());
    }
}
