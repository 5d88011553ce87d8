//! Sharded runs: `ggs bench ... --shard I/N` runs a deterministic share of the pairs in its own
//! run directory, and [`merge`] builds from the N directories the files one run would have
//! written (identical apart from the `*_ms` timing columns).
//!
//! Shard `I` of `N` takes the selected pairs whose position `k` (0-based, in protocol order
//! after `--pairs` and `--limit`) has `k mod N = I`: round robin, so shards of a protocol
//! ordered by scene get similar work. Each shard directory holds `shard.json` (its index, the
//! count, the ids of its pairs in order, and whether distances are metres) beside the usual
//! `run.json`; a shard is resumed like any run, and [`merge`] refuses shards of different
//! configurations, missing or repeated shards and shards that are not finished.

use super::config::pin_json;
use super::execute::RunOutcome;
use super::finish::finish_run;
use super::pair::BenchPair;
use super::row::{PairRow, ResultsCsv};
use ggs::error::{GgsError, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Shard `index` of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parse `I/N` with `0 ≤ I < N`.
    pub fn parse(s: &str) -> Result<Shard> {
        let bad = |why: &str| {
            GgsError::param(
                "shard",
                format!("'{s}': {why} (expected I/N, 0 ≤ I < N, e.g. 0/4)"),
            )
        };
        let (i, n) = s.split_once('/').ok_or_else(|| bad("no '/'"))?;
        let index: usize = i.trim().parse().map_err(|_| bad("I is not a number"))?;
        let count: usize = n.trim().parse().map_err(|_| bad("N is not a number"))?;
        if count == 0 || index >= count {
            return Err(bad("I must be below N"));
        }
        Ok(Shard { index, count })
    }

    /// This shard's pairs, in order.
    pub fn select(&self, pairs: &[BenchPair]) -> Vec<BenchPair> {
        pairs
            .iter()
            .enumerate()
            .filter(|(k, _)| k % self.count == self.index)
            .map(|(_, p)| p.clone())
            .collect()
    }
}

/// `shard.json` of a shard's run directory.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShardFile {
    #[serde(flatten)]
    pub shard: Shard,
    /// Pairs selected before sharding (all shards together).
    pub selected_pairs: usize,
    /// Distances in metres (summary RTE in cm).
    pub metres: bool,
    /// The ids of this shard's pairs, in order.
    pub ids: Vec<String>,
}

/// Write `out/shard.json`, or check that the one there (a resumed shard) is the same.
pub fn write_shard_file(out: &Path, file: &ShardFile) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| GgsError::io(out, e))?;
    pin_json(
        &out.join("shard.json"),
        file,
        "this run directory holds another shard or another selection of pairs; choose another --out",
        None,
    )
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| GgsError::io(path, e))
}

/// One shard directory, read.
struct ShardRun {
    dir: PathBuf,
    file: ShardFile,
    rows: HashMap<String, PairRow>,
}

fn read_shard(dir: &Path) -> Result<(String, ShardRun)> {
    let run_json = read_text(&dir.join("run.json"))?;
    let path = dir.join("shard.json");
    let file: ShardFile = serde_json::from_str(&read_text(&path)?)
        .map_err(|e| GgsError::in_file(&path, format!("not a ggs shard file: {e}")))?;
    let rows = ResultsCsv::read(&dir.join("pairs.csv"))?;
    let rows = rows.into_iter().map(|r| (r.id.clone(), r)).collect();
    Ok((
        run_json,
        ShardRun {
            dir: dir.to_path_buf(),
            file,
            rows,
        },
    ))
}

