"""Tests of the ggs Python package (run after installing the wheel: pytest python/tests)."""

import json
import os
import pickle
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import ggs

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
SHARED = Path(os.environ.get("GGS_SHARED", ROOT.parent / "shared"))


def ggs_binary():
    exe = Path(os.environ.get("GGS_BIN", ROOT / "target" / "release" / "ggs"))
    if not exe.exists():
        pytest.skip(f"{exe} not built (cargo build --release)")
    return exe


def bunny_small():
    return ggs.read_point_cloud(DATA / "bun0.pcd"), ggs.read_point_cloud(DATA / "bun4.pcd")


def test_read_gives_float64_n_by_3():
    pts = ggs.read_point_cloud(DATA / "bun0.pcd")
    assert pts.dtype == np.float64 and pts.ndim == 2 and pts.shape[1] == 3
    assert pts.shape[0] == 397


@pytest.mark.parametrize("ext", ["ply", "pcd", "npy", "xyz", "las", "laz", "e57"])
def test_write_read_round_trip(tmp_path, ext):
    rng = np.random.default_rng(1)
    pts = rng.uniform(-2, 2, size=(500, 3)).round(3)
    path = tmp_path / f"cloud.{ext}"
    ggs.write_point_cloud(path, pts)
    back = ggs.read_point_cloud(path)
    if ext in ("las", "laz"):  # stored as integers with a power-of-ten scale
        np.testing.assert_allclose(back, pts, atol=1e-9)
    else:
        np.testing.assert_array_equal(back, pts)
    # float32 input is written as its float64 values.
    p32 = pts.astype(np.float32)
    ggs.write_point_cloud(tmp_path / "f32.ply", p32)
    np.testing.assert_array_equal(ggs.read_point_cloud(tmp_path / "f32.ply"), p32.astype(np.float64))


def test_read_npz_e57_and_sampled_meshes(tmp_path):
    pts = ggs.read_point_cloud(DATA / "bun0.pcd")
    np.savez_compressed(tmp_path / "c.npz", labels=np.zeros(5), points=pts)
    np.testing.assert_array_equal(ggs.read_point_cloud(tmp_path / "c.npz"), pts)
    np.testing.assert_array_equal(ggs.read_point_cloud(tmp_path / "c.npz", array="points"), pts)
    with pytest.raises(ValueError, match="labels"):
        ggs.read_point_cloud(tmp_path / "c.npz", array="labels")
    ggs.write_point_cloud(tmp_path / "c.e57", pts)
    np.testing.assert_array_equal(ggs.read_point_cloud(tmp_path / "c.e57", scan=0), pts)
    with pytest.raises(ValueError, match="scan 4"):
        ggs.read_point_cloud(tmp_path / "c.e57", scan=4)
    woman = DATA / "human_woman.obj"
    assert ggs.read_point_cloud(woman).shape == (6890, 3)
    sampled = ggs.read_point_cloud(woman, sample_mesh=2000)
    assert sampled.shape == (2000, 3)
    np.testing.assert_array_equal(sampled, ggs.read_point_cloud(woman, sample_mesh=2000))


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros((10, 2)), "shape (10, 2)"),
        (np.zeros(30), "shape (30,)"),
        (np.zeros((0, 3)), "no point"),
        ([["a", "b", "c"]] * 10, "cannot read it as an (N, 3) array"),
        ([[0.0, 1.0], [2.0]], "cannot read it as an (N, 3) array"),
    ],
)
def test_bad_arrays_are_value_errors(bad, message):
    good = np.random.default_rng(0).uniform(size=(50, 3))
    with pytest.raises(ValueError, match="source") as e:
        ggs.register(bad, good, voxel=0.1)
    assert message in str(e.value)
    with pytest.raises(ValueError, match="target"):
        ggs.register(good, bad, voxel=0.1)


