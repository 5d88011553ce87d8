//! A run directory: the files of one benchmark run, written as pairs finish, in whatever order
//! an executor finishes them (`ggs bench` runs them in order; a Ray cluster does not).
//!
//! `run.json` pins the configuration ([`RunConfig::fingerprint`]); `pairs.csv` gets one line
//! per pair as it finishes (so an interrupted run resumes where it stopped), the failed pairs'
//! pictures go to `gallery/`, and `report.html` is rewritten at most every
//! [`html::REWRITE_EVERY_S`] seconds. [`RunDir::finish`] rewrites `pairs.csv` in the plan's
//! order and writes `results.json`, `summary.md`, `recall.svg` and the final `report.html`:
//! the same files whichever executor ran the pairs, apart from the `*_ms` timings.

use super::config::{pin_json, RunConfig};
use super::execute::{run_pair_pictured, RunOutcome};
use super::finish::finish_run;
use super::html;
use super::plan::Plan;
use super::row::{header, PairRow, ResultsCsv};
use super::shard::write_shard_file;
use ggs::error::{GgsError, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// An open run directory.
pub struct RunDir {
    out: PathBuf,
    name: &'static str,
    metres: bool,
    /// The plan's pair ids, in order.
    order: Vec<String>,
    csv: ResultsCsv,
    /// Every row recorded, earlier runs' included, by id (the last one recorded wins).
    rows: HashMap<String, PairRow>,
    resumed: usize,
    last_report: Option<Instant>,
}

impl RunDir {
    /// Open (creating it if needed) `out` for `plan`: check or write `run.json` and
    /// `shard.json`, and read the rows an earlier run left in `pairs.csv`. A directory of
    /// another configuration is refused.
    pub fn open(plan: &Plan, out: &Path) -> Result<RunDir> {
        std::fs::create_dir_all(out).map_err(|e| GgsError::io(out, e))?;
        if let Some(file) = &plan.shard {
            write_shard_file(out, file)?;
        }
        let (csv, earlier) = ResultsCsv::open(&out.join("pairs.csv"))?;
        check_run_config(out, &plan.cfg, plan.name, !earlier.is_empty())?;
        let rows: HashMap<String, PairRow> =
            earlier.into_iter().map(|r| (r.id.clone(), r)).collect();
        let order: Vec<String> = plan.pairs.iter().map(|p| p.id.clone()).collect();
        let resumed = order.iter().filter(|id| rows.contains_key(*id)).count();
        Ok(RunDir {
            out: out.to_path_buf(),
            name: plan.name,
            metres: plan.metres,
            order,
            csv,
            rows,
            resumed,
            last_report: None,
        })
    }

    /// The row recorded for pair `id`, by this run or an earlier one.
    pub fn row(&self, id: &str) -> Option<&PairRow> {
        self.rows.get(id)
    }

    /// Pairs of the plan that an earlier run had finished when this one opened.
    pub fn resumed(&self) -> usize {
        self.resumed
    }

    /// Record a finished pair: its gallery picture (PNG bytes, for a failed pair), then its
    /// line in `pairs.csv`; rewrite the in-progress report when it is due.
    pub fn record(&mut self, row: PairRow, picture_png: Option<&[u8]>) -> Result<()> {
        if let Some(png) = picture_png {
            save_picture(&html::picture_path(&self.out, &row.id), png)?;
        }
        self.csv.append(&row)?;
        self.rows.insert(row.id.clone(), row);
        let due = self
            .last_report
            .is_none_or(|t| t.elapsed().as_secs_f64() >= html::REWRITE_EVERY_S);
        let done = self.ordered_done();
        if due && done.len() < self.order.len() {
            let ctx = html::ReportContext {
                protocol: self.name,
                total_pairs: self.order.len(),
                metres: self.metres,
                out: &self.out,
            };
            html::write_report(&ctx, &done)?;
            self.last_report = Some(Instant::now());
        }
        Ok(())
    }

    /// The rows of the plan's pairs recorded so far, in the plan's order.
    fn ordered_done(&self) -> Vec<PairRow> {
        self.order
            .iter()
            .filter_map(|id| self.rows.get(id).cloned())
            .collect()
    }

    /// Every pair of the plan must have a row: rewrite `pairs.csv` with them in the plan's
    /// order (rows of other pairs, from an earlier run with another selection, kept after
    /// them) and write the run's summary files.
    pub fn finish(mut self) -> Result<RunOutcome> {
        let mut rows = Vec::with_capacity(self.order.len());
        for id in &self.order {
            let row = self.rows.remove(id).ok_or_else(|| {
                GgsError::in_file(
                    &self.out.join("pairs.csv"),
                    format!("pair '{id}' has no row: the run is not finished"),
                )
            })?;
            rows.push(row);
        }
        let mut others: Vec<PairRow> = self.rows.into_values().collect();
        others.sort_by(|a, b| a.id.cmp(&b.id));
        let mut text = header() + "\n";
        for r in rows.iter().chain(&others) {
            text += &(r.to_csv() + "\n");
        }
        drop(self.csv);
        ggs::io::write_atomic(&self.out.join("pairs.csv"), text.as_bytes())?;
        let summary = finish_run(self.name, &rows, self.metres, &self.out)?;
        Ok(RunOutcome {
            rows,
            summary,
            resumed: self.resumed,
            metres: self.metres,
        })
    }
}

/// Run the plan's pairs one after the other into `out` ([`RunDir`]): pairs already in
/// `out/pairs.csv` are not run again. `progress(done, total, row)` is called after every
/// pair, resumed ones included.
pub fn run(
    plan: &Plan,
    out: &Path,
    mut progress: impl FnMut(usize, usize, &PairRow),
) -> Result<RunOutcome> {
    let mut dir = RunDir::open(plan, out)?;
    let total = plan.pairs.len();
    for (k, pair) in plan.pairs.iter().enumerate() {
        if let Some(row) = dir.row(&pair.id) {
            progress(k + 1, total, row);
            continue;
        }
        let (row, picture) = run_pair_pictured(pair, &plan.cfg, true);
        let png = picture.map(|image| image.png());
        dir.record(row.clone(), png.as_deref())?;
        progress(k + 1, total, &row);
    }
    dir.finish()
}

/// `out/run.json`: written on a new run; on a resumed one it must equal the fingerprint, or
/// the earlier rows would be mixed with rows of another configuration.
fn check_run_config(out: &Path, cfg: &RunConfig, name: &str, resuming: bool) -> Result<()> {
    pin_json(
        &out.join("run.json"),
        &cfg.fingerprint(name),
        "this run directory holds results of another configuration (voxel, rotation set, search, verification, refinement, thresholds or motion seed differ); choose another --out, or delete the directory to start again",
        resuming.then_some(
            "missing: the earlier rows of this run directory cannot be checked against this configuration; choose another --out",
        ),
    )
}

/// Write a gallery picture (creating `gallery/`), atomically.
fn save_picture(path: &Path, png: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| GgsError::io(dir, e))?;
    }
    ggs::io::write_atomic(path, png)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::benchmark::plan::Selection;
    use ggs::Settings;

    /// A manifest of the bundled small pair three times under other names.
    fn plan(dir: &Path) -> Plan {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data");
        let line = |name: &str| {
            format!(
                "{name}\t{}\t{}\t0.825336 0 -0.564642 0.037267 0 1 0 0 0.564642 0 0.825336 0.038325 0 0 0 1\texact\t0.006\n",
                data.join("bun0.pcd").display(),
                data.join("bun4.pcd").display()
            )
        };
        let manifest = dir.join("pairs.tsv");
        std::fs::write(&manifest, line("a") + &line("b") + &line("c")).unwrap();
        let sel = Selection {
            protocol: "manifest".into(),
            manifest: Some(manifest),
            ..Selection::default()
        };
        let settings = Settings {
            verify: false,
            refine: None,
            ..Settings::default()
        };
        Plan::new(&sel, settings, 1, false).unwrap()
    }

    /// `settings` with `key` changed to another valid value.
    fn changed(settings: &Settings, key: &str) -> Settings {
        let mut fields = settings.to_json();
        let before = fields[key].clone();
        let candidates: Vec<serde_json::Value> = match &before {
            serde_json::Value::Bool(b) => vec![(!b).into()],
            serde_json::Value::Number(n) => match n.as_u64() {
                Some(k) => vec![(k + 1).into()],
                None => vec![(n.as_f64().unwrap() + 1.0).into()],
            },
            serde_json::Value::Null => vec![1.into()],
            serde_json::Value::String(_) => [
                "limited15",
                "exhaustive",
                "f64",
                "fitness",
                "p2p",
                "huber:1",
            ]
            .map(serde_json::Value::from)
            .to_vec(),
            other => panic!("{key}: unexpected {other}"),
        };
        for value in candidates {
            fields[key] = value;
            if let Ok(s) = serde_json::from_value::<Settings>(fields.clone()) {
                if s != *settings {
                    return s;
                }
            }
        }
        panic!("no other value for {key}")
    }

    #[test]
    fn changing_any_one_setting_refuses_a_resume_and_the_thread_count_does_not() {
        let dir = std::env::temp_dir().join(format!("ggs-run-json-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let plan = plan(&dir);
        check_run_config(&dir, &plan.cfg, plan.name, false).unwrap();
        let other_threads = RunConfig {
            threads: 7,
            ..plan.cfg.clone()
        };
        check_run_config(&dir, &other_threads, plan.name, true).unwrap();
        let keys: Vec<String> = plan
            .cfg
            .settings
            .to_json()
            .as_object()
            .unwrap()
            .keys()
            .cloned()
            .collect();
        assert!(keys.len() > 40, "{keys:?}");
        for key in keys {
            let cfg = RunConfig {
                settings: changed(&plan.cfg.settings, &key),
                ..plan.cfg.clone()
            };
            let e = check_run_config(&dir, &cfg, plan.name, true);
            assert!(e.is_err(), "a change of {key} resumed the run");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn without_ms(path: &Path) -> Vec<String> {
        let text = std::fs::read_to_string(path).unwrap();
        let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
        text.lines()
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                let kept: Vec<&str> = (0..f.len())
                    .filter(|&k| !header[k].ends_with("_ms"))
                    .map(|k| f[k])
                    .collect();
                kept.join(",")
            })
            .collect()
    }

    #[test]
    fn pairs_recorded_in_any_order_give_the_serial_files() {
        let dir = std::env::temp_dir().join(format!("ggs-run-dir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let plan = plan(&dir);
        let serial = run(&plan, &dir.join("serial"), |_, _, _| {}).unwrap();
        let mut any = RunDir::open(&plan, &dir.join("any")).unwrap();
        for pair in plan.pairs.iter().rev() {
            let (row, png) = crate::benchmark::run_pair_with_picture(pair, &plan.cfg);
            any.record(row, png.as_deref()).unwrap();
        }
        let outcome = any.finish().unwrap();
        assert_eq!(outcome.rows.len(), 3);
        assert_eq!(
            without_ms(&dir.join("serial/pairs.csv")),
            without_ms(&dir.join("any/pairs.csv"))
        );
        assert_eq!(serial.summary.successes, outcome.summary.successes);
        // (summary.md holds the median time per pair: not compared.)
        let read = |d: &str| std::fs::read_to_string(dir.join(d).join("run.json")).unwrap();
        assert_eq!(read("serial"), read("any"));
        assert!(dir.join("any/summary.md").is_file() && dir.join("any/report.html").is_file());
        // A run missing a pair cannot finish; reopened, it resumes the recorded ones.
        let mut part = RunDir::open(&plan, &dir.join("part")).unwrap();
        let (row, _) = crate::benchmark::run_pair_with_picture(&plan.pairs[1], &plan.cfg);
        part.record(row, None).unwrap();
        let e = part.finish().err().unwrap().to_string();
        assert!(e.contains("pair 'a' has no row"), "{e}");
        let again = RunDir::open(&plan, &dir.join("part")).unwrap();
        assert_eq!(again.resumed(), 1);
        assert!(again.row("b").is_some() && again.row("a").is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
