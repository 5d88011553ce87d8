//! Benchmark runners: the published protocols and generic manifests, run pair by pair into a
//! resumable CSV, with a summary in the layout of the papers' tables (docs/benchmarks.md).
//!
//! - [`protocol`]: pair lists, ground truth and default parameters of each protocol;
//! - [`row`]: one pair's result ([`PairRow`]) and the resumable CSV file;
//! - [`report`]: recall, mean errors, the Markdown table and the recall curves (SVG);
//! - [`html`]: `report.html`, the page with charts, every pair and a gallery of failures;
//! - [`plan`]: the pairs selected and how each is run, validated for every front end;
//! - [`run_dir`]: the run directory, written as pairs finish in any order, and the serial run;
//! - [`shard`]: a deterministic share of the pairs per run directory, and the merge of shards.

pub mod config;
pub mod execute;
mod finish;
pub mod html;
pub mod motion;
pub mod pair;
pub mod plan;
pub mod protocol;
pub mod report;
pub mod row;
pub mod run_dir;
pub mod shard;

pub use config::{BenchVoxel, RunConfig};
pub use execute::{right_pose_rank, run_pair, run_pair_with_picture, RunOutcome};
pub use pair::{missing_files, read_indices, BenchPair, CloudRef};
pub use plan::{Plan, Selection};
pub use protocol::Protocol;
pub use row::PairRow;
pub use run_dir::{run, RunDir};
