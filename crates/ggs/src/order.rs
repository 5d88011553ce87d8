//! Indices in the order of one integer key each, ties to the lower index: the sorting rule of
//! the clusters of a rotatable source (points by cluster) and of the refinement's cell grids
//! (points by cell). Thinning (`thin::cell_centroids`) packs its words itself: it runs on
//! clouds of millions of points and holds 8 bytes a point, where this holds the keys, the
//! packed words and the indices (24).

/// Indices `0..keys.len()` ordered by `(keys[i], i)`.
///
/// When the largest key and the largest index fit together in 64 bits (the usual case:
/// cell keys of a few tens of bits, clouds of millions of points) each entry is packed into
/// one word `key · 2^b + i` and the words are sorted as integers; otherwise (key, index)
/// pairs are sorted. The entries are distinct, so the unstable sort's order is total. One
/// thread: its callers build per-cloud structures while other work runs beside them.
pub fn by_key(keys: &[u64]) -> Vec<usize> {
    let n = keys.len();
    if n == 0 {
        return Vec::new();
    }
    let bits = |v: u64| 64 - v.leading_zeros();
    let index_bits = bits(n as u64 - 1);
    let key_bits = bits(keys.iter().copied().max().unwrap_or(0));
    if key_bits + index_bits <= 64 {
        // index_bits < 64: a slice holds fewer than 2^63 entries.
        let mut packed: Vec<u64> = keys
            .iter()
            .enumerate()
            .map(|(i, &k)| k << index_bits | i as u64)
            .collect();
        packed.sort_unstable();
        let low = (1u64 << index_bits) - 1;
        return packed.into_iter().map(|e| (e & low) as usize).collect();
    }
    let mut pairs: Vec<(u64, usize)> = keys.iter().copied().zip(0..n).collect();
    pairs.sort_unstable();
    pairs.into_iter().map(|(_, i)| i).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition: a stable sort by key.
    fn stable(keys: &[u64]) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..keys.len()).collect();
        idx.sort_by_key(|&i| keys[i]);
        idx
    }

    #[test]
    fn packed_and_paired_sorts_follow_the_definition() {
        let mut next = crate::test_rng::uniform(9);
        let small: Vec<u64> = (0..5000).map(|_| (next() * 700.0) as u64).collect();
        assert_eq!(by_key(&small), stable(&small));
        // Keys of 50 bits and 13 index bits: still packed.
        let wide: Vec<u64> = small.iter().map(|&k| k << 40).collect();
        assert_eq!(by_key(&wide), stable(&small));
        // Keys beyond 64 − 13 bits take the pairs.
        let large: Vec<u64> = small.iter().map(|&k| k << 53 | 7).collect();
        assert_eq!(by_key(&large), stable(&small));
        assert_eq!(by_key(&[]), Vec::<usize>::new());
        assert_eq!(by_key(&[u64::MAX]), vec![0]);
        assert_eq!(by_key(&[u64::MAX, 0, u64::MAX]), vec![1, 0, 2]);
    }
}
