#!/usr/bin/env python3
"""How `ggs align` scales with the number of scans: N partial views of the bundled human
mesh (tests/data/human_woman.obj, sampled), each the part of the surface seen within 75° of a
random direction from the centroid, moved by a seeded random rigid motion and given in a
shuffled order. Prints, per N, the registrations run, the scans placed, the worst rotation
and centroid error against the truth (relative to the frame scan), and the time.

    python3 scripts/align_scaling.py 10 50 200 [--threads 2]

Needs the ggs Python package (pip install ./python).
"""

import argparse
import time
from pathlib import Path

import numpy as np

import ggs

MESH = Path(__file__).resolve().parents[1] / "tests" / "data" / "human_woman.obj"


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def views(n: int, seed: int):
    """N views (points, truth pose p_model = T · p_view) in a shuffled order."""
    rng = np.random.default_rng(seed)
    surface = ggs.read_point_cloud(MESH, sample_mesh=60_000)
    c = surface.mean(axis=0)
    outward = surface - c
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    out = []
    for _ in range(n):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        seen = surface[outward @ d > np.cos(np.radians(75))]
        m = np.eye(4)
        m[:3, :3] = random_rotation(rng)
        m[:3, 3] = rng.uniform(-1, 1, 3)
        out.append((seen @ m[:3, :3].T + m[:3, 3], np.linalg.inv(m)))
    order = rng.permutation(n)
    return [out[k] for k in order]


def errors(a: ggs.Alignment, truths, scans):
    frame = a.names.index(a.anchor)
    to_frame = np.linalg.inv(truths[frame])
    worst_deg, worst_mm = 0.0, 0.0
    for pose, truth, pts in zip(a.poses, truths, scans):
        if pose is None:
            continue
        e = np.linalg.inv(to_frame @ truth) @ pose
        deg = np.degrees(np.arccos(np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1)))
        c = pts.mean(axis=0)
        mm = 1e3 * np.linalg.norm(e[:3, :3] @ c + e[:3, 3] - c)
        worst_deg, worst_mm = max(worst_deg, deg), max(worst_mm, mm)
    return worst_deg, worst_mm


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sizes", type=int, nargs="+")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print("| scans | registrations | placed | worst ° | worst mm | s |")
    print("|---|---|---|---|---|---|")
    for n in args.sizes:
        set_ = views(n, args.seed)
        scans = [s for s, _ in set_]
        truths = [t for _, t in set_]
        t0 = time.perf_counter()
        a = ggs.align(scans, threads=args.threads)
        secs = time.perf_counter() - t0
        deg, mm = errors(a, truths, scans)
        placed = n - len(a.unplaced)
        print(f"| {n} | {a.registrations} | {placed} | {deg:.2f} | {mm:.1f} | {secs:.1f} |", flush=True)


if __name__ == "__main__":
    main()
