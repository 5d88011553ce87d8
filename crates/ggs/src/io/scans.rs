//! Which scans of a multi-scan file (E57) to read; known whether or not E57 support is built.

/// Which scans of an E57 file to read, and in which frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct E57Options {
    /// Read only this scan (0-based); `None`: every scan, concatenated.
    pub scan: Option<usize>,
    /// Move each scan by its pose into the file's frame (true), or keep it in the scanner's
    /// own frame (false).
    pub apply_pose: bool,
}

impl Default for E57Options {
    fn default() -> Self {
        E57Options {
            scan: None,
            apply_pose: true,
        }
    }
}
