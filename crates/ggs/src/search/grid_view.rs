//! The sample types and grid views shared by voxelization (`rotated`) and correlation
//! (`correlate`), below both so that neither imports the other.

use rustfft::num_traits::Float;
use rustfft::FftNum;

/// Sample type of a correlator and of the grids it reads: f32 or f64.
pub trait Real: FftNum + Float + Default {
    /// Unit roundoff `u = 2^−p` of the type (2^−24 for f32, 2^−53 for f64).
    const UNIT_ROUNDOFF: f64;
}
impl Real for f32 {
    const UNIT_ROUNDOFF: f64 = 5.960_464_477_539_063e-8;
}
impl Real for f64 {
    const UNIT_ROUNDOFF: f64 = 1.110_223_024_625_156_5e-16;
}

/// A source grid to voxelize into: cell `(i, j, k)` is `cells[i·sx + j·sy + k]`.
pub struct GridView<'a, T> {
    pub cells: &'a mut [T],
    pub sx: usize,
    pub sy: usize,
}