def test_nan_rows_and_bad_options():
    a = np.random.default_rng(0).uniform(size=(50, 3))
    b = a.copy()
    b[7, 1] = np.nan
    with pytest.raises(ValueError, match="row 7"):
        ggs.register(a, b, voxel=0.1)
    with pytest.raises(ValueError, match="unknown rotation set"):
        ggs.register(a, a, voxel=0.1, rotations="nope")
    with pytest.raises(ValueError, match="setting refine: unknown refinement 'icp9'"):
        ggs.register(a, a, voxel=0.1, refine="icp9")
    with pytest.raises(ValueError, match="setting voxel: must be a number > 0"):
        ggs.register(a, a, voxel=-1.0)
    with pytest.raises(ValueError, match="setting search: unknown variant `greedy`"):
        ggs.register(a, a, voxel=0.1, search="greedy")
    with pytest.raises(ValueError, match="precision"):
        ggs.register(a, a, voxel=0.1, precision="f16")
    with pytest.raises(FileNotFoundError) as e:
        ggs.read_point_cloud("/nonexistent/cloud.ply")
    assert e.value.filename == "/nonexistent/cloud.ply" and e.value.errno == 2
    with pytest.raises(ValueError, match="threads"):
        ggs.register(a, a, voxel=0.1, threads=-1)
    # The verification's settings are checked by the core, as for the CLI's flags.
    with pytest.raises(ValueError, match=r"margin: must be in \[0, 1\], got 3"):
        ggs.register(a, a, voxel=0.1, margin=3.0)
    with pytest.raises(ValueError, match="max_hypotheses: must be at least 1"):
        ggs.register(a, a, voxel=0.1, max_hypotheses=0)
    with pytest.raises(ValueError, match="kernel"):
        ggs.register(a, a, voxel=0.1, kernel="huber:-1")
    with pytest.raises(ValueError, match="memory"):
        ggs.register(a, a, voxel=0.001, max_memory="1K")


def test_register_bundled_pair_and_result_fields():
    source, target = bunny_small()
    truth = np.loadtxt(DATA / "bun0_to_bun4_groundtruth.txt")
    r = ggs.register(source, target, voxel=0.006, top_k=3)
    assert r.transformation.shape == (4, 4) and r.transformation.dtype == np.float64
    assert ggs.metrics.rre(r.transformation, truth) < 1.0
    assert ggs.metrics.rte(r.transformation, truth) < 0.002
    assert isinstance(r.score, int) and r.rotation_index >= 0 and 0 <= r.ambiguity <= 1
    assert 0 < r.fitness <= 1 and r.inlier_rmse > 0 and r.converged
    assert len(r.hypotheses) == 3 and r.hypotheses[0]["rotation_index"] == r.rotation_index
    assert {"coarse_ms", "refine_ms", "total_ms"} <= set(r.timings)
    assert r.report["method"] == "gicp"
    assert "ggs.Result(" in repr(r) and "confidence=" in repr(r)
    # The verification: several distinct hypotheses, one chosen, a confidence in [0, 1].
    assert 0.0 <= r.confidence <= 1.0 and r.ambiguous in (False, True)
    assert isinstance(r.warnings, list)
    chosen = [h for h in r.verified if h["chosen"]]
    assert len(chosen) == 1 and chosen[0]["rank"] == r.chosen_rank
    assert all(0.0 <= h["score"] <= 1.0 for h in r.verified)
    # Object scans are not scans from their origin: no free space is checked.
    assert all(h["free_space_violations"] is None for h in r.verified)
    # The chosen one is scored over every sample point; one rejected on a subsample over fewer.
    assert not chosen[0]["rejected_on_subsample"] and len(chosen[0]["evidence_points"]) == 2
    for h in r.verified:
        assert not h["rejected_on_subsample"] or (
            h["rejected_early"] and h["evidence_points"][0] < chosen[0]["evidence_points"][0]
        )
    assert {"verify_ms", "search_ms"} <= set(r.timings)
    # float32 input of the same values gives the same answer.
    r32 = ggs.register(source.astype(np.float32).astype(np.float64), target, voxel=0.006)
    r32b = ggs.register(source.astype(np.float32), target, voxel=0.006)
    np.testing.assert_array_equal(r32.transformation, r32b.transformation)
    # refine() from the verified pose reproduces register()'s final refinement at full
    # resolution with the reference's stopping rules exactly; the default's (thinned clouds,
    # a step tolerance) lies close to it.
    reference = {"refine_cell": 0, "refine_min_step": 0, "max_iterations": 500}
    full = ggs.register(source, target, voxel=0.006, settings=reference)
    again = ggs.refine(source, target, chosen[0]["transformation"])
    np.testing.assert_array_equal(again.transformation, full.transformation)
    assert again.score is None and again.fitness == full.fitness and again.confidence is None
    assert ggs.metrics.rre(r.transformation, full.transformation) < 0.05
    assert ggs.metrics.rte(r.transformation, full.transformation) < 5e-5
    with pytest.raises(ValueError, match="refine_cell"):
        ggs.register(source, target, voxel=0.006, refine_cell=-1.0)


