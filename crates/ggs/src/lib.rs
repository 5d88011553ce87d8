//! # ggs: correspondence-free global registration of 3-D point clouds
//!
//! ggs implements the Greedy Grid Search of Bojanić et al. (BMVC 2022 workshop): voxelize
//! both clouds, try every rotation of a grid, find the best translation for each by FFT
//! cross-correlation, keep the best (rotation, translation). No features, no training, no
//! initial guess.
//!
//! The pipeline, one module per stage:
//! [`io`] → [`cloud`] → [`voxel`] → [`rotations`] → [`correlate`] → [`search`] → [`transform`],
//! with [`metrics`] for evaluation.
//!
//! ```no_run
//! use ggs::{io, rotations::RotationSet, search::{coarse_register, SearchConfig}};
//! let source = io::read_cloud("source.ply".as_ref(), None)?.cloud;
//! let target = io::read_cloud("target.ply".as_ref(), None)?.cloud;
//! let set = RotationSet::named("limited15")?;
//! let result = coarse_register(&source, &target, &set, &SearchConfig::with_voxel(0.005))?;
//! println!("{}", result.transform.to_text());
//! # Ok::<(), ggs::GgsError>(())
//! ```

// Grid and matrix code indexes several arrays with one axis variable; iterators would hide it.
#![allow(clippy::needless_range_loop)]

pub mod benchmark;
pub mod cloud;
pub mod correlate;
pub mod error;
pub mod generator;
pub mod io;
pub mod manifest;
pub mod memory;
pub mod metrics;
pub mod pipeline;
pub mod refine;
pub mod rotated;
pub mod rotations;
pub mod search;
pub mod threads;
pub mod transform;
pub mod voxel;

#[cfg(test)]
pub(crate) mod test_rng;

pub use cloud::{Cloud, Point};
pub use error::{GgsError, Location, Result};
pub use transform::Rigid;
