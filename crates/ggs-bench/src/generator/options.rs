//! The generator's settings as a front end receives them (names and plain numbers), checked
//! once here for every front end and turned into a [`GeneratorConfig`].

use super::crops::CropConfig;
use super::presets::{OverlapBand, Preset, PRESET_NAMES};
use super::viewpoints::{Centre, ViewConfig};
use super::{parse_cameras, GeneratorConfig, SampleSize};
use ggs::error::{GgsError, Result};
use std::path::Path;

/// The settings of `ggs partial`, unchecked.
#[derive(Debug, Clone)]
pub struct GeneratorOptions<'a> {
    /// Ground-truth preset: fpv1, fpv1-code, fp-{r,t,o}-{e,m,h}, scene-{e,m,h}.
    pub preset: &'a str,
    pub seed: u64,
    /// Points sampled on each mesh (default 100 000), unless `spacing` is given.
    pub points: Option<usize>,
    /// Mean sampling spacing instead (positive, the scans' units after scaling).
    pub spacing: Option<f64>,
    /// Use a mesh's vertices as its points.
    pub vertices: bool,
    /// Icosphere subdivisions, at most 6.
    pub subdivisions: u32,
    /// Icosphere radius (positive).
    pub radius: f64,
    /// `centroid` or `origin`.
    pub centre: &'a str,
    /// `x`, `y` or `z`.
    pub up: &'a str,
    /// Keep the first K above-floor cameras (0: all); a scene preset draws K crops (K ≥ 2).
    pub views: usize,
    /// Scene presets: crop radius as a share of the scene's extent
    /// (`crops::robust_diagonal`), in (0, 1].
    pub crop: f64,
    /// A file of camera positions (x y z per line) instead of the icosphere.
    pub cameras: Option<&'a Path>,
    /// Overlap band overrides, percent, within [0, 100]; the preset's band fills the other.
    pub min_overlap: Option<f64>,
    pub max_overlap: Option<f64>,
    /// Hidden point removal radius factor (positive).
    pub flip_factor: f64,
    /// Voxel written into the manifest (positive).
    pub voxel: f64,
    pub threads: usize,
}

/// `v` if it is a positive number, else an error naming `name`.
pub fn positive(name: &'static str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(GgsError::param(
            name,
            format!("must be a positive number, got {v}"),
        ))
    }
}

