#!/usr/bin/env bash
# Compare two ggs binaries on every real pair of ../shared/data/pairs.tsv: the coarse pick
# (rotation index, offset), its score, the chosen hypothesis's rank and a few entries of the
# final transform, for the paper preset (exhaustive, no refinement) and the defaults, each at
# the pair's voxel and at the automatic one. Prints "same" or both answers per case.
#
#   scripts/compare_picks.sh OLD_GGS NEW_GGS
set -euo pipefail
cd "$(dirname "$0")/.."
old=$1
new=$2
data=../shared/data
summary() {
    "$1" register "$2" "$3" --threads 2 --json -q "${@:4}" | python3 -c '
import json, sys
j = json.load(sys.stdin)
r = j["search"]
t = [round(x, 6) for row in j["transform"] for x in row]
print(r["rotation_index"], r["offset"], r["score"], j["chosen_rank"], t[0:12:5])'
}
grep -v '^#' "$data/pairs.tsv" | while IFS=$'\t' read -r name src tgt _ _ voxel; do
    for mode in "paper:--preset paper --refine none --voxel $voxel" "default:--voxel $voxel" \
        "default-auto:" "paper-auto:--preset paper --refine none"; do
        tag=${mode%%:*}
        read -r -a args <<< "${mode#*:}"
        a=$(summary "$old" "$data/$src" "$data/$tgt" "${args[@]}")
        b=$(summary "$new" "$data/$src" "$data/$tgt" "${args[@]}")
        if [ "$a" == "$b" ]; then echo "$name $tag same"; else echo "$name $tag: $a | $b"; fi
    done
done
