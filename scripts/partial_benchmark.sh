#!/usr/bin/env bash
# Generate the human partial-view benchmark and register it with ggs bench.
#
#   scripts/partial_benchmark.sh [PRESET [OUT_DIR [MIN_RECALL]]]
#
# PRESET: fpv1 (default), fpv1-code, fp-{r,t,o}-{e,m,h}. Writes OUT_DIR/data (views, pairs,
# manifest) and OUT_DIR/run (pairs.csv, results.json, summary.md); prints both summaries.
# Registered with ggs's defaults (no flag but the thresholds): full-SO(3) set, coarse-to-fine,
# verified hypotheses, GICP; success at 10° and 3 cm. Extra arguments after MIN_RECALL go to
# `ggs bench` (e.g. --preset paper --rotations hopf15-dedup). MIN_RECALL (percent) makes the
# script fail below it.
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-fpv1}
out=${2:-partial-$preset}
min_recall=${3:-0}
shift $(( $# < 3 ? $# : 3 ))
threads=${GGS_THREADS:-2}
points=${GGS_POINTS:-100000}  # points sampled per mesh
ggs=$(scripts/ggs_bin.sh)  # $GGS_BIN, or target/release/ggs built first
rm -rf "$out/data" "$out/run"
"$ggs" partial --inputs-list benchmarks/human_meshes.txt --preset "$preset" --seed 2022 \
    --points "$points" --threads "$threads" --out "$out/data" --quiet | grep -v '^$' | head -9
"$ggs" bench manifest "$out/data/pairs.tsv" --max-rre 10 --max-rte 0.03 \
    --threads "$threads" --out "$out/run" --quiet --min-recall "$min_recall" "$@"
