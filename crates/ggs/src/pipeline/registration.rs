//! The outcome of a registration: the transform, how sure it is, and what each stage found.

use super::first_look::FirstLookReport;
use super::verified::Verification;
use crate::refine::RefineResult;
use crate::search::SearchResult;
use crate::transform::Rigid;

/// Wall times of the stages, milliseconds.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct StageTimes {
    pub search_ms: f64,
    pub verify_ms: f64,
    pub refine_ms: f64,
    pub total_ms: f64,
}

/// The outcome of [`register`](super::register).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Registration {
    /// The final transform, `p_target = T · p_source`.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    /// The chosen hypothesis's grid transform (before polish and ICP).
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub coarse_transform: Rigid,
    pub voxel: f64,
    /// How the voxel was chosen automatically (`None`: it was given).
    pub voxel_rule: Option<String>,
    /// Rank of the chosen hypothesis among the grid search's (0: its winner).
    pub chosen_rank: usize,
    /// `1 − runner-up / chosen` verification score (or `1 −` the coarse ambiguity), in [0, 1].
    pub confidence: f64,
    /// Two distinct poses verify (or, unverified, score) about equally well.
    pub ambiguous: bool,
    /// What a user should know: ambiguity, low evidence.
    pub warnings: Vec<String>,
    pub search: SearchResult,
    /// What the first look did (`None`: it did not run).
    pub first_look: Option<FirstLookReport>,
    pub verification: Option<Verification>,
    pub refine: Option<RefineResult>,
    /// Cell edge (cloud units) of the clouds the final refinement ran on; 0: full resolution.
    pub refine_cell: f64,
    pub timings: StageTimes,
    /// The settings in force, serialized ([`crate::Settings`]); `None` for a run configured
    /// by a [`RegistrationConfig`](super::RegistrationConfig) alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub settings: Option<serde_json::Value>,
}
