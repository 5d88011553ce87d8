//! A uniform grid of cubic cells over a cloud, for the exact neighbour searches of refinement
//! whose radius is about one cell:
//!
//! - the k nearest neighbours of every point of the cloud ([`CellGrid::map_knn`]): the points
//!   of one cell share their candidates (the 3×3×3 block of cells around it), and a point's
//!   answer is certified when its k-th distance does not exceed its distance to the block's
//!   boundary (no point outside the block can then be nearer); uncertified points (sparse
//!   regions, block edges) are answered by the k-d tree, so the result is always exact;
//! - the nearest point within a radius `r` ([`CellGrid::nearest_within`]), scanning the cells
//!   that meet the cube of half-side `r` around the query.
//!
//! Cell `(i, j, k)` of size `h` covers `origin + h·[i, i+1) × [j, j+1) × [k, k+1)`, with
//! `origin` the lower corner of the cloud's bounding box. The points are ordered by (cell key,
//! index); occupied cells are found through a dense table of every cell's first point when the
//! box has at most 64 cells a point (or 65 536 cells), else through a table of every (x, y)
//! column's occupied cells when it has at most 8 columns a point, else through an
//! open-addressing hash table, so memory grows with the points, not with the box.

use super::neighbors::PointIndex;
use crate::cloud::Point;
use crate::num::floor_i64;
use rayon::prelude::*;

/// At most this many cells per axis (so a linear cell key fits 60 bits).
const MAX_DIM: u64 = 1 << 20;
/// Cells handed to one parallel task by [`CellGrid::map_knn`].
const CELLS_PER_TASK: usize = 64;
const EMPTY: u64 = u64::MAX;
/// Cell size for k-NN searches, in median k-th-neighbour distances (measured on the bunny
/// scans: smaller cells certify fewer points, larger ones scan more candidates).
pub const KNN_CELL_FACTOR: f64 = 1.6;

/// Dense cell tables (a start offset for every cell of the box, empty or not) are kept up
/// to 64 cells per point, or this many cells (256 kB) for small clouds.
const DENSE_CELLS: u64 = 1 << 16;

/// Point indices in the order of (key, index), and for every key `k < cells` the number of
/// points with a smaller key (`cells + 1` entries): a counting sort, O(points + cells).
fn counting_order(keys: &[u64], cells: usize) -> (Vec<u32>, Vec<u32>) {
    let mut starts = vec![0u32; cells + 1];
    for &k in keys {
        starts[k as usize + 1] += 1;
    }
    for c in 1..=cells {
        starts[c] += starts[c - 1];
    }
    // Each key's entry serves as its cursor, ending at the next key's start; shifted back
    // by one entry after.
    let mut order = vec![0u32; keys.len()];
    for (i, &k) in keys.iter().enumerate() {
        let cursor = &mut starts[k as usize];
        order[*cursor as usize] = i as u32;
        *cursor += 1;
    }
    starts.copy_within(0..cells, 1);
    starts[0] = 0;
    (order, starts)
}

/// `columns[col]..columns[col + 1]`: the indices of the occupied cells (sorted `keys`) in
/// column `col = key / dims[2]`.
fn column_starts(keys: &[u64], dims: [u64; 3]) -> Vec<u32> {
    let n_columns = (dims[0] * dims[1]) as usize;
    let mut columns = Vec::with_capacity(n_columns + 1);
    for (c, &key) in keys.iter().enumerate() {
        columns.resize((key / dims[2]) as usize + 1, c as u32);
    }
    columns.resize(n_columns + 1, keys.len() as u32);
    columns
}

/// Occupied cells of a grid, hashed by linear key.
struct CellTable {
    keys: Vec<u64>,
    cells: Vec<u32>,
    shift: u32,
}

impl CellTable {
    fn new(keys: &[u64]) -> Self {
        let capacity = (2 * keys.len()).next_power_of_two().max(2);
        let mut t = CellTable {
            keys: vec![EMPTY; capacity],
            cells: vec![0; capacity],
            shift: 64 - capacity.trailing_zeros(),
        };
        for (c, &key) in keys.iter().enumerate() {
            let mut s = t.slot(key);
            while t.keys[s] != EMPTY {
                s = (s + 1) & (capacity - 1);
            }
            t.keys[s] = key;
            t.cells[s] = c as u32;
        }
        t
    }