impl GeneratorOptions<'_> {
    /// The checked configuration; every error names its setting.
    pub fn config(&self) -> Result<GeneratorConfig> {
        let preset = Preset::from_name(self.preset).ok_or_else(|| {
            GgsError::param(
                "preset",
                format!(
                    "unknown preset '{}' (known: {})",
                    self.preset,
                    PRESET_NAMES.join(", ")
                ),
            )
        })?;
        let sample = match (self.points, self.spacing) {
            (_, Some(s)) => SampleSize::Spacing(positive("spacing", s)?),
            (Some(n), None) => SampleSize::Count(n),
            (None, None) => SampleSize::Count(100_000),
        };
        Ok(GeneratorConfig {
            seed: self.seed,
            overlap: self.overlap(preset)?,
            preset,
            views: self.view_config()?,
            sample,
            mesh_vertices: self.vertices,
            flip_factor: positive("flip factor", self.flip_factor)?,
            crops: self.crop_config(preset)?,
            voxel: positive("voxel", self.voxel)?,
            threads: self.threads,
        })
    }

    /// The preset's overlap band with the overrides, `None` without any.
    fn overlap(&self, preset: Preset) -> Result<Option<OverlapBand>> {
        if self.min_overlap.is_none() && self.max_overlap.is_none() {
            return Ok(None);
        }
        let band = preset.overlap();
        let b = OverlapBand {
            min: self.min_overlap.unwrap_or(band.min),
            max: self.max_overlap.unwrap_or(band.max),
        };
        if !(0.0..=100.0).contains(&b.min) || !(0.0..=100.0).contains(&b.max) || b.min > b.max {
            return Err(GgsError::param(
                "overlap",
                format!(
                    "[{}, {}] is not a range within [0, 100] (min and max overlap)",
                    b.min, b.max
                ),
            ));
        }
        Ok(Some(b))
    }

    /// How a scene preset crops: `views` crops of radius `crop ×` the scene's extent.
    fn crop_config(&self, preset: Preset) -> Result<CropConfig> {
        if !(self.crop.is_finite() && self.crop > 0.0 && self.crop <= 1.0) {
            return Err(GgsError::param(
                "crop",
                format!(
                    "must lie in (0, 1] (a share of the scene's extent), got {}",
                    self.crop
                ),
            ));
        }
        if preset.is_scene() && self.views < 2 {
            return Err(GgsError::param(
                "views",
                format!(
                    "a scene preset draws this many crops, at least 2 (got {})",
                    self.views
                ),
            ));
        }
        Ok(CropConfig {
            share: self.crop,
            count: self.views,
        })
    }

    /// Where the cameras are: the icosphere's settings or the file's positions.
    fn view_config(&self) -> Result<ViewConfig> {
        let centre = match self.centre {
            "centroid" => Centre::Centroid,
            "origin" => Centre::Origin,
            other => {
                return Err(GgsError::param(
                    "centre",
                    format!("'{other}' is not centroid or origin"),
                ))
            }
        };
        let up = match self.up {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            other => return Err(GgsError::param("up", format!("'{other}' is not x, y or z"))),
        };
        if self.subdivisions > 6 {
            return Err(GgsError::param(
                "subdivisions",
                format!(
                    "{} is too many (at most 6: 40 962 cameras)",
                    self.subdivisions
                ),
            ));
        }
        let cameras = match self.cameras {
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(|e| GgsError::io(p, e))?;
                Some(parse_cameras(p, &text)?)
            }
            None => None,
        };
        Ok(ViewConfig {
            subdivisions: self.subdivisions,
            radius: positive("radius", self.radius)?,
            centre,
            up,
            first: (self.views > 0).then_some(self.views),
            cameras,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options() -> GeneratorOptions<'static> {
        GeneratorOptions {
            preset: "fpv1",
            seed: 3,
            points: None,
            spacing: None,
            vertices: false,
            subdivisions: 1,
            radius: 1.5,
            centre: "centroid",
            up: "y",
            views: 12,
            crop: 0.4,
            cameras: None,
            min_overlap: None,
            max_overlap: None,
            flip_factor: 1000.0,
            voxel: 0.06,
            threads: 0,
        }
    }

    #[test]
    fn the_defaults_give_the_default_config_with_their_seed() {
        let cfg = options().config().unwrap();
        assert_eq!(
            cfg,
            GeneratorConfig {
                seed: 3,
                ..GeneratorConfig::default()
            }
        );
    }

    #[test]
    fn each_bad_setting_is_named() {
        let cases: [(GeneratorOptions, &str); 10] = [
            (
                GeneratorOptions {
                    crop: 1.5,
                    ..options()
                },
                "crop: must lie in (0, 1]",
            ),
            (
                GeneratorOptions {
                    preset: "scene-h",
                    views: 1,
                    ..options()
                },
                "views: a scene preset draws this many crops",
            ),
            (
                GeneratorOptions {
                    preset: "fp-z-e",
                    ..options()
                },
                "unknown preset 'fp-z-e'",
            ),
            (
                GeneratorOptions {
                    centre: "middle",
                    ..options()
                },
                "centre",
            ),
            (
                GeneratorOptions {
                    up: "w",
                    ..options()
                },
                "up",
            ),
            (
                GeneratorOptions {
                    subdivisions: 7,
                    ..options()
                },
                "subdivisions",
            ),
            (
                GeneratorOptions {
                    radius: 0.0,
                    ..options()
                },
                "radius",
            ),
            (
                GeneratorOptions {
                    spacing: Some(-1.0),
                    ..options()
                },
                "spacing",
            ),
            (
                GeneratorOptions {
                    voxel: f64::NAN,
                    ..options()
                },
                "voxel",
            ),
            (
                GeneratorOptions {
                    min_overlap: Some(70.0),
                    max_overlap: Some(60.0),
                    ..options()
                },
                "not a range",
            ),
        ];
        for (o, want) in cases {
            let e = o.config().unwrap_err().to_string();
            assert!(e.contains(want), "{e} (wanted {want})");
        }
    }

    #[test]
    fn one_overlap_bound_keeps_the_presets_other() {
        let o = GeneratorOptions {
            preset: "fp-o-m",
            max_overlap: Some(50.0),
            ..options()
        };
        let band = o.config().unwrap().overlap.unwrap();
        assert_eq!(band.max, 50.0);
        assert_eq!(band.min, Preset::from_name("fp-o-m").unwrap().overlap().min);
    }
}
