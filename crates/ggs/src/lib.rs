//! # ggs: correspondence-free global registration of 3-D point clouds
//!
//! ggs implements the Greedy Grid Search of Bojanić et al. (BMVC 2022 workshop): voxelize
//! both clouds, try every rotation of a grid, find the best translation for each by FFT
//! cross-correlation, keep the best (rotation, translation). No features, no training, no
//! initial guess. On top of it, ggs verifies the distinct hypotheses by ICP on thinned clouds
//! and a fixed-distance score, and refines the best by generalized ICP.
//!
//! The pipeline, one module per stage: [`io`] → [`cloud`] → [`rotations`] → [`search`]
//! (voxelization, FFT correlation, the grid search) → [`pipeline`] (verification of the hypotheses)
//! → [`refine`], configured by one flat [`Settings`] ([`settings`]: the presets, settings files,
//! every key) and run by [`register`], which every front end calls; [`metrics`] for evaluation.
//!
//! ```no_run
//! use ggs::{io, register, Settings};
//! let source = io::read_cloud("source.ply".as_ref(), None)?.cloud;
//! let target = io::read_cloud("target.ply".as_ref(), None)?.cloud;
//! let settings = Settings { voxel: Some(0.005), ..Settings::default() };
//! let result = register(&source, &target, &settings)?;
//! println!("{}confidence {:.2}", result.transform.to_text(), result.confidence);
//! # Ok::<(), ggs::GgsError>(())
//! ```

//! Cargo features, all on by default: `las` (LAS/LAZ), `e57` (E57 scans), `npz` (NumPy
//! archives) and `report` (the HTML report, [`render::Image::png`]). With one off, reading or
//! writing that format is an error that names the feature.

// Grid and matrix code indexes several arrays with one axis variable; iterators would hide it.
#![allow(clippy::needless_range_loop)]

/// Declares modules that are building blocks of a stage: crate-private, and public only
/// with the `internals` feature (the stage benchmarks and timing probes; no stability promise).
macro_rules! internal_modules {
    ($($name:ident),* $(,)?) => {$(
        #[cfg(feature = "internals")]
        pub mod $name;
        #[cfg(not(feature = "internals"))]
        pub(crate) mod $name;
    )*};
}

pub mod align;
pub mod cloud;
pub mod error;
#[cfg(feature = "report")]
pub mod html;
pub mod io;
pub mod memory;
pub mod mesh;
pub mod metrics;
pub mod num;
pub mod order;
pub mod pipeline;
pub mod refine;
pub mod render;
pub mod rng;
pub mod rotations;
pub mod search;
pub mod settings;
pub mod simd;
pub mod spacing;
pub mod thin;
pub mod threads;
pub mod transform;

/// Seeded uniform streams for tests (also used by the tests of `ggs-bench`).
#[doc(hidden)]
pub mod test_rng;

pub use cloud::{Cloud, Point};
pub use error::{GgsError, Location, Result};
pub use pipeline::{Registration, RegistrationConfig};
pub use settings::{register, Runtime, Settings};
pub use transform::Rigid;
