//! Settings as layers of changes over a preset: a settings file, the command line, keyword
//! arguments; each change is `key = value` with the key named as a [`Settings`] field.

use super::fields::Settings;
use crate::error::{GgsError, Result};
use crate::pipeline::Preset;
use serde_json::{Map, Value};
use std::path::Path;

/// Changes to settings from one origin, in the order given: the origin names them in errors
/// (a file's path, `command line`, `keyword arguments`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Changes {
    /// Where the changes come from, as errors name it.
    pub origin: String,
    /// (origin, key, value): an entry may name its own origin (a flag).
    entries: Vec<(String, String, Value)>,
}

/// A settings file: the preset it starts from (its `preset` key) and its other keys.
#[derive(Debug, Clone, PartialEq)]
pub struct SettingsFile {
    pub preset: Option<Preset>,
    pub changes: Changes,
}

impl Changes {
    /// No changes yet, from `origin`.
    pub fn new(origin: impl Into<String>) -> Changes {
        Changes {
            origin: origin.into(),
            entries: Vec::new(),
        }
    }

    /// Set `key` to `value` (a later change of one key wins).
    pub fn set(&mut self, key: impl Into<String>, value: impl Into<Value>) {
        self.entries
            .push((self.origin.clone(), key.into(), value.into()));
    }

    /// Set `key` to `value`, naming `origin` (a flag, say) in errors instead of the layer's.
    pub fn set_from(
        &mut self,
        origin: impl Into<String>,
        key: impl Into<String>,
        value: impl Into<Value>,
    ) {
        self.entries.push((origin.into(), key.into(), value.into()));
    }

    /// `key=value`, as `--set` takes it: the value is read as JSON (a number, `true`,
    /// `null`, a quoted string), else taken as a string (`verify_score=fitness`).
    pub fn set_assignment(&mut self, assignment: &str) -> Result<()> {
        let (key, text) = assignment
            .split_once('=')
            .ok_or_else(|| GgsError::Setting {
                origin: self.origin.clone(),
                key: assignment.to_string(),
                message: "expected KEY=VALUE".into(),
            })?;
        let value = serde_json::from_str(text.trim()).unwrap_or_else(|_| Value::from(text));
        self.set(key.trim(), value);
        Ok(())
    }

    /// The keys changed, in order.
    pub fn keys(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|(_, k, _)| k.as_str())
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn error(&self, key: &str, message: impl Into<String>) -> GgsError {
        let origin = self.entries.iter().rev().find(|(_, k, _)| k == key);
        GgsError::Setting {
            origin: origin.map_or(&self.origin, |(o, _, _)| o).clone(),
            key: key.to_string(),
            message: message.into(),
        }
    }
}

impl SettingsFile {
    /// Read a TOML (`.toml`) or JSON (`.json`) settings file: a table of settings keys, and
    /// optionally `preset`.
    pub fn read(path: &Path) -> Result<SettingsFile> {
        let text = std::fs::read_to_string(path).map_err(|e| GgsError::io(path, e))?;
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let table: Map<String, Value> = match ext.to_ascii_lowercase().as_str() {
            "toml" => {
                let t: toml::Table =
                    toml::from_str(&text).map_err(|e| GgsError::in_file(path, e.to_string()))?;
                serde_json::to_value(t)
                    .ok()
                    .and_then(|v| v.as_object().cloned())
                    .ok_or_else(|| GgsError::in_file(path, "not a table of settings"))?
            }
            "json" => serde_json::from_str(&text).map_err(|e| {
                GgsError::at_line(
                    path,
                    e.line(),
                    format!("{e} (expected an object of settings)"),
                )
            })?,
            other => {
                return Err(GgsError::in_file(
                    path,
                    format!("unknown settings format '.{other}' (toml or json)"),
                ))
            }
        };
        SettingsFile::of_table(path.display().to_string(), table)
    }

    /// A table of settings keys and optionally `preset`, from `origin`.
    pub fn of_table(origin: String, table: Map<String, Value>) -> Result<SettingsFile> {
        let mut changes = Changes::new(origin);
        let mut preset = None;
        for (key, value) in table {
            if key == "preset" {
                let name = value.as_str().unwrap_or_default();
                preset = Some(
                    name.parse()
                        .map_err(|e: GgsError| changes.error(&key, e.to_string()))?,
                );
            } else {
                changes.set(key, value);
            }
        }
        Ok(SettingsFile { preset, changes })
    }
}

/// Settings keys that only matter with verification: changing them from the preset's value
/// while `verify` is false is refused rather than ignored.
const NEED_VERIFICATION: [&str; 3] = ["max_hypotheses", "margin", "verify_score"];

impl Settings {
    /// `preset`'s settings changed by `layers` in order (a later layer wins). Refuses an
    /// unknown key, a value of the wrong kind or out of its range, naming the layer's origin
    /// and the key, and a verification setting asked for without verification.
    pub fn layered(preset: Preset, layers: &[Changes]) -> Result<Settings> {
        let base = match serde_json::to_value(Settings::preset(preset)) {
            Ok(Value::Object(m)) => m,
            _ => unreachable!("settings serialize to an object"),
        };
        let mut fields = base.clone();
        for layer in layers {
            for (_, key, value) in &layer.entries {
                let Some(slot) = fields.get_mut(key) else {
                    return Err(layer.error(key, unknown_key(key, &fields)));
                };
                *slot = value.clone();
                // Each change is read as it is made, so that its error names its key.
                if let Err(e) = serde_json::from_value::<Settings>(Value::Object(fields.clone())) {
                    return Err(layer.error(key, e.to_string()));
                }
            }
        }
        let settings: Settings =
            serde_json::from_value(Value::Object(fields.clone())).expect("each change was read");
        settings.validate().map_err(|e| blame(e, layers))?;
        if !settings.verify {
            let changed = NEED_VERIFICATION.iter().find(|k| fields[**k] != base[**k]);
            if let Some(key) = changed {
                let e = GgsError::param(key, "needs verification (verify is false)");
                return Err(blame(e, layers));
            }
        }
        Ok(settings)
    }
}

