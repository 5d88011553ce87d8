//! A search made ready: the request checked, the target's box and kernel size, the source
//! centred (or its representatives), the rotations as rows, the memory model and budget.

use super::config::{SearchConfig, SearchMode};
use super::correlator::RotatedSources;
use super::extents::{rows, RotatedBox};
use super::geometry::Geometry;
use super::memory_model::MemoryModel;
use super::rotated::RotatableCloud;
use super::source::representatives;
use super::voxel;
use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::memory;
use crate::rotations::RotationSet;
use std::time::Duration;

/// Milliseconds of `d`.
pub(super) fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Refuses a bad voxel, `top_k = 0`, an empty set, bad coarse-to-fine parameters and empty
/// clouds, before any work.
pub(super) fn validate(
    source: &Cloud,
    target: &Cloud,
    set: &RotationSet,
    cfg: &SearchConfig,
) -> Result<()> {
    let s = cfg.voxel;
    if !(s.is_finite() && s > 0.0) {
        return Err(GgsError::param(
            "voxel",
            format!("must be a positive number, got {s}"),
        ));
    }
    if cfg.top_k == 0 {
        return Err(GgsError::param("top_k", "must be at least 1"));
    }
    if set.is_empty() {
        return Err(GgsError::param("rotations", "the rotation set is empty"));
    }
    if let SearchMode::CoarseToFine(c) = &cfg.mode {
        c.validate()?;
    }
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")?;
    Ok(())
}

/// Both clouds made ready for the search: the target's box and kernel dims, the centred
/// source (or its representatives), the rotations as rows, the memory model and budget.
pub(super) struct Prepared {
    /// Min corner of the target's box: the kernel's origin.
    pub target_min: Point,
    /// Kernel dims at the voxel.
    pub kernel_dims: [usize; 3],
    pub source: RotatableCloud,
    pub rows: Vec<[[f64; 3]; 3]>,
    pub sizes: MemoryModel,
    pub budget: u64,
    pub voxel: f64,
}

impl Prepared {
    pub(super) fn new(
        source: &Cloud,
        target: &Cloud,
        set: &RotationSet,
        cfg: &SearchConfig,
        threads: usize,
    ) -> Result<Self> {
        let s = cfg.voxel;
        let budget = cfg.max_memory.unwrap_or_else(memory::default_budget);
        let tb = target.aabb().ok_or_else(|| GgsError::EmptyCloud {
            what: "target".into(),
            detail: String::new(),
        })?;
        let kernel_dims = voxel::grid_dims(tb.extent(), s)?;
        let reps = representatives(source, s);
        let rc = RotatableCloud::new(reps.as_ref().unwrap_or(source));
        let radius = rc
            .points
            .iter()
            .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
            .fold(0.0, f64::max);
        let sizes = MemoryModel {
            target_extent: tb.extent(),
            source_radius: radius,
            threads,
            points: rc.points.len(),
        };
        let early = Geometry::new(kernel_dims, [1, 1, 1]);
        let early_bytes = sizes.bytes(&early);
        if early_bytes > budget {
            return Err(sizes.error(&early, early_bytes, budget, s));
        }
        Ok(Prepared {
            target_min: tb.min,
            kernel_dims,
            source: rc,
            rows: set.matrices.iter().map(rows).collect(),
            sizes,
            budget,
            voxel: s,
        })
    }

    /// The rotated sources with the extents `boxes`.
    pub fn sources<'a>(&'a self, boxes: &'a [Option<RotatedBox>]) -> RotatedSources<'a> {
        RotatedSources {
            cloud: &self.source,
            rows: &self.rows,
            boxes,
            voxel: self.voxel,
        }
    }
}
