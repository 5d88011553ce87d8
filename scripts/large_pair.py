#!/usr/bin/env python3
"""A large-cloud registration benchmark anyone can rerun.

Densifies lidar_koide of ../shared/data by jittered copies to N points per cloud (default
4.8 million; seeded), moves the source by a known 31° motion, writes both as KITTI .bin
(float32 x y z intensity), then runs `ggs register --json` on them (the defaults, and any
extra arguments) and prints the time of every stage, the peak resident memory (ggs's
`peak_memory_bytes`) and the error against the ground truth. `--pair self` (default): one sweep (251370668, 69k
points) densified twice with independent jitter, so the ground truth is the motion itself,
exactly; `--pair sweeps`: the two sweeps, against the pairs.tsv ground truth (itself a GICP
result, good to about 0.1-0.2°).

    python3 scripts/large_pair.py [--points 4800000] [--pair self|sweeps] [-- ggs args]

Needs numpy and a release build (`cargo build --release`).
"""
import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
GGS = ROOT / "target" / "release" / "ggs"
DATA = ROOT.parent / "shared" / "data"
PAIR = "lidar_koide"
JITTER_M = 0.02  # standard deviation of each copy's offset, metres


def pair_row():
    for line in (DATA / "pairs.tsv").read_text().splitlines():
        f = line.split("\t")
        if f[0] == PAIR:
            return f[1], f[2], np.array([float(x) for x in f[3].split()]).reshape(4, 4)
    sys.exit(f"{PAIR} not in {DATA / 'pairs.tsv'}")


def read_points(ggs, path, tmp):
    """The points of `path` through `ggs convert` (to .npy)."""
    out = tmp / (Path(path).stem + ".npy")
    subprocess.run([ggs, "convert", str(path), str(out)], check=True)
    return np.load(out)


def densify(points, n, rng):
    """`n` points: copies of `points`, each point offset by Gaussian jitter."""
    reps = -(-n // len(points))
    dense = np.tile(points, (reps, 1))[:n]
    return dense + rng.normal(0.0, JITTER_M, dense.shape)


def motion(deg=31.0):
    """A fixed rigid motion: `deg` about a tilted axis, and a 3 m shift."""
    axis = np.array([0.3, -0.2, 0.93])
    axis /= np.linalg.norm(axis)
    a = np.radians(deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
    m[:3, 3] = [3.0, -1.5, 0.5]
    return m


def write_bin(path, pts):
    out = np.zeros((len(pts), 4), dtype=np.float32)
    out[:, :3] = pts
    tmp = path.with_suffix(".part")
    out.tofile(tmp)
    os.replace(tmp, path)


def errors(t, truth):
    d = np.linalg.inv(truth) @ t
    rre = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1)))
    return rre, np.linalg.norm(t[:3, 3] - truth[:3, 3])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=4_800_000)
    ap.add_argument("--dir", default="/tmp/ggs-large-pair")
    ap.add_argument("--seed", type=int, default=2022)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ggs", default=str(GGS), help="the ggs binary")
    ap.add_argument("--pair", choices=["self", "sweeps"], default="self")
    ap.add_argument("ggs_args", nargs="*", help="extra `ggs register` arguments (after --)")
    args = ap.parse_args()
    tmp = Path(args.dir)
    tmp.mkdir(parents=True, exist_ok=True)
    src_rel, tgt_rel, truth = pair_row()
    move = motion()
    if args.pair == "self":
        src_rel, truth = tgt_rel, np.eye(4)
    tag = f"{args.pair}_{args.points}_{args.seed}"
    src_bin, tgt_bin = tmp / f"source_{tag}.bin", tmp / f"target_{tag}.bin"
    if not (src_bin.exists() and tgt_bin.exists()):
        rng = np.random.default_rng(args.seed)
        src = densify(read_points(args.ggs, DATA / src_rel, tmp), args.points, rng)
        tgt = densify(read_points(args.ggs, DATA / tgt_rel, tmp), args.points, rng)
        src = src @ move[:3, :3].T + move[:3, 3]
        write_bin(src_bin, src)
        write_bin(tgt_bin, tgt)
    # p_target = truth · p_original = truth · move⁻¹ · p_moved.
    truth_moved = truth @ np.linalg.inv(move)
    cmd = [args.ggs, "register", str(src_bin), str(tgt_bin), "--json", "-q",
           "--threads", str(args.threads), *args.ggs_args]
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    out = p.stdout.read()
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        sys.exit(f"{' '.join(cmd)} failed (status {status})")
    r = json.loads(out)
    t = np.array(r["transform"])
    rre, rte = errors(t, truth_moved)
    print(f"pair              {args.pair}, {args.points} points per cloud")
    print(f"command           {' '.join(cmd)}")
    print(f"voxel             {r['voxel']} ({r.get('voxel_rule') or 'given'})")
    tm = r["timings"]
    print(f"stages ms         read {r['read_ms']:.0f}, search {tm['search_ms']:.0f}, "
          f"verify {tm['verify_ms']:.0f}, refine {tm['refine_ms']:.0f}")
    # ggs's own peak (VmHWM, this program only). wait4's ru_maxrss may also count the pages
    # of this Python process inherited before exec (hundreds of MB after making the pair).
    peak = r.get("peak_memory_bytes")
    peak_mb = peak / 2**20 if peak else usage.ru_maxrss / 1024
    print(f"wall              {wall:.2f} s, peak RSS {peak_mb:.0f} MiB")
    print(f"error             {rre:.4f}° {100 * rte:.2f} cm")


if __name__ == "__main__":
    main()
