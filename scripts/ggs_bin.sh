#!/usr/bin/env bash
# Print the ggs binary the benchmark scripts run: $GGS_BIN when set (a prebuilt binary),
# else target/release/ggs, built first. Run from the repository root.
set -euo pipefail
if [ -n "${GGS_BIN:-}" ]; then
    echo "$GGS_BIN"
else
    cargo build --release -q -p ggs-cli >&2
    echo target/release/ggs
fi