def test_presets():
    source, target = bunny_small()
    truth = np.loadtxt(DATA / "bun0_to_bun4_groundtruth.txt")
    assert ggs.PRESETS == ["default", "paper"]
    paper = ggs.register(source, target, voxel=0.006, preset="paper")
    assert paper.verified == [] and len(paper.hypotheses) == 1
    assert ggs.metrics.rre(paper.transformation, truth) < 1.0
    # The paper's set is limited15: rotation indices refer to it.
    assert paper.rotation_index < 1886
    unverified = ggs.register(source, target, voxel=0.006, verify=False, refine="none")
    np.testing.assert_array_equal(unverified.transformation, unverified.coarse_transformation)
    with pytest.raises(ValueError, match="preset"):
        ggs.register(source, target, voxel=0.006, preset="fast")
    with pytest.raises(ValueError, match="needs verification"):
        ggs.register(source, target, voxel=0.006, preset="paper", max_hypotheses=3)


def test_search_modes_and_precisions_agree():
    source, target = bunny_small()
    base = ggs.register(source, target, voxel=0.006, refine="none", verify=False, search="exhaustive")
    for search, precision in [("coarse-to-fine", "mixed"), ("exhaustive", "f64")]:
        r = ggs.register(
            source, target, voxel=0.006, refine="none", verify=False, search=search, precision=precision
        )
        np.testing.assert_array_equal(r.transformation, base.transformation)
        assert r.score == base.score


def test_same_answer_on_any_thread_count():
    # The 40k-point bundled scans (sums over many 1024-point chunks), in both precisions.
    source = ggs.read_point_cloud(DATA / "bun045.ply")
    target = ggs.read_point_cloud(DATA / "bun000.ply")
    for precision in ["mixed", "f64"]:
        runs = [ggs.register(source, target, voxel=0.005, threads=t, precision=precision) for t in (1, 2, 8)]
        for r in runs[1:]:
            np.testing.assert_array_equal(runs[0].transformation, r.transformation)
            for field in ["hypotheses", "verified", "report"]:
                a, b = (json.dumps(getattr(x, field), default=np.ndarray.tolist) for x in (runs[0], r))
                assert a == b, field


