//! From settings to the stages' parameters: the ranges checked, the presets' structure
//! built, and the registration run.

use super::fields::{Runtime, SearchKind, Settings};
use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use crate::pipeline::{
    self, FinalStage, FirstLook, PolishConfig, Preset, Registration, RegistrationConfig,
    VerifyConfig, VoxelSize,
};
use crate::refine::{CorrespondenceDistance, RefineConfig};
use crate::rotations::{RotationSet, NAMES};
use crate::search::{CoarseToFine, SearchConfig, SearchMode};

/// `Err` naming `key` unless `ok`.
fn check(ok: bool, key: &'static str, rule: &str, got: impl std::fmt::Display) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(GgsError::param(key, format!("must be {rule}, got {got}")))
    }
}

fn positive(key: &'static str, v: f64) -> Result<()> {
    check(v.is_finite() && v > 0.0, key, "a number > 0", v)
}

fn non_negative(key: &'static str, v: f64) -> Result<()> {
    check(v.is_finite() && v >= 0.0, key, "a number ≥ 0", v)
}

fn positive_fraction(key: &'static str, v: f64) -> Result<()> {
    check(v > 0.0 && v <= 1.0, key, "in (0, 1]", v)
}

fn at_least_one(key: &'static str, n: usize) -> Result<()> {
    check(n >= 1, key, "at least 1", n)
}

impl Settings {
    /// Every setting in its range, else an error that names its key. The stages' own checks
    /// ([`VerifyConfig::validate`], the coarse-to-fine search's, [`FinalStage::validate`])
    /// name the same keys.
    pub fn validate(&self) -> Result<()> {
        if let Some(v) = self.voxel {
            positive("voxel", v)?;
        }
        at_least_one("auto_voxel_cells", self.auto_voxel_cells)?;
        non_negative("auto_voxel_spacings", self.auto_voxel_spacings)?;
        for (key, v) in [
            ("dedup", self.dedup),
            ("distinct_radius", self.distinct_radius),
        ] {
            if let Some(v) = v {
                non_negative(key, v)?;
            }
        }
        self.coarse_to_fine().validate()?;
        if let Some(k) = self.top_k {
            at_least_one("top_k", k)?;
        }
        if let Some(m) = self.max_memory {
            check(m > 0, "max_memory", "at least 1 byte", m)?;
        }
        self.validate_first_look()?;
        self.verify_config().validate()?;
        self.validate_polish()?;
        self.validate_refinement()?;
        positive_fraction("align_min_overlap", self.align_min_overlap)?;
        let c = self.align_min_confidence;
        check(
            (0.0..=1.0).contains(&c),
            "align_min_confidence",
            "in [0, 1]",
            c,
        )?;
        at_least_one("align_model_scans", self.align_model_scans)?;
        at_least_one("align_batch", self.align_batch)?;
        self.final_stage().validate()
    }

    fn validate_first_look(&self) -> Result<()> {
        at_least_one("first_look_rotations", self.first_look_rotations)?;
        at_least_one("first_look_hypotheses", self.first_look_hypotheses)?;
        let s = self.first_look_accept_score;
        check(
            s.is_finite() && (0.0..=1.0).contains(&s),
            "first_look_accept_score",
            "in [0, 1]",
            s,
        )?;
        non_negative("first_look_screen_cell", self.first_look_screen_cell)
    }

    fn validate_polish(&self) -> Result<()> {
        positive_fraction("polish_step_fraction", self.polish_step_fraction)?;
        at_least_one("polish_levels", self.polish_levels)
    }

    fn validate_refinement(&self) -> Result<()> {
        if let Some(d) = self.max_distance {
            positive("max_distance", d)?;
        }
        positive_fraction("distance_quantile", self.distance_quantile)?;
        at_least_one("max_iterations", self.max_iterations)?;
        check(
            self.neighbors >= 3,
            "neighbors",
            "at least 3",
            self.neighbors,
        )?;
        positive("gicp_epsilon", self.gicp_epsilon)
    }

    /// The coarse-to-fine search's parameters.
    fn coarse_to_fine(&self) -> CoarseToFine {
        CoarseToFine {
            factor: self.coarse_factor,
            keep_fraction: self.coarse_keep,
            keep_min: self.coarse_keep_min,
            neighbour_deg: self.coarse_neighbour,
            hypotheses: self.coarse_hypotheses,
            stop_when_winner_holds: false,
        }
    }

