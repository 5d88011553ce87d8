#!/usr/bin/env python3
"""Accuracy, time and memory of `ggs align` on the Stanford bunny's ten scans, shuffled and moved.

Each seed writes a set: every scan of ../shared/data/stanford_bunny moved by a seeded random
rigid motion (rotation uniform, translation up to 0.5 m a side), the order shuffled, and with
--distractor OBJ the vertices of another object scaled to the bunny's size mixed in. The set
is aligned with no flag (`ggs align --list`), and each placed scan's pose is compared with
the scanner's poses in bun.conf, up to the anchor's frame: the rotation angle, and the shift
of the scan's centroid. One pairwise registration of two bunny scans (bun000 onto bun045, as
a whole process, the median of three runs) runs before each alignment, so the ratio of the
two times compares runs of the same moment on the same machine.

    python3 scripts/align_bunny.py --seeds 1 2 3 --threads 2
    python3 scripts/align_bunny.py --seeds 1 --distractor ../shared/data/human_meshes/nefertiti-lowres.obj --check

--check exits non-zero unless every bunny scan is placed within 1° and 2 mm and the
distractor is not placed. Needs numpy and a built `ggs` (cargo build --release).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCANS = ["bun000", "bun045", "bun090", "bun180", "bun270", "bun315", "chin", "ear_back", "top2", "top3"]
MAX_DEG, MAX_MM = 1.0, 2.0


def read_ply_points(path: Path) -> np.ndarray:
    """The x, y, z of an ASCII PLY's vertices."""
    lines = path.read_text().split("\n")
    end = lines.index("end_header")
    count = next(int(line.split()[2]) for line in lines[:end] if line.startswith("element vertex"))
    return np.array([[float(v) for v in line.split()[:3]] for line in lines[end + 1 : end + 1 + count]])


def write_ply(path: Path, points: np.ndarray) -> None:
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
        "property double x\nproperty double y\nproperty double z\nend_header\n"
    )
    path.write_bytes(header.encode() + points.astype("<f8").tobytes())


def quaternion_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def scanner_poses(conf: Path) -> dict:
    """bun.conf's `bmesh NAME tx ty tz qx qy qz qw`: p_world = R · p + t, with R the
    transpose of the quaternion's matrix (the file's convention)."""
    poses = {}
    for line in conf.read_text().splitlines():
        f = line.split()
        if f and f[0] == "bmesh":
            x, y, z, w = map(float, f[5:9])
            pose = np.eye(4)
            pose[:3, :3] = quaternion_matrix(w, x, y, z).T
            pose[:3, 3] = [float(v) for v in f[2:5]]
            poses[Path(f[1]).stem] = pose
    return poses


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return quaternion_matrix(*(q / np.linalg.norm(q)))


def make_set(folder: Path, data: Path, seed: int, distractor: Path | None) -> dict:
    """Write the moved scans and list.txt; return each file's motion (file = M · original)."""
    rng = np.random.default_rng(seed)
    motions = {}
    for name in SCANS:
        points = read_ply_points(data / f"{name}.ply")
        m = np.eye(4)
        m[:3, :3] = random_rotation(rng)
        m[:3, 3] = rng.uniform(-0.5, 0.5, 3)
        write_ply(folder / f"{name}_moved.ply", points @ m[:3, :3].T + m[:3, 3])
        motions[f"{name}_moved.ply"] = m
    order = list(motions)
    if distractor is not None:
        v = np.array([[float(t) for t in line.split()[1:4]] for line in distractor.read_text().splitlines() if line.startswith("v ")])
        v = (v - v.mean(axis=0)) * (0.15 / np.ptp(v, axis=0).max())
        write_ply(folder / "distractor.ply", v @ random_rotation(rng).T)
        order.append("distractor.ply")
    rng.shuffle(order)
    (folder / "list.txt").write_text("\n".join(order) + "\n")
    return motions


def run(command: list, cwd: Path | None = None) -> tuple:
    """Wall seconds, peak resident MB and stdout of a child process."""
    start = time.perf_counter()
    child = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    out = child.stdout.read()
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    if status != 0:
        sys.exit(f"{' '.join(map(str, command))} failed")
    return seconds, usage.ru_maxrss / 1024, out


def errors(result: dict, folder: Path, truth: dict, motions: dict) -> tuple:
    """Worst rotation (degrees) and centroid shift (mm) of the placed bunny scans; the
    bunny scans not placed; whether the distractor was placed."""

    def world(name: str) -> np.ndarray:  # p_world = truth · M⁻¹ · p_file
        return truth[name.removesuffix("_moved.ply")] @ np.linalg.inv(motions[name])

    to_anchor = np.linalg.inv(world(result["anchor"]))
    worst_deg = worst_mm = 0.0
    missing, distractor_placed = [], False
    for scan in result["scans"]:
        if scan["name"] not in motions:
            distractor_placed = scan["pose"] is not None
            continue
        if scan["pose"] is None:
            missing.append(scan["name"])
            continue
        e = np.linalg.inv(to_anchor @ world(scan["name"])) @ np.array(scan["pose"])
        deg = np.degrees(np.arccos(np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1)))
        c = np.frombuffer((folder / scan["name"]).read_bytes().split(b"end_header\n", 1)[1], "<f8").reshape(-1, 3).mean(axis=0)
        mm = 1e3 * np.linalg.norm(e[:3, :3] @ c + e[:3, 3] - c)
        worst_deg, worst_mm = max(worst_deg, deg), max(worst_mm, mm)
    return worst_deg, worst_mm, missing, distractor_placed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--distractor", type=Path, help="an OBJ of another object to mix in")
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "stanford_bunny")
    ap.add_argument("--ggs", type=Path, default=ROOT / "target" / "release" / "ggs")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--check", action="store_true", help="fail unless every scan is within 1° / 2 mm and the distractor unplaced")
    args = ap.parse_args()
    truth = scanner_poses(args.data / "bun.conf")
    threads = ["--threads", str(args.threads)]
    pair = [args.ggs, "register", args.data / "bun000.ply", args.data / "bun045.ply", *threads]
    print("| seed | placed | distractor | worst ° | worst mm | registrations | align s | pair s | ratio | MB |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    failed = False
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            motions = make_set(folder, args.data, seed, args.distractor)
            pair_s = statistics.median(run(pair)[0] for _ in range(3))
            align_s, mb, out = run([args.ggs, "align", "--list", "list.txt", "--out", "out", "--json", *threads], cwd=folder)
            result = json.loads(out)
            deg, mm, missing, stray = errors(result, folder, truth, motions)
        placed = len(SCANS) - len(missing)
        distractor = "-" if args.distractor is None else ("PLACED" if stray else "unplaced")
        print(
            f"| {seed} | {placed}/{len(SCANS)} | {distractor} | {deg:.2f} | {mm:.2f} | {result['registrations']} "
            f"| {align_s:.2f} | {pair_s:.2f} | {align_s / pair_s:.1f} | {mb:.0f} |",
            flush=True,
        )
        failed |= bool(missing) or stray or deg > MAX_DEG or mm > MAX_MM
    if args.check and failed:
        sys.exit("align_bunny: a scan is unplaced or off by more than 1° / 2 mm, or the distractor was placed")


if __name__ == "__main__":
    main()
