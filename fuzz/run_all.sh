#!/usr/bin/env bash
# Run every fuzz target for SECONDS each (default 600), two at a time (fork mode: a crash
# is saved and the run goes on), seeds from
# fuzz/make_seeds.py; logs in fuzz/logs/, crashes in fuzz/artifacts/<target>/.
#   bash fuzz/run_all.sh [SECONDS] [TARGET...]
set -u
cd "$(dirname "$0")/.."
secs=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(ply pcd text npy npz kitti las e57 obj stl)
mkdir -p fuzz/logs
run() {
  cargo +nightly fuzz run -O "$1" -- -max_total_time="$secs" -max_len=65536 \
    -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
    -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 > "fuzz/logs/$1.log" 2>&1
  echo "$1 exit $?" >> fuzz/logs/summary.txt
}
for ((i = 0; i < ${#targets[@]}; i += 2)); do
  run "${targets[i]}" &
  [ $((i + 1)) -lt ${#targets[@]} ] && run "${targets[i + 1]}" &
  wait
done