    #[inline]
    fn slot(&self, key: u64) -> usize {
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    #[inline]
    fn get(&self, key: u64) -> Option<usize> {
        let mask = self.keys.len() - 1;
        let mut s = self.slot(key);
        loop {
            match self.keys[s] {
                k if k == key => return Some(self.cells[s] as usize),
                EMPTY => return None,
                _ => s = (s + 1) & mask,
            }
        }
    }
}

/// Points of a cloud bucketed into cubic cells.
pub struct CellGrid {
    h: f64,
    inv_h: f64,
    origin: [f64; 3],
    dims: [u64; 3],
    /// Original indices of the points, sorted by (cell key, index).
    order: Vec<u32>,
    /// The points in that order.
    sorted: Vec<Point>,
    /// Cell `c` holds `sorted[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    /// Integer coordinates of each occupied cell.
    coords: Vec<[u64; 3]>,
    table: CellTable,
    /// When the box has few enough cells: `dense[key]..dense[key + 1]` are the sorted
    /// positions of the points in the cell with that linear key, so a run of cells along z
    /// is one contiguous range.
    dense: Option<Vec<u32>>,
    /// Without a dense table, when the box has few enough columns: the occupied cells of
    /// column `(i, j)` (linear index `i·dims[1] + j`) are `columns[col]..columns[col + 1]`, in
    /// increasing z, and their points are one contiguous run of sorted points.
    columns: Option<Vec<u32>>,
}

impl CellGrid {
    /// Bucket `points` into cells of size `h`; `None` when `h` is not a positive finite size
    /// or the box would need more than 2^20 cells along an axis (the caller then uses the
    /// k-d tree alone).
    pub fn new(points: &[Point], h: f64) -> Option<Self> {
        Self::with_dense_limit(points, h, DENSE_CELLS.max(64 * points.len() as u64))
    }

    /// [`Self::new`] with a dense cell table only when the box has at most `dense_limit`
    /// cells, else a column table when it has at most `dense_limit / 8` columns (4 bytes a
    /// column: at most 32 bytes a point beside the 36 of its copy and order), else the hash
    /// table alone.
    fn with_dense_limit(points: &[Point], h: f64, dense_limit: u64) -> Option<Self> {
        if !(h.is_finite() && h > 0.0) || points.is_empty() || points.len() > u32::MAX as usize {
            return None;
        }
        let crate::cloud::Aabb { min: lo, max: hi } = crate::cloud::bounds(points)?;
        let inv_h = 1.0 / h;
        let mut dims = [0u64; 3];
        for a in 0..3 {
            let n = ((hi[a] - lo[a]) * inv_h).floor() + 1.0;
            if !(n.is_finite() && n <= MAX_DIM as f64) {
                return None;
            }
            dims[a] = n as u64;
        }
        let mut grid = CellGrid {
            h,
            inv_h,
            origin: lo,
            dims,
            order: Vec::new(),
            sorted: Vec::new(),
            start: Vec::new(),
            coords: Vec::new(),
            table: CellTable::new(&[]),
            dense: None,
            columns: None,
        };
        let point_keys: Vec<u64> = points.iter().map(|p| grid.key(&grid.cell_of(p))).collect();
        let total = dims[0] * dims[1] * dims[2];
        let dense = total <= dense_limit;
        // The order of (cell key, index): by counting where the dense table is built anyway
        // (one pass over the cells), by sorting otherwise ([`crate::order::by_key`]).
        let (order, dense_starts) = if dense {
            let (order, starts) = counting_order(&point_keys, total as usize);
            (order, Some(starts))
        } else {
            let order = crate::order::by_key(&point_keys);
            (order.into_iter().map(|i| i as u32).collect(), None)
        };
        let mut keys = Vec::new();
        grid.sorted = Vec::with_capacity(order.len());
        for (s, &i) in order.iter().enumerate() {
            let key = point_keys[i as usize];
            if keys.last() != Some(&key) {
                keys.push(key);
                grid.start.push(s as u32);
                grid.coords.push(grid.cell_of(&points[i as usize]));
            }
            grid.sorted.push(points[i as usize]);
        }
        grid.start.push(order.len() as u32);
        grid.order = order;
        grid.dense = dense_starts;
        if !dense && dims[0] * dims[1] <= dense_limit / 8 {
            grid.columns = Some(column_starts(&keys, dims));
        }
        // The hash serves only a grid with neither table.
        if grid.dense.is_none() && grid.columns.is_none() {
            grid.table = CellTable::new(&keys);
        }
        Some(grid)
    }

