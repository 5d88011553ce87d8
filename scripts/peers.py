#!/usr/bin/env python3
"""ggs side by side with the feature-based pipelines users compare it with, in one run.

    scripts/peers.py [--runs 3] [--threads 2] [--ggs target/release/ggs] [--pairs a,b] [--out table.md]

Methods, each on the same pairs, the runs interleaved (ggs, peer, ggs, peer, ...), medians:
- `ggs`: `ggs register SOURCE TARGET --voxel V` with no other flag (the defaults: full-SO(3)
  grid search, verified hypotheses, GICP), timed as a whole process (reading the files
  included);
- `open3d`: Open3D's global registration recipe (voxel downsampling at V, normals in 2V, FPFH in
  5V, RANSAC on feature matches with edge-length and distance checkers, 100 000 iterations,
  confidence 0.999), then generalized ICP at full resolution (max distance V); timed from
  the loaded clouds (registration only, as Open3D users report it);
- `open3d, GICP at V`: the same RANSAC, then the same GICP on both clouds downsampled at V
  (the fastest form of the recipe; about twice the rotation error of full resolution on the
  bunny pair, 0.16° against 0.075°);
- `open3d+small_gicp`: the same RANSAC, then small_gicp's GICP (downsampling at V/2, 4
  threads' worth of work on --threads);
- `kiss-matcher` and `kiss-matcher + GICP`: KISS-Matcher's features and robust solver, alone
  and followed by small_gicp's GICP (as for Open3D above), timed from the loaded clouds.
A peer that is not installed (`pip install open3d small_gicp kiss-matcher`) is skipped and said so.
Pairs: those of --manifest (default ../shared/data/pairs.tsv) named by --pairs (default
bunny_bun045_bun000, 3dmatch_demo, lidar_koide; `all` with --limit N for a generated
benchmark), at their own voxel. Success as in the manifest: RRE < 10° and RTE < 3 voxels, or
--max-rre / --max-rte (the LiDAR thresholds: 5 and 0.6).
Prints a Markdown table (time, RRE, RTE per method and pair) and, for several pairs, the
solved count per method.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data"


def rre_rte(t, gt):
    r = t[:3, :3].T @ gt[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))
    return float(angle), float(np.linalg.norm(t[:3, 3] - gt[:3, 3]))


def load_pairs(manifest, names, limit):
    """The manifest's pairs named in `names` (all when empty), at most `limit`."""
    pairs = {}
    order = []
    for line in manifest.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        name, src, tgt, t, _, voxel = line.split("\t")[:6]
        if not names or name in names:
            gt = np.array([float(x) for x in t.split()]).reshape(4, 4)
            pairs[name] = (manifest.parent / src, manifest.parent / tgt, gt, float(voxel))
            order.append(name)
    missing = [n for n in names if n not in pairs]
    if missing:
        sys.exit(f"not in {manifest}: {missing}")
    return [(n, *pairs[n]) for n in (names or order)][:limit]


def run_ggs(exe, threads, given_voxel=True):
    """`ggs register` at the pair's voxel, or with no flag at all (the automatic voxel)."""
    def register(src, tgt, voxel):
        voxel_args = ["--voxel", str(voxel)] if given_voxel else []
        t0 = time.perf_counter()
        out = subprocess.run(
            [exe, "register", src, tgt, *voxel_args, "--threads", str(threads), "-q"],
            check=True, capture_output=True, text=True,
        )
        dt = time.perf_counter() - t0
        rows = [[float(v) for v in line.split()] for line in out.stdout.splitlines()[:4]]
        return np.array(rows), dt

    return register


def timed(read, register):
    """A method of the table: `register(source, target, V)` on the clouds `read` loads,
    timed from the loaded clouds (registration only)."""
    def run(src_path, tgt_path, voxel):
        src, tgt = read(src_path), read(tgt_path)
        t0 = time.perf_counter()
        t = register(src, tgt, voxel)
        return t, time.perf_counter() - t0

    return run