    /// The verification's parameters (used when `verify`).
    fn verify_config(&self) -> VerifyConfig {
        VerifyConfig {
            margin: self.margin,
            max_hypotheses: self.max_hypotheses,
            distance_voxels: self.verify_distance_voxels,
            spacing_factor: self.verify_distance_spacings,
            scan_distance_fraction: self.verify_distance_range,
            cell_voxels: self.verify_cell,
            check_iterations: self.verify_check_iterations,
            max_iterations: self.verify_iterations,
            reject_ratio: self.reject_ratio,
            fine_cell_voxels: self.verify_fine_cell,
            fine_iterations: self.verify_fine_iterations,
            fine_distance_voxels: self.verify_fine_distance,
            settle_ratio: self.settle_ratio,
            ambiguous_ratio: self.ambiguous_ratio,
            score: self.verify_score,
            free_space_weight: self.free_space_weight,
            free_space_tolerance: self.free_space_tolerance,
            free_space_margin_voxels: self.free_space_margin,
            least_score: 0.0,
        }
    }

    /// The final refinement's schedule: its iteration cap is the refinement's own.
    fn final_stage(&self) -> FinalStage {
        FinalStage {
            cell_voxels: self.refine_cell,
            min_step: self.refine_min_step,
            max_iterations: usize::MAX,
        }
    }

    /// The final refinement's parameters (`None`: `refine` is none); `threads` as
    /// [`Runtime::threads`]. `ggs refine` runs these alone.
    pub fn refine_config(&self, threads: usize) -> Option<RefineConfig> {
        self.refine.map(|method| RefineConfig {
            method,
            correspondence: match self.max_distance {
                Some(d) => CorrespondenceDistance::Fixed(d),
                None => CorrespondenceDistance::Quantile(self.distance_quantile),
            },
            kernel: self.kernel,
            max_iterations: self.max_iterations,
            neighbors: self.neighbors,
            epsilon: self.gicp_epsilon,
            threads,
            ..RefineConfig::default()
        })
    }

    /// The rotation set: a built-in one by name, or a `.npy` file of shape `[N, 3, 3]`; less
    /// its near-duplicates when `dedup` is set.
    pub fn rotation_set(&self) -> Result<RotationSet> {
        let set = if NAMES.contains(&self.rotations.as_str()) || !self.rotations.ends_with(".npy") {
            RotationSet::named(&self.rotations)?
        } else {
            crate::io::npy::read_rotation_set(self.rotations.as_ref())?
        };
        match self.dedup {
            Some(tol) => set.without_duplicates_within(tol),
            None => Ok(set),
        }
    }

    /// The stages' parameters, the ranges checked first; `threads` as [`Runtime::threads`].
    pub fn plan(&self, threads: usize) -> Result<RegistrationConfig> {
        self.validate()?;
        let mut search = SearchConfig::with_voxel(f64::NAN);
        search.mode = match self.search {
            SearchKind::Exhaustive => SearchMode::Exhaustive,
            SearchKind::CoarseToFine => SearchMode::CoarseToFine(self.coarse_to_fine()),
        };
        search.precision = self.precision;
        search.top_k = match (self.top_k, self.verify) {
            (Some(k), _) => k,
            (None, true) => self.max_hypotheses,
            (None, false) => 1,
        };
        search.distinct_radius_deg = self.distinct_radius;
        search.max_memory = self.max_memory;
        let refine = self.refine_config(threads);
        Ok(RegistrationConfig {
            voxel: match self.voxel {
                Some(v) => VoxelSize::Fixed(v),
                None => VoxelSize::Auto {
                    cells: self.auto_voxel_cells,
                    spacings: self.auto_voxel_spacings,
                },
            },
            rotations: self.rotation_set()?,
            search,
            polish: self.polish.then_some(PolishConfig {
                step_fraction: self.polish_step_fraction,
                levels: self.polish_levels,
                max_moves: self.polish_max_moves,
            }),
            verify: self.verify.then(|| self.verify_config()),
            // The K best of the whole search: a first look has only its own few.
            first_look: (self.first_look && self.top_k.is_none()).then_some(FirstLook {
                rotations: self.first_look_rotations,
                hypotheses: self.first_look_hypotheses,
                accept_score: self.first_look_accept_score,
                screen_cell_voxels: self.first_look_screen_cell,
                stop_unsettled: false,
            }),
            final_stage: self.final_stage(),
            refine,
            threads,
        })
    }

    /// These settings as a TOML document (a settings file; unset optional settings left out).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("settings serialize")
    }

    /// [`Settings::plan`] on `runtime`'s threads, with its progress callback and cancel flag.
    pub fn plan_with(&self, runtime: &Runtime) -> Result<RegistrationConfig> {
        let mut cfg = self.plan(runtime.threads)?;
        cfg.search.progress = runtime.progress.clone();
        cfg.search.cancel = runtime.cancel.clone();
        Ok(cfg)
    }

    /// These settings as a JSON object, as results echo them ([`Registration::settings`]).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("settings serialize")
    }
}

