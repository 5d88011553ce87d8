//! # ggs-bench: benchmarks on top of the ggs registration library
//!
//! What sits above the algorithm: the product a benchmark user runs, kept out of the core
//! crate so that `ggs` is what a Python user or a robotics integrator needs.
//!
//! - [`manifest`]: `pairs.tsv`, the one reader and writer of pair lists with ground truth;
//! - [`benchmark`]: dataset protocols (3DMatch, KITTI, ETH, FAUST-partial), the validated
//!   selection ([`benchmark::plan`]), resumable run directories, sharding, reports;
//! - [`generator`]: the partial-view benchmark generator (`ggs partial`), including the
//!   rebuild of the published FPv1 pairs.
//!
//! Every front end (the `ggs bench` and `ggs partial` commands, `ggs.bench` in Python) calls
//! these modules; each pair is registered by `ggs::pipeline::register`.

// Grid and matrix code indexes several arrays with one axis variable; iterators would hide it.
#![allow(clippy::needless_range_loop)]

pub mod benchmark;
pub mod generator;
pub mod manifest;