    /// Cell size.
    #[cfg(feature = "internals")]
    pub fn cell_size(&self) -> f64 {
        self.h
    }

    /// Number of occupied cells.
    pub fn cells(&self) -> usize {
        self.coords.len()
    }

    /// Number of points in occupied cell `cell`.
    pub fn cell_len(&self, cell: usize) -> usize {
        self.range(cell).len()
    }

    /// Cell coordinates of a point of the cloud (clamped into the box against rounding).
    #[inline]
    fn cell_of(&self, p: &Point) -> [u64; 3] {
        let mut c = [0u64; 3];
        for a in 0..3 {
            let x = floor_i64((p[a] - self.origin[a]) * self.inv_h);
            c[a] = (x.max(0) as u64).min(self.dims[a] - 1);
        }
        c
    }

    #[inline]
    fn key(&self, c: &[u64; 3]) -> u64 {
        (c[0] * self.dims[1] + c[1]) * self.dims[2] + c[2]
    }

    /// The occupied cells of column `(i, j)` (inside the box) with z in `k0..=k1`, as a range
    /// of cell indices (empty if none), from the column table `columns`.
    #[inline]
    fn column_cells(
        &self,
        columns: &[u32],
        i: i64,
        j: i64,
        k0: i64,
        k1: i64,
    ) -> std::ops::Range<usize> {
        let col = (i as u64 * self.dims[1] + j as u64) as usize;
        let (start, end) = (columns[col] as usize, columns[col + 1] as usize);
        // A column holds a few cells on a surface, in increasing z: a linear walk.
        let z = |c: &&[u64; 3]| c[2] as i64;
        let below = self.coords[start..end].iter().take_while(|c| z(c) < k0);
        let first = start + below.count();
        let within = self.coords[first..end].iter().take_while(|c| z(c) <= k1);
        first..first + within.count()
    }

    /// The sorted positions of the points of cells `(i, j, k0..=k1)` (inside the box): one
    /// run, since those cells' keys are consecutive. Found through whichever table the grid
    /// keeps: the dense one (two entries), the column one (a walk along the column) or the
    /// hash (a probe per cell).
    #[inline(always)]
    fn column_run(&self, i: i64, j: i64, k0: i64, k1: i64) -> std::ops::Range<usize> {
        let key = |k: i64| self.key(&[i as u64, j as u64, k as u64]) as usize;
        if let Some(dense) = &self.dense {
            return dense[key(k0)] as usize..dense[key(k1) + 1] as usize;
        }
        let cells = if let Some(columns) = &self.columns {
            self.column_cells(columns, i, j, k0, k1)
        } else {
            let mut found = (k0..=k1).filter_map(|k| self.table.get(key(k) as u64));
            match found.next() {
                Some(first) => first..found.next_back().unwrap_or(first) + 1,
                None => 0..0,
            }
        };
        if cells.is_empty() {
            return 0..0;
        }
        self.start[cells.start] as usize..self.start[cells.end] as usize
    }

    #[inline]
    fn range(&self, cell: usize) -> std::ops::Range<usize> {
        self.start[cell] as usize..self.start[cell + 1] as usize
    }