/// Register `source` onto `target` with `settings`: the pipeline every front end calls (see
/// [`crate::pipeline`]). The result echoes the settings ([`Registration::settings`]).
pub fn register(source: &Cloud, target: &Cloud, settings: &Settings) -> Result<Registration> {
    register_with(source, target, settings, &Runtime::default())
}

/// [`register`] with the threads, progress callback and cancel flag of `runtime`.
pub fn register_with(
    source: &Cloud,
    target: &Cloud,
    settings: &Settings,
    runtime: &Runtime,
) -> Result<Registration> {
    register_planned(source, target, settings, &settings.plan_with(runtime)?)
}

/// Run `cfg`, the [`Settings::plan`] of `settings` with what a front end sets beside them (a
/// progress callback sized to the rotation set, a rotation set given as matrices); the result
/// echoes `settings`.
pub fn register_planned(
    source: &Cloud,
    target: &Cloud,
    settings: &Settings,
    cfg: &RegistrationConfig,
) -> Result<Registration> {
    let mut reg = pipeline::register(source, target, cfg)?;
    reg.settings = Some(settings.to_json());
    Ok(reg)
}

impl RegistrationConfig {
    /// The stages' parameters of `preset` ([`Settings::preset`]), on every core.
    pub fn preset(preset: Preset) -> Self {
        Settings::preset(preset)
            .plan(0)
            .expect("the presets are valid")
    }
}

impl Default for RegistrationConfig {
    /// The default preset's.
    fn default() -> Self {
        Self::preset(Preset::Default)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_presets_read_back_from_their_toml_and_json() {
        for preset in [Preset::Default, Preset::Paper] {
            let s = Settings::preset(preset);
            s.validate().unwrap();
            let from_toml: Settings = toml::from_str(&s.to_toml()).unwrap_or_else(|e| {
                // Unset optional keys are left out of TOML and read back as unset.
                panic!("{preset:?}: {e}")
            });
            assert_eq!(from_toml, s);
            let from_json: Settings = serde_json::from_value(s.to_json()).unwrap();
            assert_eq!(from_json, s);
        }
    }

    #[test]
    fn the_plan_follows_the_settings() {
        let s = Settings::default();
        let cfg = s.plan(3).unwrap();
        assert_eq!(cfg.search.top_k, s.max_hypotheses);
        assert!(cfg.first_look.is_some() && cfg.verify.is_some() && cfg.polish.is_none());
        assert_eq!(cfg.refine.unwrap().max_iterations, 100);
        assert_eq!(cfg.refine.unwrap().threads, 3);
        // Reported hypotheses of the whole search: no first look.
        let top = Settings {
            top_k: Some(5),
            ..Settings::default()
        };
        let cfg = top.plan(0).unwrap();
        assert!(cfg.first_look.is_none());
        assert_eq!(cfg.search.top_k, 5);
        let bare = Settings {
            verify: false,
            refine: None,
            ..Settings::default()
        };
        let cfg = bare.plan(0).unwrap();
        assert!(cfg.verify.is_none() && cfg.refine.is_none());
        assert_eq!(cfg.search.top_k, 1);
        let paper = Settings::preset(Preset::Paper).plan(0).unwrap();
        assert_eq!(paper.rotations.name, "limited15");
        assert!(matches!(paper.search.mode, SearchMode::Exhaustive));
    }

    #[test]
    fn out_of_range_settings_are_refused_by_their_key() {
        let bad = |s: Settings| s.plan(0).unwrap_err().to_string();
        let d = Settings::default;
        assert!(bad(Settings {
            voxel: Some(-1.0),
            ..d()
        })
        .contains("voxel"));
        assert!(bad(Settings {
            coarse_factor: 0.5,
            ..d()
        })
        .contains("coarse_factor"));
        assert!(bad(Settings {
            top_k: Some(0),
            ..d()
        })
        .contains("top_k"));
        assert!(bad(Settings {
            refine_cell: -1.0,
            ..d()
        })
        .contains("refine_cell"));
        assert!(bad(Settings {
            neighbors: 2,
            ..d()
        })
        .contains("neighbors"));
        let iterations = Settings {
            verify_iterations: 5,
            ..d()
        };
        assert!(bad(iterations).contains("verify_iterations"));
        let unknown = Settings {
            rotations: "hopf99".into(),
            ..d()
        };
        assert!(bad(unknown).contains("hopf99"));
    }
}
