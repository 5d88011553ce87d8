"""``ggs.align`` on the bundled bunny scans: poses in the first scan's frame, names, the
anchor, the files, and the errors."""

import json
from pathlib import Path

import numpy as np
import pytest

import ggs

DATA = Path(__file__).resolve().parents[2] / "tests" / "data"
SCANS = [DATA / "bun000.ply", DATA / "bun045.ply"]


def test_two_scans_are_placed_in_the_first_ones_frame():
    progress = []
    a = ggs.align(SCANS, threads=2, progress=lambda k, n: progress.append((k, n)))
    assert a.names == [str(p) for p in SCANS]
    assert a.unplaced == [] and a.anchor == str(SCANS[0])
    assert np.array_equal(a.poses[0], np.eye(4))
    angle = np.degrees(np.arccos((np.trace(a.poses[1][:3, :3]) - 1) / 2))
    assert abs(angle - 34.3) < 1.0
    assert a.confidences[0] == 1.0 and a.confidences[1] > 0.3
    assert a.document["format"] == "ggs-alignment/1"
    assert a.graph and a.graph[0]["accepted"]
    assert progress and progress[-1] == (2, 2)
    assert "2 of 2 scans placed" in repr(a)


def test_arrays_with_names_and_an_anchor_give_the_same_relative_pose(tmp_path):
    clouds = [ggs.read_point_cloud(p) for p in SCANS]
    a = ggs.align(clouds, names=["front", "side"], anchor="side")
    assert a.anchor == "side" and np.array_equal(a.pose("side"), np.eye(4))
    b = ggs.align(SCANS)
    relative = np.linalg.inv(b.poses[1]) @ b.poses[0]
    assert np.allclose(a.pose("front"), relative, atol=1e-3)
    a.write(tmp_path)
    doc = json.loads((tmp_path / "poses.json").read_text())
    assert [s["name"] for s in doc["scans"]] == ["front", "side"]
    assert (tmp_path / "scans" / "front.ply").is_file() and (tmp_path / "report.html").is_file()
    assert "pose graph" in a.report_html().lower()
    with pytest.raises(KeyError, match="no scan named 'top'"):
        a.pose("top")


def test_bad_input_is_refused_with_what_is_wrong():
    with pytest.raises(ValueError, match="at least two scans"):
        ggs.align(SCANS[:1])
    with pytest.raises(ValueError, match="anchor: no scan named 'x'"):
        ggs.align(SCANS, anchor="x")
    with pytest.raises(ValueError, match="names: 1 names for 2 scans"):
        ggs.align(SCANS, names=["a"])
    with pytest.raises(ValueError, match="align_min_confidence"):
        ggs.align(SCANS, align_min_confidence=2.0)
    with pytest.raises(ValueError, match="both named"):
        ggs.align(SCANS, names=["a", "a"])
    with pytest.raises(FileNotFoundError):
        ggs.align([SCANS[0], DATA / "absent.ply"])
    with pytest.raises(ValueError, match="executor"):
        ggs.align(SCANS, executor="dask")  # type: ignore[arg-type]
