//! Out-of-place matrix transposes in square tiles: the layout changes between the
//! correlator's transforms along z, y and x (`search::cpu`), where each axis must be
//! contiguous for its FFT. Values are copied, never combined, so results do not depend on
//! the tiling.

/// Tile edge: a tile's 4 source rows are read as 4 short runs and its 4 destination rows
/// written as 4 short runs, instead of one strided access per element (measured on the
/// correlator's `f32` spectra, 8-byte elements: see docs/performance.md).
const TILE: usize = 4;

/// `dst[c·ds + r] = src[r·ss + c]` for `r < rows`, `c < cols`.
///
/// Panics if a slice is too short for the strides (a caller's bug).
pub(super) fn transpose<T: Copy>(
    src: &[T],
    ss: usize,
    dst: &mut [T],
    ds: usize,
    rows: usize,
    cols: usize,
) {
    if rows == 0 || cols == 0 {
        return;
    }
    let whole_rows = rows - rows % TILE;
    let whole_cols = cols - cols % TILE;
    for r0 in (0..whole_rows).step_by(TILE) {
        let run = |i: usize| &src[(r0 + i) * ss..(r0 + i) * ss + cols];
        let runs: [&[T]; TILE] = std::array::from_fn(run);
        for c0 in (0..whole_cols).step_by(TILE) {
            for j in 0..TILE {
                let column: [T; TILE] = std::array::from_fn(|i| runs[i][c0 + j]);
                let at = (c0 + j) * ds + r0;
                dst[at..at + TILE].copy_from_slice(&column);
            }
        }
        for c in whole_cols..cols {
            let column: [T; TILE] = std::array::from_fn(|i| runs[i][c]);
            let at = c * ds + r0;
            dst[at..at + TILE].copy_from_slice(&column);
        }
    }
    for r in whole_rows..rows {
        let run = &src[r * ss..r * ss + cols];
        for (c, &v) in run.iter().enumerate() {
            dst[c * ds + r] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every shape up to 9 × 9 with padded strides, against the element-wise definition;
    /// cells outside the transposed block stay untouched.
    #[test]
    fn equals_the_definition_and_writes_nothing_else() {
        for rows in 0..10 {
            for cols in 0..10 {
                let (ss, ds) = (cols + 3, rows + 2);
                let src: Vec<u32> = (0..rows * ss).map(|i| i as u32 + 1).collect();
                let mut dst = vec![0u32; cols.max(1) * ds];
                transpose(&src, ss, &mut dst, ds, rows, cols);
                let mut want = vec![0u32; dst.len()];
                for r in 0..rows {
                    for c in 0..cols {
                        want[c * ds + r] = src[r * ss + c];
                    }
                }
                assert_eq!(dst, want, "{rows} × {cols}");
            }
        }
    }
}