    /// The nearest point within squared distance `r2` of `q` (inclusive): its original index
    /// and squared distance; ties go to the lowest index. Scans every cell meeting the cube
    /// `q ± r`, so it is meant for `r` up to a few cells.
    pub fn nearest_within(&self, q: &Point, r2: f64) -> Option<(usize, f64)> {
        // A relative margin so that rounding in the cell arithmetic never drops a cell.
        let r = r2.sqrt() * (1.0 + 1e-9) + 1e-12 * self.h;
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        for a in 0..3 {
            lo[a] = floor_i64((q[a] - r - self.origin[a]) * self.inv_h).max(0);
            hi[a] =
                floor_i64((q[a] + r - self.origin[a]) * self.inv_h).min(self.dims[a] as i64 - 1);
            if lo[a] > hi[a] {
                return None;
            }
        }
        // The best so far as (index, squared distance), starting from the sentinel
        // (usize::MAX, r2): a point at exactly r2 still wins it, so no separate radius test,
        // and no Option in the loop. The minimum of (d2, index) over the points within r2
        // does not depend on the scan order.
        let (mut best_i, mut best_d2) = (usize::MAX, r2);
        let mut scan = |range: std::ops::Range<usize>| {
            let (sorted, order) = (&self.sorted[range.clone()], &self.order[range]);
            for (p, &idx) in sorted.iter().zip(order) {
                let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if d2 < best_d2 || (d2 == best_d2 && (idx as usize) < best_i) {
                    (best_i, best_d2) = (idx as usize, d2);
                }
            }
        };
        // Squared distance from q to the slab of cells i (or j) along one axis.
        let gap2 = |a: usize, i: i64| {
            let cell_lo = self.origin[a] + i as f64 * self.h;
            let g = (cell_lo - q[a]).max(q[a] - (cell_lo + self.h)).max(0.0);
            g * g
        };
        for i in lo[0]..=hi[0] {
            let gi = gap2(0, i);
            for j in lo[1]..=hi[1] {
                // Columns whose xy distance from q exceeds r hold no candidate (the bound is
                // made loose by the same margin as the range).
                if gi + gap2(1, j) > r * r {
                    continue;
                }
                scan(self.column_run(i, j, lo[2], hi[2]));
            }
        }
        (best_i != usize::MAX).then_some((best_i, best_d2))
    }

    /// Mean number of points in the cell of a point (`Σ_cells count² / n`): the occupancy a
    /// query near the data meets, weighted by where the points are.
    pub fn mean_occupancy(&self) -> f64 {
        let sq: f64 = (0..self.cells())
            .map(|c| (self.range(c).len() as f64).powi(2))
            .sum();
        sq / self.order.len() as f64
    }

    /// Number of points.
    #[cfg(feature = "internals")]
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether the grid holds no point (never: [`Self::new`] refuses an empty cloud).
    #[cfg(feature = "internals")]
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// For every original point index: its cell and its position among the cell's points.
    pub fn locations(&self) -> Vec<(u32, u32)> {
        let mut loc = vec![(0u32, 0u32); self.order.len()];
        for cell in 0..self.cells() {
            for (off, s) in self.range(cell).enumerate() {
                loc[self.order[s] as usize] = (cell as u32, off as u32);
            }
        }
        loc
    }

    /// The points of the 3 × 3 × 3 block of cells around `cell` into `pts` / `idx`, and the
    /// block's min and max corners.
    fn gather_block(
        &self,
        cell: usize,
        pts: &mut Vec<Point>,
        idx: &mut Vec<u32>,
    ) -> ([f64; 3], [f64; 3]) {
        let c = self.coords[cell];
        pts.clear();
        idx.clear();
        let inside = |a: usize, v: i64| v >= 0 && (v as u64) < self.dims[a];
        let [ci, cj, ck] = c.map(|v| v as i64);
        let (k0, k1) = ((ck - 1).max(0), (ck + 1).min(self.dims[2] as i64 - 1));
        for i in (ci - 1..=ci + 1).filter(|&i| inside(0, i)) {
            for j in (cj - 1..=cj + 1).filter(|&j| inside(1, j)) {
                let r = self.column_run(i, j, k0, k1);
                pts.extend_from_slice(&self.sorted[r.clone()]);
                idx.extend_from_slice(&self.order[r]);
            }
        }
        let mut lo = [0.0; 3];
        let mut hi = [0.0; 3];
        for a in 0..3 {
            lo[a] = self.origin[a] + (c[a] as f64 - 1.0) * self.h;
            hi[a] = self.origin[a] + (c[a] as f64 + 2.0) * self.h;
        }
        (lo, hi)
    }

