#!/usr/bin/env bash
# Generate a scene-crop benchmark from real scans and register it with ggs bench, no flag.
#
#   scripts/scene_benchmark.sh KIND PRESET [OUT_DIR [MIN_RECALL]]
#
# KIND: indoor (the RGB-D fragments of benchmarks/scenes_indoor.txt, success at 15° and
# 0.3 m, as 3DMatch) or lidar (the LiDAR scans of benchmarks/scenes_lidar.txt, 5° and 0.6 m,
# as KITTI). PRESET: scene-e, scene-m or scene-h (overlap 60–100 %, 30–60 %, 10–30 %).
# 16 crops per scan, seed 2026. Registered with `--voxel auto`: what a user who gives no flag
# gets. Writes OUT_DIR/data (crops, pairs, manifest) and OUT_DIR/run (pairs.csv, summary.md,
# report.html); prints the run's summary line and how many failures were flagged. Extra
# arguments after MIN_RECALL go to `ggs bench`. MIN_RECALL (percent) makes the script fail
# below it.
set -euo pipefail
cd "$(dirname "$0")/.."
kind=${1:?KIND: indoor or lidar}
preset=${2:?PRESET: scene-e, scene-m or scene-h}
out=${3:-scenes-$kind-$preset}
min_recall=${4:-0}
shift $(( $# < 4 ? $# : 4 ))
case "$kind" in
    indoor) thresholds=(--max-rre 15 --max-rte 0.3) ;;
    lidar) thresholds=(--max-rre 5 --max-rte 0.6) ;;
    *) echo "KIND must be indoor or lidar, not '$kind'" >&2; exit 2 ;;
esac
threads=${GGS_THREADS:-2}
ggs=$(scripts/ggs_bin.sh)  # $GGS_BIN, or target/release/ggs built first
rm -rf "$out/data" "$out/run"
"$ggs" partial --inputs-list "benchmarks/scenes_$kind.txt" --preset "$preset" --seed 2026 \
    --views 16 --threads "$threads" --out "$out/data" --quiet | grep -v '^$' | head -9
"$ggs" bench manifest "$out/data/pairs.tsv" --voxel auto "${thresholds[@]}" \
    --threads "$threads" --out "$out/run" --quiet --min-recall "$min_recall" "$@" |
    grep -E '^\| manifest|^Flagged'