def test_error_types_name_the_file(tmp_path):
    bad = tmp_path / "bad.ply"
    bad.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                   "property float z\nend_header\n0 0 0\n1 x 0\n")
    with pytest.raises(ValueError, match=r"bad.ply: line 9: 'x' is not a number"):
        ggs.read_point_cloud(bad)
    header = tmp_path / "h.pcd"
    header.write_text("VERSION .7\nFIELDS x y z\nSIZE 4 4\n")
    with pytest.raises(ValueError, match=r"h.pcd: line 4"):
        ggs.read_point_cloud(header)
    with pytest.raises(IsADirectoryError) as e:
        ggs.read_point_cloud(tmp_path)
    assert e.value.filename == str(tmp_path)
    points = np.zeros((3, 3))
    missing = tmp_path / "no" / "such" / "dir.ply"
    with pytest.raises(FileNotFoundError) as f:
        ggs.write_point_cloud(missing, points)
    assert f.value.filename == str(missing) and not missing.parent.exists()
    with pytest.raises(ValueError, match="x.weird: unknown point-cloud format"):
        ggs.write_point_cloud(tmp_path / "x.weird", points)
    # A failed write leaves the file that was there.
    kept = tmp_path / "kept.ply"
    ggs.write_point_cloud(kept, points)
    before = kept.read_bytes()
    with pytest.raises(ValueError):
        ggs.write_point_cloud(kept, np.zeros((3, 2)))
    assert kept.read_bytes() == before


def test_rotation_sets_and_metrics():
    for name in ggs.ROTATION_SETS:
        rs = ggs.rotation_set(name)
        assert rs.ndim == 3 and rs.shape[1:] == (3, 3)
    rs = ggs.rotation_set("limited15")
    assert rs.shape == (1886, 3, 3)
    np.testing.assert_allclose(rs @ rs.transpose(0, 2, 1), np.broadcast_to(np.eye(3), rs.shape), atol=1e-12)
    with pytest.raises(ValueError):
        ggs.rotation_set("nope")
    t = np.eye(4)
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    t2 = np.array([[c, -s, 0, 0.3], [s, c, 0, 0], [0, 0, 1, 0.4], [0, 0, 0, 1]])
    assert ggs.metrics.rre(t2, t) == pytest.approx(30.0)
    assert ggs.metrics.rte(t2, t) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="not a rotation"):
        ggs.metrics.rre(np.diag([2.0, 1, 1, 1]), t)


def test_gil_is_released_during_registration():
    source, target = bunny_small()
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    th = threading.Thread(target=count)
    th.start()
    t0 = time.perf_counter()
    ggs.register(source, target, voxel=0.003, rotations="full15", search="exhaustive", threads=1)
    t1 = time.perf_counter()
    done.set()
    th.join()
    during = [t for t in ticks if t0 < t < t1]
    # With the GIL held the other thread could not tick at all during the call (an exhaustive
    # full15 search at 3 mm: thousands of rotations, far longer than a few ticks).
    assert len(during) >= 10, len(during)


def test_ctrl_c_interrupts_a_long_search():
    import _thread
    import signal

    source, target = bunny_small()
    # A process started in the background by a shell without job control inherits SIGINT
    # ignored, and then interrupt_main does nothing: Python's own handler is put back here.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.3, _thread.interrupt_main)
    finished = 0
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            # One exhaustive full15 search at 2 mm on one thread scores 6364 rotations on
            # grids of ~80³: far longer than 0.3 s on any machine.
            for _ in range(50):
                ggs.register(source, target, voxel=0.002, rotations="full15", search="exhaustive", threads=1)
                finished += 1
    finally:
        signal.signal(signal.SIGINT, previous)
    # The interrupt stopped the first search from inside; it did not wait for it to end.
    assert finished == 0


def test_equals_the_cli_bit_for_bit():
    pair = SHARED / "data" / "stanford_bunny"
    if not (pair / "bun045.ply").exists():
        pytest.skip(f"{pair} not found (../shared beside the checkout)")
    exe = ggs_binary()
    src, tgt = pair / "bun045.ply", pair / "bun000.ply"
    out = subprocess.run(
        [str(exe), "register", str(src), str(tgt), "--voxel", "0.005", "--threads", "2", "--json", "-q"],
        check=True,
        capture_output=True,
        text=True,
    )
    cli = json.loads(out.stdout)
    r = ggs.register(ggs.read_point_cloud(src), ggs.read_point_cloud(tgt), voxel=0.005, threads=2)
    assert r.transformation.tolist() == cli["transform"]
    assert r.coarse_transformation.tolist() == cli["coarse_transform"]
    assert r.score == cli["search"]["score"]
    assert r.fitness == cli["refine"]["report"]["fitness_source"]
    # One serialization: Python's document is the CLI's, less what only a process knows.
    doc = r.document
    assert list(doc) == list(cli) and doc["format"] == "ggs-registration/2"
    skip = {"source", "target", "timings", "search", "refine", "read_ms", "total_ms", "peak_memory_bytes"}
    for key in set(cli) - skip:
        assert doc[key] == cli[key], key
    assert doc["search"]["hypotheses"] == cli["search"]["hypotheses"]


