#!/usr/bin/env python3
"""Run a benchmark manifest through Ray and measure what going through Ray costs.

    python3 scripts/ray_bench.py MANIFEST [--compare RUN_DIR] [--workers 1,2] [--local]
                                 [--max-rre DEG] [--max-rte D] [--out DIR]

For each worker count W of --workers, starts a local Ray cluster of W one-CPU workers (or
uses the cluster of RAY_ADDRESS, then give one count), runs ``ggs.bench.run(MANIFEST,
executor="ray")`` into OUT/ray-W and prints pairs per second. --local also runs the same
pairs in this process, one thread, one pair after another: the same work without Ray, so
the difference is Ray's overhead per pair. --compare RUN_DIR checks that each run's
``pairs.csv`` (apart from the ``*_ms`` columns) and ``run.json`` equal those of RUN_DIR (a
``ggs bench`` run of the same manifest and thresholds) and exits 1 if not.

Needs the ggs package and Ray (pip install ./python ray).
"""

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import List

import ggs.bench


def without_ms(path: Path) -> List[str]:
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [k for k, name in enumerate(header) if not name.endswith("_ms")]
    return [",".join(line.split(",")[k] for k in keep) for line in lines]


def same_as(run: Path, reference: Path) -> bool:
    ok = without_ms(run / "pairs.csv") == without_ms(reference / "pairs.csv")
    ok &= (run / "run.json").read_text() == (reference / "run.json").read_text()
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("manifest", type=Path)
    ap.add_argument("--compare", type=Path, help="a ggs bench run directory of the same pairs")
    ap.add_argument("--workers", default="2", help="comma-separated worker counts (default 2)")
    ap.add_argument("--local", action="store_true", help="also run without Ray, one thread")
    ap.add_argument("--max-rre", type=float)
    ap.add_argument("--max-rte", type=float)
    ap.add_argument("--out", type=Path, help="run directories go here (default: a temporary one)")
    args = ap.parse_args()
    import ray

    out = args.out or Path(tempfile.mkdtemp(prefix="ggs-ray-"))
    common = dict(max_rre=args.max_rre, max_rte=args.max_rte, progress=False, threads=1)
    rows = []
    failed = False

    def record(label: str, run_dir: Path, seconds: float, pairs: int) -> None:
        nonlocal failed
        same = "" if args.compare is None else ("yes" if same_as(run_dir, args.compare) else "NO")
        failed |= same == "NO"
        rows.append((label, pairs, seconds, same))

    if args.local:
        d = out / "local-1"
        t0 = time.perf_counter()
        run = ggs.bench.run(args.manifest, out=d, **common)
        record("this process, 1 thread", d, time.perf_counter() - t0, len(run.pairs))
    for w in [int(x) for x in args.workers.split(",")]:
        d = out / f"ray-{w}"
        if "RAY_ADDRESS" in os.environ:
            ray.init()
        else:
            ray.init(num_cpus=w, include_dashboard=False, log_to_driver=False)
        t0 = time.perf_counter()
        run = ggs.bench.run(args.manifest, out=d, executor="ray", **common)
        record(f"Ray, {w} worker(s) x 1 thread", d, time.perf_counter() - t0, len(run.pairs))
        ray.shutdown()
    print(f"{args.manifest}: run directories in {out}\n")
    print("| executor | pairs | wall s | pairs/s | s/pair | same pairs.csv |")
    print("|---|---|---|---|---|---|")
    for label, pairs, s, same in rows:
        print(f"| {label} | {pairs} | {s:.2f} | {pairs / s:.2f} | {s / pairs:.3f} | {same or '-'} |")
    if failed:
        print(f"\nFAILED: a run differs from {args.compare}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
