#!/usr/bin/env bash
# Run every fuzz target for SECONDS each (default 600), two at a time. Builds once (release,
# with debug assertions and overflow checks, AddressSanitizer), then runs the binaries in
# libFuzzer's fork mode: a crash, an out-of-memory or a timeout is saved under
# fuzz/artifacts/<target>/ and the run goes on. Seeds: fuzz/make_seeds.py (fuzz/corpus/).
# Logs: fuzz/logs/<target>.log, one line per target in fuzz/logs/summary.txt.
#   bash fuzz/run_all.sh [SECONDS] [TARGET...]
set -u
cd "$(dirname "$0")/.."
secs=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(ply pcd text npy npz kitti las e57 obj stl)
mkdir -p fuzz/logs
cargo +nightly fuzz build -O -a || exit 1
bin=fuzz/target/x86_64-unknown-linux-gnu/release
run() {
  mkdir -p "fuzz/artifacts/$1" "fuzz/corpus/$1"
  "$bin/$1" -artifact_prefix="fuzz/artifacts/$1/" -max_total_time="$secs" -max_len=65536 \
    -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
    -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 "fuzz/corpus/$1" > "fuzz/logs/$1.log" 2>&1
  echo "$1 exit $? $(date -u +%FT%TZ)" >> fuzz/logs/summary.txt
}
for ((i = 0; i < ${#targets[@]}; i += 2)); do
  run "${targets[i]}" &
  [ $((i + 1)) -lt ${#targets[@]} ] && run "${targets[i + 1]}" &
  wait
done
