//! Overlap of two views of one scan, from their visible-point index sets (docs/generator.md).

/// `|I_a ∩ I_b| / |I_a| × 100`, for ascending index lists: the share of view `a`'s points that
/// view `b` also sees, in percent. Asymmetric: `overlap(a, b) ≠ overlap(b, a)` when the views
/// differ in size. 0 when `a` is empty.
pub fn overlap_percent(a: &[u32], b: &[u32]) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    let (mut i, mut j, mut common) = (0, 0, 0usize);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                common += 1;
                i += 1;
                j += 1;
            }
        }
    }
    common as f64 / a.len() as f64 * 100.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn asymmetric() {
        let a = [1, 2, 3, 4];
        let b = [3, 4, 5, 6, 7, 8, 9, 10];
        assert_eq!(overlap_percent(&a, &b), 50.0);
        assert_eq!(overlap_percent(&b, &a), 25.0);
        assert_eq!(overlap_percent(&a, &a), 100.0);
        assert_eq!(overlap_percent(&[], &a), 0.0);
        assert_eq!(overlap_percent(&a, &[]), 0.0);
    }
}