def test_open3d_example():
    pytest.importorskip("open3d")
    import importlib.util

    spec = importlib.util.spec_from_file_location("example", ROOT / "python" / "examples" / "open3d_example.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    os.environ["GGS_NO_WINDOW"] = "1"
    r = mod.main(["example"])
    truth = np.loadtxt(DATA / "bun0_to_bun4_groundtruth.txt")
    assert ggs.metrics.rre(r.transformation, truth) < 1.0


class PointCloudLike:
    """What Open3D's PointCloud looks like to ggs: an object with ``.points``."""

    def __init__(self, points):
        self.points = [tuple(p) for p in points]


def test_array_likes_and_point_cloud_objects_are_accepted():
    source, target = bunny_small()
    base = ggs.register(source, target, voxel=0.006)
    for s in (source.tolist(), PointCloudLike(source), tuple(map(tuple, source))):
        r = ggs.register(s, PointCloudLike(target), voxel=0.006)
        np.testing.assert_array_equal(r.transformation, base.transformation)
    ints = np.round(source * 1000).astype(np.int64)
    r = ggs.register(ints, np.round(target * 1000), voxel=6.0)
    assert r.transformation.shape == (4, 4)


def test_results_pickle_and_convert_to_dicts():
    import pickle

    source, target = bunny_small()
    r = ggs.register(source, target, voxel=0.006)
    back = pickle.loads(pickle.dumps(r))
    np.testing.assert_array_equal(back.transformation, r.transformation)
    assert back.confidence == r.confidence and back.verified[0]["score"] == r.verified[0]["score"]
    d = r.to_dict()
    assert set(d) >= {"transformation", "confidence", "ambiguous", "verified", "timings", "report"}
    d["transformation"][0, 0] = 99.0
    assert r.transformation[0, 0] != 99.0  # a copy
    keys = set(r.timings)
    assert keys == set(ggs.register(source, target, voxel=0.006, refine="none").timings)
    assert keys == set(ggs.refine(source, target, np.eye(4)).timings)
    assert ggs.register(source, target, voxel=0.006, refine="none").timings["refine_ms"] == 0.0


def test_symmetric_data_is_flagged_with_a_ggs_warning():
    # Points on the faces of a 3 × 2 × 1 box, sampled twice: turning it by 180° about an axis
    # gives the same surface, so at least two distinct poses fit equally well. (The same
    # sample twice would not do: the identity puts every point exactly on itself, which the
    # tight score prefers to a turn that puts it near another.)
    def box(seed):
        rng = np.random.default_rng(seed)
        u = rng.uniform(-1, 1, size=(6000, 3)) * [1.5, 1.0, 0.5]
        axis = rng.integers(0, 3, size=6000)
        sign = rng.choice([-1.0, 1.0], size=6000)
        u[np.arange(6000), axis] = sign * np.array([1.5, 1.0, 0.5])[axis]
        return u

    with pytest.warns(ggs.GgsWarning, match="ambiguous"):
        r = ggs.register(box(3), box(4), voxel=0.15)
    assert r.ambiguous and r.confidence < 0.1 and r.warnings


def test_helpers():
    pts = np.array([[0.0, 0, 0], [0.01, 0, 0], [1.0, 1, 1], [1.02, 1, 1]])
    np.testing.assert_allclose(ggs.voxel_downsample(pts, 0.5), [[0.005, 0, 0], [1.01, 1, 1]])
    with pytest.raises(ValueError, match="voxel"):
        ggs.voxel_downsample(pts, 0.0)
    g = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0), [0.0]), -1).reshape(-1, 3)
    n = ggs.estimate_normals(g, neighbors=8)
    np.testing.assert_allclose(np.abs(n[:, 2]), 1.0, atol=1e-9)
    t = np.eye(4)
    t[:3, 3] = [0.0, 0.0, 0.3]
    moved = ggs.transform_points(g, t)
    np.testing.assert_allclose(moved[:, 2], 0.3)
    e = ggs.evaluate(g, moved, t, max_distance=0.01)
    assert (e.fitness, e.fitness_target, e.inliers) == (1.0, 1.0, len(g)) and e.inlier_rmse < 1e-12
    e = ggs.evaluate(g, moved, np.eye(4), max_distance=0.5)
    assert e.fitness == 1.0 and abs(e.inlier_rmse - 0.3) < 1e-12


