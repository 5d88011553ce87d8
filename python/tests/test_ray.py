"""ggs on a real local Ray cluster (not mocked): a benchmark through Ray writes the files of
``ggs bench``, a worker killed mid-run loses no pair, an interrupted run resumes, and
``register_many`` over Ray equals local registration.

Needs Ray (``pip install ray``; skipped without it unless GGS_REQUIRE_RAY=1) and, for the
benchmark tests, ../shared beside the checkout (skipped without it unless
GGS_REQUIRE_SHARED=1). ``.ci/run`` installs Ray and sets both.
"""

import os
import signal
import subprocess
import time
from pathlib import Path
from typing import Dict, List

import numpy as np
import pytest

import ggs
import ggs.bench

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
SHARED = Path(os.environ.get("GGS_SHARED", ROOT.parent / "shared"))
REAL_PAIRS = SHARED / "data" / "pairs.tsv"


def _require(env: str, why: str) -> None:
    if os.environ.get(env) == "1":
        pytest.fail(f"{why}, and {env}=1 requires it")
    pytest.skip(f"SKIPPED: {why}; {env}=1 makes this an error", allow_module_level=True)


try:
    import ray
except ImportError:
    _require("GGS_REQUIRE_RAY", "Ray is not installed (pip install ray)")


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of two one-CPU workers."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def shared_pairs() -> Path:
    if not REAL_PAIRS.is_file():
        _require("GGS_REQUIRE_SHARED", f"{REAL_PAIRS} not found (../shared beside the checkout)")
    return REAL_PAIRS


def without_ms(path: Path) -> List[str]:
    """pairs.csv without its ``*_ms`` timing columns."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [k for k, name in enumerate(header) if not name.endswith("_ms")]
    # No field of these pairs holds a comma (ids are plain names).
    return [",".join(line.split(",")[k] for k in keep) for line in lines]


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The shared real pairs run by ``ggs bench`` (the CLI), or by the local executor where
    the CLI is not built."""
    pairs = shared_pairs()
    out = tmp_path_factory.mktemp("reference")
    exe = Path(os.environ.get("GGS_BIN", ROOT / "target" / "release" / "ggs"))
    if exe.is_file():
        cmd = [str(exe), "bench", "manifest", str(pairs), "--out", str(out), "-q", "--threads", "2"]
        subprocess.run(cmd, check=True, capture_output=True)
    else:
        ggs.bench.run(pairs, out=out, threads=2, progress=False)
    return out


def test_a_ray_run_writes_the_files_of_ggs_bench(cluster, reference, tmp_path):
    seen: List[int] = []
    run = ggs.bench.run(
        shared_pairs(),
        out=tmp_path,
        executor="ray",
        progress=lambda done, total, row: seen.append(done),
    )
    assert seen == list(range(1, len(run.pairs) + 1))
    assert without_ms(tmp_path / "pairs.csv") == without_ms(reference / "pairs.csv")
    assert (tmp_path / "run.json").read_text() == (reference / "run.json").read_text()
    assert run.recall == pytest.approx(100.0 * 12 / 13)
    for name in ["results.json", "summary.md", "recall.svg", "report.html"]:
        assert (tmp_path / name).is_file(), name


def running_pair_workers() -> List[int]:
    """Pids of Ray workers running a benchmark pair now (Ray titles them by the task)."""
    pids = []
    for entry in Path("/proc").iterdir():
        try:
            title = (entry / "cmdline").read_bytes().split(b"\0")[0]
        except OSError:
            continue
        if title.startswith(b"ray::_run_pair"):
            pids.append(int(entry.name))
    return pids


def test_a_worker_killed_mid_run_loses_no_pair(cluster, reference, tmp_path):
    killed: Dict[str, int] = {}

    def kill_once(done: int, total: int, row: dict) -> None:
        deadline = time.monotonic() + 10
        while not killed and time.monotonic() < deadline:
            pids = running_pair_workers()
            if pids:
                os.kill(pids[0], signal.SIGKILL)
                killed["pid"] = pids[0]
            else:
                time.sleep(0.01)

    run = ggs.bench.run(shared_pairs(), out=tmp_path, executor="ray", progress=kill_once)
    assert killed, "no worker was running a pair to kill"
    assert not any(p["error"] for p in run.pairs), [p["error"] for p in run.pairs]
    assert without_ms(tmp_path / "pairs.csv") == without_ms(reference / "pairs.csv")
    # With no retry the killed pair is recorded as lost, never dropped, and run again when
    # the run is resumed.
    killed.clear()
    lost = tmp_path / "lost"
    run = ggs.bench.run(shared_pairs(), out=lost, executor="ray", limit=4, retries=0, progress=kill_once)
    errors = [p["error"] for p in run.pairs if p["error"]]
    assert len(errors) == 1 and errors[0].startswith("executor: WorkerCrashedError"), errors
    run = ggs.bench.run(shared_pairs(), out=lost, executor="ray", limit=4, progress=False)
    assert run.resumed == 3 and not any(p["error"] for p in run.pairs)
    assert without_ms(lost / "pairs.csv") == without_ms(reference / "pairs.csv")[:5]


class Stop(Exception):
    pass


def test_an_interrupted_ray_run_resumes_to_the_same_files(cluster, reference, tmp_path):
    def stop_after_three(done: int, total: int, row: dict) -> None:
        if done == 3:
            raise Stop()

    with pytest.raises(Stop):
        ggs.bench.run(shared_pairs(), out=tmp_path, executor="ray", limit=6, progress=stop_after_three)
    assert len(without_ms(tmp_path / "pairs.csv")) == 1 + 3
    run = ggs.bench.run(shared_pairs(), out=tmp_path, executor="ray", limit=6, progress=False)
    assert run.resumed == 3
    assert without_ms(tmp_path / "pairs.csv") == without_ms(reference / "pairs.csv")[:7]
    # Another configuration in the same directory is refused, not mixed in.
    with pytest.raises(ValueError, match="another configuration"):
        ggs.bench.run(shared_pairs(), out=tmp_path, executor="ray", limit=6, voxel=0.01)


def test_register_many_over_ray_equals_local_registration(cluster):
    pairs = [(DATA / "bun0.pcd", DATA / "bun4.pcd"), (str(DATA / "bun045.ply"), str(DATA / "bun000.ply"))]
    order: List[int] = []
    remote = ggs.register_many(pairs, executor="ray", progress=lambda k, r: order.append(k))
    local = ggs.register_many(pairs, threads=1)
    assert sorted(order) == [0, 1]
    for r, l in zip(remote, local):
        assert isinstance(r, ggs.Result) and isinstance(l, ggs.Result)
        assert np.array_equal(r.transformation, l.transformation)
    # A pair that fails is reported in its place, not lost, with its own exception type.
    bad = [(DATA / "missing.ply", DATA / "bun4.pcd"), pairs[0]]
    got = ggs.register_many(bad, executor="ray", on_error="return")
    assert isinstance(got[0], FileNotFoundError) and isinstance(got[1], ggs.Result)
    with pytest.raises(FileNotFoundError):
        ggs.register_many(bad, executor="ray")


def test_align_over_ray_equals_local_alignment(cluster):
    scans = [DATA / "bun045.ply", DATA / "bun000.ply", DATA / "bun0.pcd"]
    remote = ggs.align(scans, executor="ray", align_batch=2)
    local = ggs.align(scans, threads=1, align_batch=2)
    assert remote.names == local.names and remote.unplaced == local.unplaced
    for r, l in zip(remote.poses, local.poses):
        assert (r is None and l is None) or np.array_equal(r, l)
    assert remote.registrations == local.registrations
