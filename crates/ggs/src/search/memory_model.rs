//! What the large buffers of a search cost, and the error for a search that does not fit.

use super::blocks::Coords;
use super::geometry::Geometry;
use super::sized::SizedPlans;
use super::voxel;
use crate::error::GgsError;
use crate::memory;

/// Bytes per source point: the centred triple and its coordinate arrays.
const POINT_BYTES: u64 = 24 + Coords::BYTES_PER_POINT as u64;

/// What the large buffers of a search cost, and which voxel size makes them fit.
pub(super) struct MemoryModel {
    pub target_extent: [f64; 3],
    /// Largest distance of a source point from the centroid: every rotated source grid has
    /// at most `floor(2·radius/s) + 1` cells per axis.
    pub source_radius: f64,
    pub threads: usize,
    pub points: usize,
}

impl MemoryModel {
    /// Kernel spectra (f32 and f64, and the smaller f32 plans of [`SizedPlans`]), one
    /// workspace per thread (the f64 one, the larger of the two a worker holds at a time),
    /// kernel occupancy and the centred points ([`POINT_BYTES`] each).
    pub fn bytes(&self, geo: &Geometry) -> u64 {
        let cells = geo
            .kernel_dims
            .iter()
            .fold(1u64, |a, &d| a.saturating_mul(d as u64));
        geo.kernel_bytes(4)
            .saturating_add(geo.kernel_bytes(8))
            .saturating_add(SizedPlans::bytes_bound(geo))
            .saturating_add((self.threads as u64).saturating_mul(geo.workspace_bytes(8)))
            .saturating_add(cells)
            .saturating_add((self.points as u64).saturating_mul(POINT_BYTES))
    }

    /// Upper bound of `bytes` at voxel `s`, from the source's bounding sphere.
    fn bound_at(&self, s: f64) -> Option<(Geometry, u64)> {
        let nr = voxel::grid_dims(self.target_extent, s).ok()?;
        let ns = voxel::axis_cells(2.0 * self.source_radius, s);
        let geo = Geometry::new(nr, [ns; 3]);
        Some((geo, self.bytes(&geo)))
    }

    /// The error for a search that does not fit, with a voxel size that does (by the bound).
    pub fn error(&self, geo: &Geometry, need: u64, budget: u64, voxel: f64) -> GgsError {
        let mut suggested = voxel;
        for _ in 0..2000 {
            suggested *= 1.02;
            if self.bound_at(suggested).is_some_and(|(_, b)| b <= budget) {
                break;
            }
        }
        // Round up to 3 significant digits so the printed value still fits.
        let unit = 10f64.powf(suggested.log10().floor() - 2.0);
        let suggested = (suggested / unit).ceil() * unit;
        let digits = (2.0 - suggested.log10().floor()).max(0.0) as usize;
        let suggested = format!("{suggested:.digits$}");
        GgsError::MemoryBudget(format!(
            "the search needs about {} (FFT grid {}×{}×{} for kernel {}×{}×{} and source up to {}×{}×{}, {} thread(s)) but the budget is {}; use a voxel size of at least {} (now {voxel}), fewer threads, or raise --max-memory",
            memory::human_bytes(need),
            geo.fft_len[0], geo.fft_len[1], geo.fft_len[2],
            geo.kernel_dims[0], geo.kernel_dims[1], geo.kernel_dims[2],
            geo.source_max[0], geo.source_max[1], geo.source_max[2],
            self.threads,
            memory::human_bytes(budget),
            suggested,
        ))
    }
}