def test_progress_callback_and_every_option_reachable():
    source, target = bunny_small()
    calls = []
    r = ggs.register(source, target, voxel=0.006, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1][0] == calls[-1][1] == 6360
    assert all(a[0] <= b[0] for a, b in zip(calls, calls[1:]))
    by_array = ggs.register(
        source, target, voxel=0.006, rotations=ggs.rotation_set("limited15"), verify=False
    )
    by_name = ggs.register(source, target, voxel=0.006, rotations="limited15", verify=False)
    np.testing.assert_array_equal(by_array.transformation, by_name.transformation)
    r = ggs.register(
        source, target, voxel=0.006, kernel="huber:0.01", distinct_radius=45.0,
        max_memory="2G", margin=0.0, max_hypotheses=3, top_k=2, dedup=1.0, coarse_factor=3.0,
        coarse_keep=0.05, coarse_keep_min=8, max_distance=0.01, max_iterations=40, neighbors=15,
    )
    # max_hypotheses counts the voxel size's; the coarse level's follow them.
    levels = [h["level"] for h in r.verified]
    assert levels.count("voxel") == 3 and len(r.hypotheses) == 2
    assert levels[:3] == ["voxel"] * 3 and set(levels[3:]) <= {"coarse"}
    assert r.report["correspondence_distance"] == 0.01 and r.report["iterations"] <= 40


def test_first_look_settles_a_clear_pair_and_can_be_turned_off():
    source = ggs.read_point_cloud(DATA / "bun045.ply")
    target = ggs.read_point_cloud(DATA / "bun000.ply")
    first = ggs.register(source, target, voxel=0.005)
    look = first.first_look
    assert look["accepted"] and look["rotations"] == 16 and look["score"] >= 0.5
    assert look["verified"] == len(first.verified)
    # The coarse level's alternatives, and only they, were screened on coarser cells.
    assert any(h["screened"] for h in first.verified)
    assert all(h["screened"] == (h["level"] == "coarse") for h in first.verified)
    whole = ggs.register(source, target, voxel=0.005, first_look=False)
    assert whole.first_look is None and len(whole.verified) > len(first.verified)
    assert not any(h["screened"] for h in whole.verified)
    assert ggs.metrics.rre(first.transformation, whole.transformation) < 0.01
    paper = ggs.register(source, target, voxel=0.005, preset="paper")
    assert paper.first_look is None