def small_gicp_refine(threads, skipped):
    """small_gicp's GICP from `init` (downsampling at V/2, max distance V), as a function of
    (source points, target points, init, V); None, saying what is `skipped`, when small_gicp
    is not installed."""
    try:
        import small_gicp
    except ImportError:
        print(f"small_gicp not installed (pip install small_gicp): {skipped} skipped", file=sys.stderr)
        return None

    def refine(src, tgt, init, voxel):
        r = small_gicp.align(
            tgt, src, init_T_target_source=init, downsampling_resolution=voxel / 2,
            max_correspondence_distance=voxel, num_threads=threads,
        )
        return np.asarray(r.T_target_source)

    return refine


def open3d_methods(threads):
    try:
        import open3d as o3d
    except ImportError:
        print("open3d not installed (pip install open3d): its rows are skipped", file=sys.stderr)
        return {}
    reg = o3d.pipelines.registration
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)

    def read(path):
        pts = read_points(path)
        pc = o3d.geometry.PointCloud()
        pc.points = o3d.utility.Vector3dVector(pts)
        return pc

    def features(pc, voxel):
        down = pc.voxel_down_sample(voxel)
        down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * voxel, max_nn=30))
        fpfh = reg.compute_fpfh_feature(down, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100))
        return down, fpfh

    def ransac(src, tgt, voxel):
        """The RANSAC transform and both clouds downsampled at `voxel` (its inputs)."""
        s, sf = features(src, voxel)
        t, tf = features(tgt, voxel)
        d = 1.5 * voxel
        r = reg.registration_ransac_based_on_feature_matching(
            s, t, sf, tf, True, d, reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9), reg.CorrespondenceCheckerBasedOnDistance(d)],
            reg.RANSACConvergenceCriteria(100000, 0.999),
        )
        return r.transformation, s, t

    def with_open3d_gicp(src_path, tgt_path, voxel, downsampled=False):
        """RANSAC, then GICP on the clouds as read or on RANSAC's clouds downsampled at V."""
        src, tgt = read(src_path), read(tgt_path)
        t0 = time.perf_counter()
        init, src_down, tgt_down = ransac(src, tgt, voxel)
        if downsampled:
            src, tgt = src_down, tgt_down
        for pc in (src, tgt):
            pc.estimate_covariances(o3d.geometry.KDTreeSearchParamKNN(20))
        r = reg.registration_generalized_icp(src, tgt, voxel, init)
        return np.asarray(r.transformation), time.perf_counter() - t0

    methods = {
        "open3d": with_open3d_gicp,
        "open3d, GICP at V": lambda s, t, v: with_open3d_gicp(s, t, v, downsampled=True),
    }
    gicp = small_gicp_refine(threads, "its rows are")
    if gicp is None:
        return methods

    def ransac_then_small_gicp(src, tgt, voxel):
        init, _, _ = ransac(src, tgt, voxel)
        return gicp(np.asarray(src.points), np.asarray(tgt.points), init, voxel)

    methods["open3d+small_gicp"] = timed(read, ransac_then_small_gicp)
    return methods