    /// `f(i, indices, points)` for the points of `cell` at `positions` (offsets in the cell's
    /// order, see [`Self::locations`]), with the original indices and the coordinates of its
    /// `k` nearest points (itself included; fewer if the cloud is smaller), in an order fixed
    /// by the data: a point's answer does not depend on which other positions are asked for.
    /// The cell's candidates (the 3 × 3 × 3 block around it) are gathered once. `points` and
    /// `tree` must hold the points the grid was built from; the tree answers the points the
    /// grid cannot certify. `hint` is a typical k-th-neighbour distance (a little above the
    /// median): it only speeds the search up, the answer does not depend on it.
    #[allow(clippy::too_many_arguments)]
    pub fn cell_knn_at<T>(
        &self,
        cell: usize,
        positions: impl IntoIterator<Item = usize>,
        points: &[Point],
        k: usize,
        hint: f64,
        tree: &PointIndex,
        scratch: &mut KnnScratch,
        out: &mut Vec<T>,
        f: impl Fn(usize, &[u32], &[Point]) -> T,
    ) {
        let n = self.order.len();
        debug_assert_eq!(points.len(), n, "cell_knn_at: the grid's points");
        let k = k.min(n).max(1);
        let hint2 = if hint > 0.0 {
            hint * hint
        } else {
            f64::INFINITY
        };
        let KnnScratch {
            cand_pts,
            cand_idx,
            keys,
            cand_d2,
            nbr_idx,
            nbr_pts,
        } = scratch;
        let (block_lo, block_hi) = self.gather_block(cell, cand_pts, cand_idx);
        keys.resize(cand_pts.len(), 0);
        cand_d2.resize(cand_pts.len(), 0.0);
        let cell_points = self.range(cell);
        for off in positions {
            let s = cell_points.start + off;
            debug_assert!(
                s < cell_points.end,
                "cell_knn_at: a position outside the cell"
            );
            let q = &self.sorted[s];
            let i = self.order[s] as usize;
            nbr_idx.clear();
            nbr_pts.clear();
            // Distance from q to the block's boundary, less a margin for the rounding of the
            // cell arithmetic: only candidates within it can be certified neighbours.
            let mut bd = f64::INFINITY;
            for a in 0..3 {
                bd = bd.min(q[a] - block_lo[a]).min(block_hi[a] - q[a]);
            }
            bd -= 1e-9 * self.h;
            let bd2 = if bd > 0.0 { bd * bd } else { -1.0 };
            for (d2, p) in cand_d2.iter_mut().zip(cand_pts.iter()) {
                let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                *d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            }
            let m = keys_within(cand_d2, keys, bd2, hint2, k);
            if m >= k {
                let kept = &mut keys[..m];
                if m > k {
                    kept.select_nth_unstable(k - 1);
                }
                for &key in &kept[..k] {
                    let pos = (key as u32) as usize;
                    nbr_idx.push(cand_idx[pos]);
                    nbr_pts.push(cand_pts[pos]);
                }
            } else {
                tree.for_k_nearest(q, k, |j| {
                    nbr_idx.push(j as u32);
                    nbr_pts.push(points[j]);
                });
            }
            out.push(f(i, nbr_idx, nbr_pts));
        }
    }