def test_verify_score_tight_weighs_closeness_fitness_counts():
    source, target = bunny_small()
    tight = ggs.register(source, target, voxel=0.006, max_hypotheses=3, margin=0.0)
    fitness = ggs.register(
        source, target, voxel=0.006, max_hypotheses=3, margin=0.0, verify_score="fitness"
    )
    # A point within D counts 1 − d²/D² ≤ 1: the tight scores are lower, pose by pose.
    assert [t["rank"] for t in tight.verified] == [f["rank"] for f in fitness.verified]
    for t, f in zip(tight.verified, fitness.verified):
        assert t["score"] <= f["score"]
    assert tight.verified[0]["score"] < fitness.verified[0]["score"]
    # Oriented counts a subset of the tight score's points, with the same weights.
    oriented = ggs.register(
        source, target, voxel=0.006, max_hypotheses=3, margin=0.0, verify_score="oriented"
    )
    assert [o["rank"] for o in oriented.verified] == [t["rank"] for t in tight.verified]
    for o, t in zip(oriented.verified, tight.verified):
        assert o["score"] <= t["score"]
    with pytest.raises(ValueError, match="unknown variant `close`"):
        ggs.register(source, target, voxel=0.006, verify_score="close")
    with pytest.raises(ValueError, match="needs verification"):
        ggs.register(source, target, voxel=0.006, verify=False, verify_score="fitness")


def test_register_many(tmp_path):
    src, tgt = DATA / "bun0.pcd", DATA / "bun4.pcd"
    a, b = bunny_small()
    seen = []
    out = ggs.register_many(
        [(src, tgt), (a, b), (tmp_path / "missing.ply", tgt)],
        voxel=0.006,
        on_error="return",
        progress=lambda k, r: seen.append(k),
    )
    assert seen == [0, 1, 2]
    np.testing.assert_array_equal(out[0].transformation, out[1].transformation)
    assert isinstance(out[2], FileNotFoundError)
    with pytest.raises(FileNotFoundError):
        ggs.register_many([(tmp_path / "missing.ply", tgt)], voxel=0.006)


def test_bench_voxel_auto_registers_as_with_no_voxel(tmp_path):
    t = "0.825336 0 -0.564642 0.037267 0 1 0 0 0.564642 0 0.825336 0.038325 0 0 0 1"
    manifest = tmp_path / "pairs.tsv"
    manifest.write_text(f"fwd\t{DATA / 'bun0.pcd'}\t{DATA / 'bun4.pcd'}\t{t}\texact\t0.006\n")
    run = ggs.bench.run(manifest, out=tmp_path / "run", voxel="auto", threads=2, progress=False)
    plain = ggs.register(*bunny_small())
    row = run.pairs[0]
    assert float(row["voxel"]) == plain.voxel != 0.006
    assert float(row["max_rte"]) == pytest.approx(3 * 0.006)
    with pytest.raises(ValueError, match="neither 'auto' nor a positive number"):
        ggs.bench.run(manifest, out=tmp_path / "bad", voxel="big", progress=False)


def test_docstrings_and_signatures_are_visible_at_runtime():
    import inspect

    params = inspect.signature(ggs.register).parameters
    assert {"preset", "rotations", "max_hypotheses", "progress", "kernel"} <= set(params)
    assert "preset" in ggs.register.__doc__ and "FileNotFoundError" in ggs.read_point_cloud.__doc__
    assert ggs.Result.confidence.__doc__


def _python_blocks(markdown):
    import re

    return re.findall(r"```python\n(.*?)```", markdown.read_text(), flags=re.S)


@pytest.mark.parametrize(
    "doc", ["README.md", "python/README.md", "docs/settings.md", "docs/align.md"]
)
def test_readme_examples_run_as_written(doc, monkeypatch):
    blocks = _python_blocks(ROOT / doc)
    assert blocks, doc
    monkeypatch.chdir(ROOT)
    for code in blocks:
        exec(compile(code, doc, "exec"), {})


