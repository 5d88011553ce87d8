"""Calling overhead of the Python package against the CLI.

    python scripts/python_overhead.py [RUNS]

Registers bunny_bun045_bun000 (../shared/data, 5 mm, limited15 + GICP, 2 threads) RUNS
times (default 5) with `ggs register --json` and with `ggs.register`, interleaved, and prints
the medians: the CLI's registration time (coarse + refinement, from its JSON, file reading
excluded) against the wall time of the Python call (array conversion included, file
reading excluded). Needs the wheel installed and target/release/ggs built.
"""

import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import ggs

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "data" / "stanford_bunny"
EXE = ROOT / "target" / "release" / "ggs"


def main(runs):
    src, tgt = PAIR / "bun045.ply", PAIR / "bun000.ply"
    source, target = ggs.read_point_cloud(src), ggs.read_point_cloud(tgt)
    cli_ms, py_ms = [], []
    same = True
    for _ in range(runs):
        out = subprocess.run(
            [str(EXE), "register", str(src), str(tgt), "--voxel", "0.005", "--threads", "2", "--json", "-q"],
            check=True, capture_output=True, text=True,
        )
        j = json.loads(out.stdout)
        cli_ms.append(j["search"]["timings"]["total_ms"] + j["refine"]["total_ms"])
        t0 = time.perf_counter()
        r = ggs.register(source, target, voxel=0.005, threads=2)
        py_ms.append((time.perf_counter() - t0) * 1e3)
        same &= r.transformation.tolist() == j["transform"]
    c, p = statistics.median(cli_ms), statistics.median(py_ms)
    print(f"CLI registration (coarse + GICP), median of {runs}: {c:.1f} ms  {sorted(round(x) for x in cli_ms)}")
    print(f"Python ggs.register wall time, median of {runs}:   {p:.1f} ms  {sorted(round(x) for x in py_ms)}")
    print(f"overhead: {100 * (p - c) / c:+.1f} %; identical transforms: {same}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