def kiss_matcher_methods(threads):
    """KISS-Matcher (Lim et al., ICRA 2025) alone, and followed by small_gicp's GICP.

    Faster-PFH features at 5 V, k-core pruning, GNC-TLS; it refuses voxels below a few
    centimetres, so small clouds are scaled up by k = max(1, 0.3 / V) and the answer scaled
    back. Timed from the loaded clouds, with its `match` + `solve` entry points (3 × n arrays;
    `estimate` converts the points one by one and is slower). It is not deterministic: the
    table reports the last run's answer.
    """
    try:
        import kiss_matcher
    except ImportError:
        print("kiss-matcher not installed (pip install kiss-matcher): its rows are skipped", file=sys.stderr)
        return {}

    def estimate(src, tgt, voxel):
        k = max(1.0, 0.3 / voxel)
        m = kiss_matcher.KISSMatcher(kiss_matcher.KISSMatcherConfig(voxel * k))
        s_m, t_m = m.match(np.ascontiguousarray(src.T * k), np.ascontiguousarray(tgt.T * k))
        as_3n = lambda v: np.asarray(v, dtype=np.float64).reshape(-1, 3).T
        sol = m.solve(as_3n(s_m), as_3n(t_m))
        t = np.eye(4)
        t[:3, :3] = np.asarray(sol.rotation)
        t[:3, 3] = np.asarray(sol.translation).ravel() / k
        return t

    methods = {"kiss-matcher": timed(read_points, estimate)}
    gicp = small_gicp_refine(threads, "KISS-Matcher + GICP is")
    if gicp is None:
        return methods
    methods["kiss-matcher + GICP"] = timed(
        read_points, lambda src, tgt, voxel: gicp(src, tgt, estimate(src, tgt, voxel), voxel)
    )
    return methods


def read_points(path):
    """The points of a pair's file, read by the ggs Python package if installed, else numpy."""
    try:
        import ggs

        return ggs.read_point_cloud(path)
    except ImportError:
        if str(path).endswith(".npy"):
            return np.load(path)
        sys.exit("reading PLY/PCD needs the ggs Python package (pip install ./python)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ggs", default=str(ROOT / "target/release/ggs"))
    ap.add_argument("--manifest", default=str(DATA / "pairs.tsv"), help="pairs.tsv-style file")
    ap.add_argument("--pairs", default="bunny_bun045_bun000,3dmatch_demo,lidar_koide",
                    help="comma-separated pair names; 'all' for every pair of the manifest")
    ap.add_argument("--limit", type=int, default=1000)
    ap.add_argument("--max-rre", type=float, default=10.0, help="success: RRE below, degrees")
    ap.add_argument("--max-rte", type=float, help="success: RTE below (default 3 voxels of the pair)")
    ap.add_argument("--out")
    a = ap.parse_args()
    if not Path(a.ggs).exists():
        sys.exit(f"{a.ggs} not built (cargo build --release)")
    try:
        import threadpoolctl  # noqa: F401  (Open3D and numpy honour OMP_NUM_THREADS)
    except ImportError:
        pass
    os.environ.setdefault("OMP_NUM_THREADS", str(a.threads))
    methods = {
        "ggs": run_ggs(a.ggs, a.threads),
        "ggs (no flag)": run_ggs(a.ggs, a.threads, given_voxel=False),
        **open3d_methods(a.threads),
        **kiss_matcher_methods(a.threads),
    }
    rows = []
    solved = {m: 0 for m in methods}
    count = 0
    names = [] if a.pairs == "all" else a.pairs.split(",")
    for name, src, tgt, gt, voxel in load_pairs(Path(a.manifest), names, a.limit):
        times = {m: [] for m in methods}
        last = {}
        for _ in range(a.runs):
            for m, f in methods.items():
                t, dt = f(src, tgt, voxel)
                times[m].append(dt)
                last[m] = t
        count += 1
        for m in methods:
            e_r, e_t = rre_rte(last[m], gt)
            ok = e_r < a.max_rre and e_t < (a.max_rte if a.max_rte is not None else 3 * voxel)
            solved[m] += ok
            rows.append(f"| {name} | {m} | {statistics.median(times[m]):.3f} | {e_r:.3f} | {e_t:.4f} | {'yes' if ok else 'no'} |")
    table = "\n".join(
        [f"runs {a.runs}, threads {a.threads}, medians",
         "", "| pair | method | s | RRE ° | RTE | solved |", "|---|---|---|---|---|---|", *rows,
         "", "solved: " + ", ".join(f"{m} {solved[m]}/{count}" for m in methods)]
    )
    print(table)
    if a.out:
        Path(a.out).write_text(table + "\n")


if __name__ == "__main__":
    main()