def test_a_scan_moved_by_random_rotations_is_solved_with_no_option():
    # A user's own arrays: bun000 moved by uniform random rotations (up to 180°) and shifts,
    # registered back onto itself with nothing but the defaults (auto voxel included).
    target = ggs.read_point_cloud(DATA / "bun000.ply")
    rng = np.random.default_rng(7)
    for _ in range(3):
        w, x, y, z = rng.normal(size=4) / 1.0
        n = np.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / n, x / n, y / n, z / n
        t = np.eye(4)
        t[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
        t[:3, 3] = rng.uniform(-0.1, 0.1, 3)
        source = ggs.transform_points(target, np.linalg.inv(t))
        r = ggs.register(source, target)
        assert ggs.metrics.rre(r.transformation, t) < 0.1 and ggs.metrics.rte(r.transformation, t) < 1e-3
        assert not r.ambiguous


def test_report_html_is_the_cli_page_and_needs_a_register_result(tmp_path):
    source, target = bunny_small()
    r = ggs.register(source, target, voxel=0.006)
    out = tmp_path / "report.html"
    r.report_html(out, source_name="bun045", target_name="bun000", command="python demo.py")
    html = out.read_text()
    assert html.startswith("<!DOCTYPE html>") and html.rstrip().endswith("</html>")
    for section in ("Before and after", "3-D view", "Hypotheses", "Quality", "Time per stage"):
        assert section in html
    assert "bun045" in html and "python demo.py" in html
    assert html.count("data:image/png;base64,") == 6  # 2 × 3 views, inline
    assert "http://" not in html.replace("http://www.w3.org/2000/svg", "")
    back = pickle.loads(pickle.dumps(r))
    with pytest.raises(ValueError, match="no report"):
        back.report_html(tmp_path / "x.html")
    refined = ggs.refine(source, target, r.transformation)
    with pytest.raises(ValueError, match="no report"):
        refined.report_html(tmp_path / "y.html")
    assert not (tmp_path / "x.html").exists() and not (tmp_path / "y.html").exists()


def test_render_returns_an_image_that_shows_the_alignment():
    source, target = bunny_small()
    r = ggs.register(source, target, voxel=0.006)
    img = ggs.render(target, source, r.transformation, view="front", size=(320, 200))
    assert img.shape == (200, 320, 3) and img.dtype == np.uint8
    painted = (img.min(axis=2) < 225).mean()
    assert 0.05 < painted < 0.9
    rgb = img.astype(int)
    orange = (rgb[:, :, 0] > rgb[:, :, 2] + 60).sum()
    assert orange > 100, "the source is drawn"
    alone = ggs.render(target, view="plan", size=(64, 64))
    alone = alone.astype(int)
    assert (alone[:, :, 0] > alone[:, :, 2] + 60).sum() == 0, "no source, no orange"
    with pytest.raises(ValueError, match="view must be"):
        ggs.render(target, view="top")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="size must be"):
        ggs.render(target, size=(0, 10))


def test_settings_are_one_dict_that_a_result_echoes_and_a_call_takes_back(tmp_path):
    source, target = bunny_small()
    defaults = ggs.settings()
    assert defaults["margin"] == 0.5 and defaults["rotations"] == "hopf15-id"
    assert ggs.settings("paper")["search"] == "exhaustive"
    changed = ggs.settings(settings={"margin": 0.4}, max_hypotheses=8)
    assert (changed["margin"], changed["max_hypotheses"]) == (0.4, 8)
    r = ggs.register(source, target, voxel=0.006, margin=0.4)
    assert r.settings is not None
    assert r.settings == ggs.settings(voxel=0.006, margin=0.4)
    again = ggs.register(source, target, settings=r.settings)
    assert np.array_equal(again.transformation, r.transformation)
    toml = tmp_path / "scans.toml"
    toml.write_text('preset = "paper"\nvoxel = 0.006\n')
    assert ggs.settings(settings=toml)["search"] == "exhaustive"
    assert ggs.settings(settings=str(toml), preset="default")["search"] == "coarse-to-fine"
    with pytest.raises(ValueError, match=r"setting margn: unknown setting \(did you mean margin\?\)"):
        ggs.settings(settings={"margn": 0.3})
    with pytest.raises(ValueError, match="scans.toml: setting voxel"):
        toml.write_text("voxel = -2.0\n")
        ggs.settings(settings=toml)
    assert ggs.refine(source, target, r.transformation).settings is None
