#!/usr/bin/env python3
"""Read throughput and memory of ggs on large files (50 million points).

Writes a synthetic cloud of N points (default 50 million; a noisy sphere shell, float32) as
binary PLY (x y z float32 + an extra uchar property, as scanners write), binary PCD
(x y z intensity float32) and KITTI .bin with numpy; LAS and LAZ through `ggs convert`.
Then times `ggs info --json FILE` (read + parse + drop of non-finite points) several times
per file and reports the median throughput (file MB / s) and peak RSS (wait4), beside the
time `cat FILE > /dev/null` takes (the page cache's speed: the files are read warm, as on a
second run; the first, cold read is also reported, with the disk's own speed from dd when
the caches can be dropped).

    python3 scripts/large_files.py [--points 50000000] [--dir /tmp/ggs-large] [--runs 3]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
GGS = ROOT / "target" / "release" / "ggs"


def run(cmd, capture=True):
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE if capture else subprocess.DEVNULL, stderr=subprocess.PIPE)
    out = p.stdout.read() if capture else b""
    err = p.stderr.read()
    _, status, usage = os.wait4(p.pid, 0)
    secs = time.perf_counter() - t0
    if status != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed: {err.decode()}")
    return out, secs, usage.ru_maxrss * 1024 / 1e6  # MB (ru_maxrss is in KiB)


def make_points(n, seed=6):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3)).astype(np.float32)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v *= (10.0 + rng.normal(scale=0.05, size=(n, 1))).astype(np.float32)
    return v


def write_files(d, n):
    d.mkdir(parents=True, exist_ok=True)
    files = {}
    ply = d / f"cloud{n}.ply"
    pcd = d / f"cloud{n}.pcd"
    kitti = d / f"cloud{n}.bin"
    if not (ply.exists() and pcd.exists() and kitti.exists()):
        pts = make_points(n)
        rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("q", "u1")])
        rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
        rec["q"] = 7
        with open(ply, "wb") as f:
            f.write(
                (
                    "ply\nformat binary_little_endian 1.0\ncomment synthetic, scripts/large_files.py\n"
                    f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar quality\nend_header\n"
                ).encode()
            )
            rec.tofile(f)
        four = np.empty((n, 4), dtype="<f4")
        four[:, :3] = pts
        four[:, 3] = 0.5
        with open(pcd, "wb") as f:
            f.write(
                (
                    "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n"
                    f"COUNT 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
                ).encode()
            )
            four.tofile(f)
        four.tofile(kitti)
        del pts, rec, four
    files["binary PLY (float32 + uchar)"] = ply
    files["binary PCD (float32 ×4)"] = pcd
    files["KITTI .bin"] = kitti
    for ext in ["las", "laz"]:
        p = d / f"cloud{n}.{ext}"
        if not p.exists():
            run([GGS, "convert", "-q", ply, p], capture=False)
        files[ext.upper() + (" (format 0, 1.4)" if ext == "las" else " (LASzip)")] = p
    return files


def drop_caches():
    try:
        subprocess.run(["sync"], check=True)
        Path("/proc/sys/vm/drop_caches").write_text("3\n")
        return True
    except OSError:
        return False


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=50_000_000)
    ap.add_argument("--dir", type=Path, default=Path("/tmp/ggs-large"))
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--only", help="only the files whose label contains this")
    ap.add_argument("--generate-only", action="store_true", help="write the files, measure nothing")
    a = ap.parse_args()
    if not GGS.exists():
        sys.exit("build first: cargo build --release")
    files = write_files(a.dir, a.points)
    if a.generate_only:
        return
    out_mb = a.points * 24 / 1e6
    print(f"{a.points} points; the output cloud itself takes {out_mb:.0f} MB (24 bytes a point)")
    print(f"{'file':32} {'MB':>7} {'cold MB/s':>9} {'dd MB/s':>8} {'ggs MB/s':>9} {'cat MB/s':>9} {'peak RSS MB':>11} {'beside output':>13}")
    rows = []
    for label, path in files.items():
        if a.only and a.only.lower() not in label.lower():
            continue
        size = path.stat().st_size / 1e6
        cold = dd = None
        if drop_caches():
            _, secs, _ = run([GGS, "info", "--json", path])
            cold = size / secs
            drop_caches()
            _, secs, _ = run(["dd", f"if={path}", "of=/dev/null", "bs=4M"], capture=False)
            dd = size / secs
        speeds, peaks = [], []
        for _ in range(a.runs):
            out, secs, peak = run([GGS, "info", "--json", path])
            info = json.loads(out)[0]
            assert info["points"] == a.points, info
            speeds.append(size / info["read_s"])
            peaks.append(peak)
        _, cat_s, _ = run(["cat", path], capture=False)
        med = statistics.median(speeds)
        peak = max(peaks)
        fmt = lambda v: f"{v:9.0f}" if v else f"{'-':>9}"
        print(f"{label:32} {size:7.0f} {fmt(cold)} {fmt(dd)[1:]} {med:9.0f} {size / cat_s:9.0f} {peak:11.0f} {peak - out_mb:13.0f}")
        rows.append(dict(file=label, mb=size, cold_mb_s=cold, dd_mb_s=dd, ggs_mb_s=med, cat_mb_s=size / cat_s, peak_rss_mb=peak))
    (a.dir / "results.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