/// An out-of-range error named by the last layer that set its key.
fn blame(e: GgsError, layers: &[Changes]) -> GgsError {
    let GgsError::InvalidParameter { name, message } = &e else {
        return e;
    };
    match layers.iter().rev().find(|l| l.keys().any(|k| k == *name)) {
        Some(layer) => layer.error(name, message.clone()),
        None => e,
    }
}

/// "unknown setting", with the known keys that are a typo away from `key` or share a word
/// with it.
fn unknown_key(key: &str, known: &Map<String, Value>) -> String {
    let words: Vec<&str> = key.split('_').filter(|w| w.len() > 2).collect();
    let close: Vec<&str> = known
        .keys()
        .map(String::as_str)
        .filter(|k| edit_distance(k, key) <= 2 || k.split('_').any(|w| words.contains(&w)))
        .collect();
    if close.is_empty() {
        "unknown setting".to_string()
    } else {
        format!("unknown setting (did you mean {}?)", close.join(", "))
    }
}

/// Levenshtein distance: the fewest single-character insertions, deletions and
/// substitutions that turn `a` into `b`.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitution = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(diagonal + 1);
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(origin: &str, pairs: &[(&str, Value)]) -> Changes {
        let mut c = Changes::new(origin);
        for (k, v) in pairs {
            c.set(*k, v.clone());
        }
        c
    }

    #[test]
    fn later_layers_win_and_untouched_keys_keep_the_presets_values() {
        let file = layer(
            "a.toml",
            &[("margin", 0.3.into()), ("max_hypotheses", 8.into())],
        );
        let flags = layer("command line", &[("margin", 0.4.into())]);
        let s = Settings::layered(Preset::Default, &[file, flags]).unwrap();
        assert_eq!((s.margin, s.max_hypotheses), (0.4, 8));
        let base = Settings::preset(Preset::Default);
        assert_eq!(
            Settings {
                margin: 0.5,
                max_hypotheses: 32,
                ..s
            },
            base
        );
    }

    #[test]
    fn errors_name_the_origin_the_key_and_what_is_wrong() {
        let e = |pairs: &[(&str, Value)]| {
            Settings::layered(Preset::Default, &[layer("s.toml", pairs)])
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            e(&[("margn", 0.3.into())]),
            "s.toml: setting margn: unknown setting (did you mean margin?)"
        );
        let kind = e(&[("margin", "high".into())]);
        assert!(
            kind.starts_with("s.toml: setting margin: invalid type"),
            "{kind}"
        );
        assert_eq!(
            e(&[("margin", 3.into())]),
            "s.toml: setting margin: must be in [0, 1], got 3"
        );
        assert_eq!(
            e(&[("verify", false.into()), ("verify_score", "fitness".into())]),
            "s.toml: setting verify_score: needs verification (verify is false)"
        );
        let search = e(&[("search", "greedy".into())]);
        assert!(search.contains("unknown variant `greedy`"), "{search}");
    }

    #[test]
    fn a_set_assignment_reads_json_else_a_string() {
        let mut c = Changes::new("--set");
        c.set_assignment("margin=0.25").unwrap();
        c.set_assignment("verify_score=fitness").unwrap();
        c.set_assignment("voxel=null").unwrap();
        c.set_assignment("max_memory=2G").unwrap();
        assert!(c.set_assignment("margin").is_err());
        let s = Settings::layered(Preset::Default, &[c]).unwrap();
        assert_eq!(s.margin, 0.25);
        assert_eq!(s.verify_score, crate::pipeline::VerifyScore::Fitness);
        assert_eq!(s.max_memory, Some(2 << 30));
    }

    #[test]
    fn settings_files_in_toml_and_json_read_alike() {
        let dir = std::env::temp_dir().join(format!("ggs-settings-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let toml = dir.join("s.toml");
        std::fs::write(
            &toml,
            "preset = \"paper\"\nvoxel = 0.5\nrefine = \"none\"\n",
        )
        .unwrap();
        let json = dir.join("s.json");
        std::fs::write(
            &json,
            r#"{"preset": "paper", "voxel": 0.5, "refine": "none"}"#,
        )
        .unwrap();
        let [a, b] = [&toml, &json].map(|p| SettingsFile::read(p).unwrap());
        assert_eq!(a.preset, Some(Preset::Paper));
        let sa = Settings::layered(Preset::Paper, &[a.changes]).unwrap();
        let sb = Settings::layered(Preset::Paper, &[b.changes]).unwrap();
        assert_eq!(sa, sb);
        assert_eq!((sa.voxel, sa.refine), (Some(0.5), None));
        std::fs::write(&toml, "voxel = 0.5\nvoxel = 0.6\n").unwrap();
        let e = SettingsFile::read(&toml).unwrap_err().to_string();
        assert!(
            e.starts_with(&toml.display().to_string()) && e.contains("line 2"),
            "{e}"
        );
        let yaml = dir.join("s.yaml");
        std::fs::write(&yaml, "voxel: 0.5\n").unwrap();
        let e = SettingsFile::read(&yaml).unwrap_err().to_string();
        assert!(e.contains("unknown settings format '.yaml'"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn edit_distance_counts_single_character_edits() {
        assert_eq!(edit_distance("margin", "margn"), 1);
        assert_eq!(edit_distance("kernel", "kernle"), 2);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("voxel", "voxel"), 0);
    }
}