    /// [`Self::cell_knn_at`] for every point of the cloud, in parallel over cells; returned in
    /// the cloud's order.
    pub fn map_knn<T, F>(
        &self,
        points: &[Point],
        k: usize,
        hint: f64,
        tree: &PointIndex,
        f: F,
    ) -> Vec<T>
    where
        T: Send,
        F: Fn(usize, &[u32], &[Point]) -> T + Sync,
    {
        let n = self.order.len();
        assert_eq!(points.len(), n, "map_knn: the grid's points");
        let chunks: Vec<Vec<T>> = (0..self.cells())
            .collect::<Vec<_>>()
            .par_chunks(CELLS_PER_TASK)
            .map(|cells| {
                let mut out = Vec::new();
                let mut scratch = KnnScratch::default();
                for &cell in cells {
                    let all = 0..self.cell_len(cell);
                    self.cell_knn_at(cell, all, points, k, hint, tree, &mut scratch, &mut out, &f);
                }
                out
            })
            .collect();
        // Results are in cell order; put them back in the cloud's order.
        let mut slots: Vec<Option<T>> = (0..n).map(|_| None).collect();
        let mut s = 0;
        for chunk in chunks {
            for t in chunk {
                slots[self.order[s] as usize] = Some(t);
                s += 1;
            }
        }
        slots
            .into_iter()
            .map(|t| t.expect("every point visited once"))
            .collect()
    }
}

/// Reusable buffers of [`CellGrid::cell_knn_at`].
#[derive(Default)]
pub struct KnnScratch {
    cand_pts: Vec<Point>,
    cand_idx: Vec<u32>,
    keys: Vec<u128>,
    cand_d2: Vec<f64>,
    nbr_idx: Vec<u32>,
    nbr_pts: Vec<Point>,
}

/// A [`RadiusSearch`] uses the k-d tree when its cells would hold more points than this on
/// average ([`CellGrid::mean_occupancy`]): a query scans about four cells.
pub const MAX_RADIUS_OCCUPANCY: f64 = 32.0;

/// Cell size of a [`RadiusSearch`], in radii (measured on the bunny scans).
pub const RADIUS_CELL_FACTOR: f64 = 2.0;

/// Nearest point within a fixed radius `r`, the query of every ICP iteration: a grid of
/// cells of size `2r`, so that a query meets two cells per axis (a column farther than `r`
/// is skipped), or a k-d tree when the cloud's box is too large for such cells or they
/// would be crowded. Cells of `r` (three per axis) or less scan fewer points but look up
/// more cells, and cost more.
pub struct RadiusSearch<'a> {
    r2: f64,
    grid: Option<CellGrid>,
    tree: Option<TreeRef<'a>>,
}

enum TreeRef<'a> {
    Borrowed(&'a PointIndex),
    Owned(PointIndex),
}

impl<'a> RadiusSearch<'a> {
    /// Index `points` (not empty) for queries of radius `r` (> 0). `tree`, when given,
    /// indexes the same points and serves if the grid does not; otherwise one is built then.
    pub fn new(points: &[Point], r: f64, tree: Option<&'a PointIndex>) -> Self {
        // Where the cells would be crowded (clouds much denser in places than the radius,
        // such as LiDAR scans near the sensor) the tree, which adapts to density, is cheaper.
        let grid = CellGrid::new(points, RADIUS_CELL_FACTOR * r)
            .filter(|g| g.mean_occupancy() <= MAX_RADIUS_OCCUPANCY);
        tracing::debug!(grid = grid.is_some(), "radius search");
        let tree = match (&grid, tree) {
            (Some(_), _) => None,
            (None, Some(t)) => Some(TreeRef::Borrowed(t)),
            (None, None) => Some(TreeRef::Owned(PointIndex::new(points))),
        };
        RadiusSearch {
            r2: r * r,
            grid,
            tree,
        }
    }

    /// Index and squared distance of the nearest point within `r` of `q` (inclusive), if
    /// any; among equally near points the grid returns the lowest index.
    #[inline]
    pub fn nearest(&self, q: &Point) -> Option<(usize, f64)> {
        match (&self.grid, &self.tree) {
            (Some(g), _) => g.nearest_within(q, self.r2),
            (None, Some(TreeRef::Borrowed(t))) => t.nearest_within(q, self.r2),
            (None, Some(TreeRef::Owned(t))) => t.nearest_within(q, self.r2),
            (None, None) => unreachable!("RadiusSearch holds a grid or a tree"),
        }
    }
}

impl RadiusSearch<'_> {
    /// [`Self::nearest`] given `hint`, a point of the set (the answer of the previous ICP
    /// iteration): the same answer, found on the grid by scanning only within the hint's
    /// distance when that is less than `r`: once ICP settles, one or two cells instead of
    /// eight. Exact: every point nearer than the hint lies within it, and a point as near is
    /// included (the bound is inclusive and its distance is computed by the same expression as
    /// the scan's), so the tie still goes to the lowest index.
    #[inline]
    pub fn nearest_near(&self, q: &Point, hint: Option<&Point>) -> Option<(usize, f64)> {
        match (&self.grid, hint) {
            (Some(g), Some(h)) => {
                let d = [h[0] - q[0], h[1] - q[1], h[2] - q[2]];
                let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                g.nearest_within(q, if d2 < self.r2 { d2 } else { self.r2 })
            }
            _ => self.nearest(q),
        }
    }
}

