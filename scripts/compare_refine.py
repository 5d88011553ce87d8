#!/usr/bin/env python3
"""Time Open3D's and small_gicp's GICP on the same pair, start pose and correspondence
distance as `ggs refine`, for docs/refinement.md.

Needs `pip install open3d small_gicp numpy` (not a dependency of ggs). Usage:

    target/release/ggs register SRC TGT --voxel 0.005 --refine none -q | head -4 > /tmp/T.txt
    target/release/ggs refine SRC TGT --init /tmp/T.txt --threads 2 --json > /tmp/ggs.json
    OMP_NUM_THREADS=2 python3 scripts/compare_refine.py SRC TGT /tmp/T.txt /tmp/ggs.json

Both libraries get all points (no downsampling), covariances from 20 nearest neighbours,
the correspondence distance ggs chose, up to 500 iterations and 2 threads. Prints the median
of 7 runs with and without the covariance estimation.
"""
import json
import sys
import time

import numpy as np
import open3d as o3d
import small_gicp

src_path, tgt_path, init_path, ggs_json = sys.argv[1:5]
init = np.loadtxt(init_path)
ggs = json.load(open(ggs_json))["refine"]
d_c = ggs["report"]["correspondence_distance"]
src = o3d.io.read_point_cloud(src_path)
tgt = o3d.io.read_point_cloud(tgt_path)
reg = o3d.pipelines.registration


def median_ms(times):
    return 1e3 * float(np.median(times))


def open3d_run():
    s, t = o3d.geometry.PointCloud(src), o3d.geometry.PointCloud(tgt)
    t0 = time.perf_counter()
    s.estimate_covariances(o3d.geometry.KDTreeSearchParamKNN(20))
    t.estimate_covariances(o3d.geometry.KDTreeSearchParamKNN(20))
    t1 = time.perf_counter()
    r = reg.registration_generalized_icp(
        s, t, d_c, init, reg.TransformationEstimationForGeneralizedICP(),
        reg.ICPConvergenceCriteria(1e-6, 1e-6, 500))
    t2 = time.perf_counter()
    return t2 - t0, t2 - t1, r


def small_gicp_run():
    S, T = np.asarray(src.points), np.asarray(tgt.points)
    t0 = time.perf_counter()
    ts, ss = small_gicp.PointCloud(T), small_gicp.PointCloud(S)
    tt = small_gicp.KdTree(ts, num_threads=2)
    st = small_gicp.KdTree(ss, num_threads=2)
    small_gicp.estimate_covariances(ts, tt, num_neighbors=20, num_threads=2)
    small_gicp.estimate_covariances(ss, st, num_neighbors=20, num_threads=2)
    t1 = time.perf_counter()
    r = small_gicp.align(ts, ss, tt, init_T_target_source=init, registration_type="GICP",
                         max_correspondence_distance=d_c, num_threads=2, max_iterations=500,
                         rotation_epsilon=1e-8, translation_epsilon=1e-8)
    t2 = time.perf_counter()
    return t2 - t0, t2 - t1, r


for name, run in [("open3d", open3d_run), ("small_gicp", small_gicp_run)]:
    runs = [run() for _ in range(7)]
    print(f"{name}: total {median_ms([r[0] for r in runs]):.1f} ms, "
          f"without covariances {median_ms([r[1] for r in runs]):.1f} ms")
print(f"ggs: total {ggs['total_ms']:.1f} ms (one run; setup {ggs['setup_ms']:.1f}, "
      f"iterations {ggs['iterate_ms']:.1f})")
