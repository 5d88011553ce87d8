//! The settings of a registration: every knob a user turns, in one flat, serializable struct.
//!
//! A preset is a value of it ([`Settings::preset`]). A settings file (TOML or JSON), the
//! command line's flags and Python's keyword arguments are layers of `key = value` changes
//! laid over a preset, each key named as the field ([`Settings::layered`]). [`Settings::plan`]
//! checks every range ([`Settings::validate`]) and turns the settings into the stages'
//! parameters ([`RegistrationConfig`](crate::RegistrationConfig)). What a run needs beside
//! its settings, and which does not change its result (threads, a progress callback, a cancel
//! flag), is passed beside them ([`Runtime`]).
//!
//! ```toml
//! # ggs register a.ply b.ply --config scans.toml
//! preset = "default"   # the base the other keys change (default or paper)
//! voxel = 0.5
//! max_hypotheses = 48
//! verify_score = "fitness"
//! ```

mod fields;
mod layers;
mod plan;
mod serde_forms;

pub use fields::{Runtime, SearchKind, Settings};
pub use layers::{Changes, SettingsFile};
pub use plan::{register, register_planned, register_with};