/// The median distance to the k-th neighbour over an evenly strided sample of up to 512
/// points, or `None` for a degenerate cloud (all points equal). A k-NN grid takes cells of
/// [`KNN_CELL_FACTOR`] times this, so that most points are certified within their 3×3×3
/// block.
pub fn median_kth_distance(points: &[Point], tree: &PointIndex, k: usize) -> Option<f64> {
    let n = points.len();
    if n == 0 {
        return None;
    }
    let step = n.div_ceil(512);
    let mut d: Vec<f64> = points
        .iter()
        .step_by(step)
        .map(|p| tree.kth_distance(p, k))
        .collect();
    let m = d.len() / 2;
    d.select_nth_unstable_by(m, f64::total_cmp);
    let h = d[m] * 1.0;
    (h.is_finite() && h > 0.0).then_some(h)
}

/// Packs the candidates within the certified radius into `keys[..m]` and returns `m`.
///
/// Branch-free: every candidate is written, those within the radius are kept. Keys (d² bits,
/// position) order like (d², position) since d² ≥ 0. First within `min(bd2, hint2)` (few
/// candidates to select from), then, if that holds fewer than `k`, within `bd2`.
#[inline]
fn keys_within(d2s: &[f64], keys: &mut [u128], bd2: f64, hint2: f64, k: usize) -> usize {
    let mut m = 0;
    for limit2 in [bd2.min(hint2), bd2] {
        m = 0;
        for (pos, &d2) in d2s.iter().enumerate() {
            keys[m] = ((d2.to_bits() as u128) << 32) | pos as u128;
            m += (d2 <= limit2) as usize;
        }
        if m >= k || hint2 >= bd2 {
            break;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::Point;

    fn cloud(n: usize, seed: u64) -> Vec<Point> {
        let mut r = crate::test_rng::uniform(seed);
        // A noisy sphere plus a few far outliers: dense and sparse regions.
        let mut pts = crate::test_rng::noisy_sphere(&mut r, n);
        pts.extend((0..5).map(|i| [3.0 + i as f64, -2.0, 0.5 * i as f64]));
        pts
    }

    #[test]
    fn knn_matches_the_tree() {
        let pts = cloud(3000, 7);
        let tree = PointIndex::new(&pts);
        let k = 12;
        let h = median_kth_distance(&pts, &tree, k).unwrap() * KNN_CELL_FACTOR;
        let grid = CellGrid::new(&pts, h).unwrap();
        let got = grid.map_knn(&pts, k, h * 0.6, &tree, |i, nb, np| {
            for (j, p) in nb.iter().zip(np) {
                assert_eq!(pts[*j as usize], *p);
            }
            let mut v: Vec<u32> = nb.to_vec();
            v.sort_unstable();
            (i, v)
        });
        for (i, (gi, v)) in got.iter().enumerate() {
            assert_eq!(*gi, i);
            let mut want: Vec<u32> = tree
                .k_nearest(&pts[i], k)
                .into_iter()
                .map(|j| j as u32)
                .collect();
            want.sort_unstable();
            assert_eq!(v, &want, "point {i}");
        }
    }

    #[test]
    fn nearest_within_matches_the_tree() {
        let pts = cloud(2000, 3);
        let tree = PointIndex::new(&pts);
        let grid = CellGrid::new(&pts, 0.05).unwrap();
        let queries = cloud(500, 11);
        for r in [0.001, 0.02, 0.05, 0.12] {
            for q in &queries {
                let q = [q[0] * 1.01, q[1], q[2] + 0.003];
                let a = grid.nearest_within(&q, r * r);
                let b = tree.nearest_within(&q, r * r);
                assert_eq!(a.map(|x| x.1), b.map(|x| x.1), "r {r} q {q:?}");
            }
        }
    }

    #[test]
    fn hashed_column_and_dense_grids_agree() {
        let pts = cloud(3000, 21);
        let tree = PointIndex::new(&pts);
        let r = median_kth_distance(&pts, &tree, 10).unwrap();
        let h = r * KNN_CELL_FACTOR;
        let dense = CellGrid::new(&pts, h).unwrap();
        let hashed = CellGrid::with_dense_limit(&pts, h, 0).unwrap();
        let [nx, ny, _] = dense.dims;
        let columns = CellGrid::with_dense_limit(&pts, h, 8 * nx * ny).unwrap();
        assert!(dense.dense.is_some() && dense.columns.is_none());
        assert!(hashed.dense.is_none() && hashed.columns.is_none());
        assert!(columns.dense.is_none() && columns.columns.is_some());
        let knn = |g: &CellGrid| g.map_knn(&pts, 10, 1.5 * r, &tree, |_, nb, _| nb.to_vec());
        let expected = knn(&dense);
        assert_eq!(knn(&hashed), expected);
        assert_eq!(knn(&columns), expected);
        for q in cloud(300, 4) {
            let q = [q[0] + 0.01, q[1], q[2]];
            for rr in [0.5 * r, 2.0 * r, 5.0 * r] {
                let expected = dense.nearest_within(&q, rr * rr);
                assert_eq!(hashed.nearest_within(&q, rr * rr), expected);
                assert_eq!(columns.nearest_within(&q, rr * rr), expected);
            }
        }
    }

    #[test]
    fn counted_and_sorted_orders_agree() {
        let mut next = crate::test_rng::uniform(9);
        let keys: Vec<u64> = (0..5000).map(|_| (next() * 700.0) as u64).collect();
        let sorted: Vec<u32> = crate::order::by_key(&keys)
            .into_iter()
            .map(|i| i as u32)
            .collect();
        let (counted, starts) = counting_order(&keys, 700);
        assert_eq!(counted, sorted);
        for k in [0usize, 1, 350, 699, 700] {
            assert_eq!(
                starts[k] as usize,
                keys.iter().filter(|&&x| (x as usize) < k).count()
            );
        }
    }

    #[test]
    fn radius_search_matches_the_tree() {
        let pts = cloud(2000, 5);
        let tree = PointIndex::new(&pts);
        let queries = cloud(400, 13);
        // Small radii on the grid, the largest on the tree (crowded cells).
        for (r, on_grid) in [(0.003, true), (0.04, true), (0.3, false)] {
            let rs = RadiusSearch::new(&pts, r, Some(&tree));
            assert_eq!(rs.grid.is_some(), on_grid, "r {r}");
            for q in &queries {
                let q = [q[0], q[1] * 0.99, q[2] - 0.002];
                let a = rs.nearest(&q).map(|x| x.1);
                assert_eq!(a, tree.nearest_within(&q, r * r).map(|x| x.1), "r {r}");
            }
        }
        // A box too large for cells of 2r: the tree answers.
        let far = vec![[0.0; 3], [1e9, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let rs = RadiusSearch::new(&far, 1e-3, None);
        assert!(rs.grid.is_none());
        assert_eq!(rs.nearest(&[1.0005, 0.0, 0.0]).map(|x| x.0), Some(2));
        assert_eq!(rs.nearest(&[1.5, 0.0, 0.0]), None);
    }

    #[test]
    fn degenerate_inputs() {
        assert!(CellGrid::new(&[], 1.0).is_none());
        assert!(CellGrid::new(&[[0.0; 3]], 0.0).is_none());
        assert!(CellGrid::new(&[[0.0; 3], [1e9, 0.0, 0.0]], 1e-3).is_none());
        let same = vec![[1.0, 2.0, 3.0]; 30];
        let tree = PointIndex::new(&same);
        assert!(median_kth_distance(&same, &tree, 20).is_none());
        let g = CellGrid::new(&same, 1.0).unwrap();
        assert_eq!(g.cells(), 1);
        let nb = g.map_knn(&same, 20, 0.0, &tree, |_, nb, _| nb.len());
        assert!(nb.iter().all(|&n| n == 20));
    }
}