/// Merge the shard directories `dirs` into `out`: `run.json`, `pairs.csv` (the rows in the
/// order of the unsharded run), `results.json`, `summary.md`, `recall.svg`, `report.html` and
/// the failed pairs' pictures, as one run would have written them.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<RunOutcome> {
    let mut runs = Vec::with_capacity(dirs.len());
    let mut config: Option<(PathBuf, String)> = None;
    for dir in dirs {
        let (run_json, run) = read_shard(dir)?;
        match &config {
            Some((first, text)) if *text != run_json => {
                return Err(GgsError::in_file(
                    &dir.join("run.json"),
                    format!(
                        "another configuration than {}: shards of one run must share it",
                        first.display()
                    ),
                ))
            }
            Some(_) => {}
            None => config = Some((dir.join("run.json"), run_json)),
        }
        runs.push(run);
    }
    let Some((_, run_json)) = config else {
        return Err(GgsError::param("merge", "no run directory given"));
    };
    let order = merged_order(&runs)?;
    let mut rows = Vec::with_capacity(order.len());
    for (k, id) in order {
        let run = &runs[k];
        let row = run.rows.get(&id).cloned().ok_or_else(|| {
            GgsError::in_file(
                &run.dir.join("pairs.csv"),
                format!("shard {}/{} is not finished (pair '{id}' has no row): run it again with the same command to resume it", run.file.shard.index, run.file.shard.count),
            )
        })?;
        rows.push(row);
    }
    std::fs::create_dir_all(out).map_err(|e| GgsError::io(out, e))?;
    ggs::io::write_atomic(&out.join("run.json"), run_json.as_bytes())?;
    let mut text = super::row::header() + "\n";
    for r in &rows {
        text += &(r.to_csv() + "\n");
    }
    ggs::io::write_atomic(&out.join("pairs.csv"), text.as_bytes())?;
    copy_pictures(&runs, &rows, out)?;
    let protocol: serde_json::Value = serde_json::from_str(&run_json).unwrap_or_default();
    let name = protocol["protocol"]
        .as_str()
        .unwrap_or("merged")
        .to_string();
    let summary = finish_run(&name, &rows, runs[0].file.metres, out)?;
    Ok(RunOutcome {
        rows,
        summary,
        resumed: 0,
        metres: runs[0].file.metres,
    })
}

/// `(shard, id)` of every pair in the unsharded run's order; every shard of one count must be
/// there exactly once, with the same selection.
fn merged_order(runs: &[ShardRun]) -> Result<Vec<(usize, String)>> {
    let count = runs[0].file.shard.count;
    let selected = runs[0].file.selected_pairs;
    let mut by_index: Vec<Option<usize>> = vec![None; count];
    for (k, run) in runs.iter().enumerate() {
        let f = &run.file;
        let expected = (selected + count - 1 - f.shard.index.min(selected)) / count;
        if f.shard.count != count || f.selected_pairs != selected || f.ids.len() != expected {
            return Err(GgsError::in_file(
                &run.dir.join("shard.json"),
                format!("shard {}/{} of {} pairs does not belong with shard 0..{count} of {selected} pairs", f.shard.index, f.shard.count, f.selected_pairs),
            ));
        }
        if by_index[f.shard.index].replace(k).is_some() {
            return Err(GgsError::in_file(
                &run.dir.join("shard.json"),
                format!("shard {}/{count} is given twice", f.shard.index),
            ));
        }
    }
    if let Some(missing) = by_index.iter().position(Option::is_none) {
        return Err(GgsError::param(
            "merge",
            format!("shard {missing}/{count} is missing: give all {count} run directories"),
        ));
    }
    Ok((0..selected)
        .map(|k| {
            let run = by_index[k % count].expect("checked above");
            (run, runs[run].file.ids[k / count].clone())
        })
        .collect())
}

/// Copy the failed pairs' gallery pictures into `out/gallery/`.
fn copy_pictures(runs: &[ShardRun], rows: &[PairRow], out: &Path) -> Result<()> {
    for r in rows.iter().filter(|r| !r.success) {
        for run in runs {
            let from = super::html::picture_path(&run.dir, &r.id);
            if from.is_file() {
                let to = super::html::picture_path(out, &r.id);
                let dir = to.parent().expect("in gallery/");
                std::fs::create_dir_all(dir).map_err(|e| GgsError::io(dir, e))?;
                let bytes = std::fs::read(&from).map_err(|e| GgsError::io(&from, e))?;
                ggs::io::write_atomic(&to, &bytes)?;
                break;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_partition_the_pairs() {
        assert_eq!(Shard::parse("1/4").unwrap(), Shard { index: 1, count: 4 });
        for bad in ["4/4", "1", "a/2", "0/0", "-1/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        let ids: Vec<usize> = (0..11).collect();
        let mut seen = Vec::new();
        for i in 0..4 {
            let share: Vec<usize> = ids.iter().copied().filter(|k| k % 4 == i).collect();
            let expected = (11 + 4 - 1 - i) / 4;
            assert_eq!(share.len(), expected, "shard {i}");
            seen.extend(share);
        }
        seen.sort();
        assert_eq!(seen, ids);
    }
}
