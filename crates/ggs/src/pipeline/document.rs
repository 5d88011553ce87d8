//! The one serialized form of a result: what `ggs register --json` and `ggs refine --json`
//! print, what Python's `Result` is read from, and what a benchmark row is filled from. The
//! layout is versioned by its `format` field ([`REGISTRATION_FORMAT`],
//! [`REFINEMENT_FORMAT`]) and documented in docs/cli.md, "The JSON result".

use super::registration::Registration;
use crate::refine::RefineResult;
use crate::transform::Rigid;

/// `format` of a [`RegistrationDocument`]: its name and layout version.
pub const REGISTRATION_FORMAT: &str = "ggs-registration/2";
/// `format` of a [`RefinementDocument`].
pub const REFINEMENT_FORMAT: &str = "ggs-refinement/1";

/// A [`Registration`] with what the run around it knows: where the clouds came from and how
/// long the whole call took. The registration's fields sit at the top level.
#[derive(Debug, serde::Serialize)]
pub struct RegistrationDocument<'a> {
    /// [`REGISTRATION_FORMAT`].
    pub format: &'static str,
    /// The source's and the target's file names (`None`: points given in memory).
    pub source: Option<String>,
    pub target: Option<String>,
    /// The preset the settings started from.
    pub preset: Option<&'a str>,
    #[serde(flatten)]
    pub registration: &'a Registration,
    /// Reading both clouds, ms (`None`: points given in memory).
    pub read_ms: Option<f64>,
    /// The whole call, reading included, ms.
    pub total_ms: f64,
    /// The process's peak resident memory, bytes (where the system reports it).
    pub peak_memory_bytes: Option<u64>,
}

impl<'a> RegistrationDocument<'a> {
    /// The document of `registration`, with no file names and no read time.
    pub fn new(registration: &'a Registration, total_ms: f64) -> Self {
        RegistrationDocument {
            format: REGISTRATION_FORMAT,
            source: None,
            target: None,
            preset: None,
            registration,
            read_ms: None,
            total_ms,
            peak_memory_bytes: crate::memory::peak_resident(),
        }
    }

    /// As pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a registration serializes")
    }
}

/// An ICP refinement of a given start (`ggs refine`, Python's `refine`).
#[derive(Debug, serde::Serialize)]
pub struct RefinementDocument<'a> {
    /// [`REFINEMENT_FORMAT`].
    pub format: &'static str,
    pub source: Option<String>,
    pub target: Option<String>,
    /// The start, `p_target = init · p_source`.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub init: Rigid,
    /// The refined transform.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    pub refine: &'a RefineResult,
    /// The whole call, reading included, ms.
    pub total_ms: f64,
}

impl<'a> RefinementDocument<'a> {
    /// The document of `refined` from `init`, with no file names.
    pub fn new(init: Rigid, refined: &'a RefineResult, total_ms: f64) -> Self {
        RefinementDocument {
            format: REFINEMENT_FORMAT,
            source: None,
            target: None,
            init,
            transform: refined.transform,
            refine: refined,
            total_ms,
        }
    }

    /// As pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a refinement serializes")
    }
}
