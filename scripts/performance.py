#!/usr/bin/env python3
"""Per-stage times and peak memory of `ggs register` on the pairs of docs/performance.md.

    scripts/performance.py [--runs 5] [--threads 2] [--ggs target/release/ggs] [--out report.md]

For each pair and each search mode (exhaustive, coarse-to-fine) it runs `ggs register --json`
RUNS times and prints the median of every stage, the peak resident memory of the process
(from wait4's rusage) and whether every run of every mode gave the same transform (it must).
Pairs: bunny_bun045_bun000 (5 mm, limited15), 3dmatch_demo (6 cm, limited15), lidar_koide
(1.0 m, limited15) from ../shared/data, and a generated human pair (FAUST-partial style,
human_man views 0 and 3 of `ggs partial --preset fpv1 --seed 2022`, 6 cm, ico162-s10).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data"


def run(cmd):
    """Run cmd; return (stdout, peak RSS in MB)."""
    with tempfile.TemporaryFile() as out:
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(p.pid, 0)
        err = p.stderr.read().decode()
        p.stderr.close()
        if status != 0:
            sys.exit(f"failed ({status}): {' '.join(map(str, cmd))}\n{err}")
        out.seek(0)
        return out.read().decode(), usage.ru_maxrss / 1024.0


def human_pair(ggs, threads):
    work = Path(tempfile.mkdtemp(prefix="ggs-perf-"))
    subprocess.run(
        [ggs, "partial", ROOT / "tests/data/human_woman.obj", "--preset", "fpv1", "--seed", "2022",
         "--points", "100000", "--threads", str(threads), "--out", work, "--quiet"],
        check=True, stdout=subprocess.DEVNULL)
    for line in (work / "pairs.tsv").read_text().splitlines():
        if line.startswith("#"):
            continue
        name, src, tgt = line.split("\t")[:3]
        return name, work / src, work / tgt
    sys.exit("the generator wrote no pair")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ggs", default=str(ROOT / "target/release/ggs"))
    ap.add_argument("--out")
    ap.add_argument("--only", help="only pairs whose name contains this")
    a = ap.parse_args()
    name, hsrc, htgt = human_pair(a.ggs, a.threads)
    pairs = [
        ("bunny_bun045_bun000", DATA / "stanford_bunny/bun045.ply", DATA / "stanford_bunny/bun000.ply",
         "0.005", "limited15"),
        ("3dmatch_demo", DATA / "3dmatch_geotransformer_demo/src.npy",
         DATA / "3dmatch_geotransformer_demo/ref.npy", "0.06", "limited15"),
        ("lidar_koide", DATA / "lidar_koide_gicp_pair/251371071.pcd",
         DATA / "lidar_koide_gicp_pair/251370668.pcd", "1.0", "limited15"),
        (f"generated {name}", hsrc, htgt, "0.06", "ico162-s10"),
    ]
    stages = [("read", lambda d: d["read_ms"]),
              ("target", lambda d: d["search"]["timings"]["target_ms"]),
              ("extents", lambda d: d["search"]["timings"]["extents_ms"]),
              ("coarse level", lambda d: d["search"]["timings"]["coarse_level_ms"]),
              ("search", lambda d: d["search"]["timings"]["search_ms"]),
              ("coarse total", lambda d: d["search"]["timings"]["total_ms"]),
              ("GICP", lambda d: d["refine"]["total_ms"]),
              ("total", lambda d: d["total_ms"])]
    cpu = ["cpu_voxelize_ms", "cpu_forward_ms", "cpu_product_ms", "cpu_inverse_ms"]
    lines = [f"runs: {a.runs} per cell (median), threads: {a.threads}", "",
             "| pair | mode | " + " | ".join(s for s, _ in stages)
             + " | CPU vox/fwd/x/inv ms | rotations scored | f64 re-scored | GFLOP | GFLOP/s (FFT CPU) | peak MB | same T |",
             "|---" * (len(stages) + 9) + "|"]
    for pname, src, tgt, voxel, rot in pairs:
        if a.only and a.only not in pname:
            continue
        transforms = set()
        for mode in ["exhaustive", "coarse-to-fine"]:
            rows, rss = [], []
            for _ in range(a.runs):
                out, mb = run([a.ggs, "register", src, tgt, "--voxel", voxel, "--rotations", rot,
                               "--threads", str(a.threads), "--search", mode, "--json", "-q"])
                d = json.loads(out)
                rows.append(d)
                rss.append(mb)
                transforms.add(json.dumps(d["coarse_transform"]))
            med = lambda f: statistics.median(f(d) for d in rows)
            r = rows[0]["search"]
            fft_cpu = med(lambda d: sum(d["search"]["timings"][k] for k in cpu[1:])) * 1e-3
            cells = [f"{med(f):.0f}" for _, f in stages]
            cpus = "/".join(f"{med(lambda d, k=k: d['search']['timings'][k]):.0f}" for k in cpu)
            lines.append(
                f"| {pname} | {mode} | " + " | ".join(cells)
                + f" | {cpus} | {r['scored']} of {r['rotations']} | {r['rescored']} | {r['fft_gflop']:.2f}"
                + f" | {r['fft_gflop'] / fft_cpu:.1f} | {statistics.median(rss):.0f} | {'yes' if len(transforms) == 1 else 'NO'} |")
            print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if a.out:
        Path(a.out).write_text(text)
    else:
        print()
        print(text)


if __name__ == "__main__":
    main()
