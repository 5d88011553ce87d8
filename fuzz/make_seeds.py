#!/usr/bin/env python3
"""Build the fuzz seed corpora from the real files in ../shared/data.

Every seed is a small, valid file cut from a real scan (the first few hundred points, with
the header's counts rewritten), in every layout the parser handles: PLY ascii / binary LE /
binary BE (the bunny scans, with their obj_info lines and range_grid element), PCD ascii /
binary / binary_compressed (PCL's test views, the LiDAR scan), CSV in both layouts
(libpointmatcher), NPY and NPZ (3DMatch), KITTI .bin, LAS / LAZ / E57 (written by
`ggs convert` from the real points), OBJ (human meshes) and STL (their triangles).

    python3 fuzz/make_seeds.py [--ggs target/release/ggs]   # writes fuzz/corpus/<target>/
"""
import argparse
import io
import os
import struct
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
DATA = ROOT.parent.parent / "shared" / "data"
N = 300  # points per seed


def out(target, name, data):
    d = ROOT / "corpus" / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data)


def ply_seeds():
    for name in ["bun000.ply", "top2.ply"]:
        # The Stanford scans have CRLF line ends: the ascii seed keeps them.
        text = (DATA / "stanford_bunny" / name).read_bytes().replace(b"\r\n", b"\n")
        head, body = text.split(b"end_header\n", 1)
        lines = head.decode().splitlines()
        vertex_lines = body.split(b"\n")[:N]
        new = []
        for l in lines:
            if l.startswith("element vertex"):
                new.append(f"element vertex {N}")
            elif l.startswith("element range_grid"):
                new.append("element range_grid 4")
            else:
                new.append(l)
        rows = [list(map(float, v.split()[:3])) for v in vertex_lines]
        grid = b"1 0\n0\n2 1 2\n0\n"
        ascii_ply = ("\n".join(new) + "\nend_header\n").encode() + b"\n".join(vertex_lines) + b"\n" + grid
        out("ply", f"{name}.ascii.ply", ascii_ply.replace(b"\n", b"\r\n"))
        for fmt, e in [("binary_little_endian", "<"), ("binary_big_endian", ">")]:
            h = "\n".join(l.replace("format ascii", f"format {fmt}") for l in new) + "\nend_header\n"
            b = bytearray(h.encode())
            for r in rows:
                b += struct.pack(e + "3f", *r)
            for cnt, idx in [(1, [0]), (0, []), (2, [1, 2]), (0, [])]:
                b += struct.pack(e + "B", cnt) + struct.pack(e + f"{len(idx)}i", *idx)
            out("ply", f"{name}.{fmt}.ply", bytes(b))
    # A mesh with faces, doubles, colours.
    rows = read_obj(DATA / "human_meshes" / "human_man.obj")
    v, f = rows
    h = f"ply\nformat binary_little_endian 1.0\ncomment cut from human_man.obj\nelement vertex {len(v)}\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    b = bytearray(h.encode())
    for p in v:
        b += struct.pack("<3dB", *p, 200)
    for t in f:
        b += struct.pack("<B3i", 3, *t)
    out("ply", "human_man.mesh.ply", bytes(b))


def pcd_header(fields, sizes, types, n, data):
    return (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        f"FIELDS {' '.join(fields)}\nSIZE {' '.join(map(str, sizes))}\nTYPE {' '.join(types)}\n"
        f"COUNT {' '.join('1' for _ in fields)}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
        f"POINTS {n}\nDATA {data}\n"
    ).encode()


def lzf_literals(raw):
    """LZF with literal runs only (valid for any decoder), plus one back-reference."""
    outb = bytearray()
    i = 0
    while i < len(raw):
        run = raw[i : i + 32]
        outb.append(len(run) - 1)
        outb += run
        i += len(run)
    return bytes(outb)


def pcd_seeds():
    for name in ["bun0.pcd", "bun4.pcd"]:
        out("pcd", name, (DATA / "pcl_test" / name).read_bytes())
    raw = (DATA / "lidar_koide_gicp_pair" / "251370668.pcd").read_bytes()
    head, body = raw.split(b"DATA binary\n", 1)
    recs = body[: 16 * N]
    out("pcd", "lidar.binary.pcd", pcd_header(["x", "y", "z", "intensity"], [4] * 4, ["F"] * 4, N, "binary") + recs)
    pts = [struct.unpack_from("<4f", recs, 16 * i) for i in range(N)]
    cols = b"".join(b"".join(struct.pack("<f", p[k]) for p in pts) for k in range(4))
    comp = lzf_literals(cols)
    out("pcd", "lidar.compressed.pcd", pcd_header(["x", "y", "z", "intensity"], [4] * 4, ["F"] * 4, N, "binary_compressed") + struct.pack("<II", len(comp), len(cols)) + comp)
    # Back-references: 48 zero bytes = one literal zero, then a copy of 47 bytes at
    # distance 1 (ctrl 7<<5 with an extra length byte: 7 + 38 + 2 = 47).
    zeros = bytes(24 * 2)
    comp = bytes([0, 0]) + bytes([7 << 5, 38, 0])
    out("pcd", "zeros.compressed.pcd", pcd_header(["x", "y", "z"], [8] * 3, ["F"] * 3, 2, "binary_compressed") + struct.pack("<II", len(comp), len(zeros)) + comp)
    text = "\n".join(" ".join(f"{v:.6f}" for v in p[:3]) for p in pts[:50])
    out("pcd", "lidar.ascii.pcd", pcd_header(["x", "y", "z"], [4] * 3, ["F"] * 3, 50, "ascii") + text.encode() + b"\n")


def text_seeds():
    for name in ["car_cloud400.csv", "car_cloud401.csv"]:
        lines = (DATA / "libpointmatcher_car" / name).read_bytes().split(b"\n")[:N]
        out("text", name, b"\n".join(lines) + b"\n")


def npy_bytes(rows, dtype="<f8"):
    header = f"{{'descr': '{dtype}', 'fortran_order': False, 'shape': ({len(rows)}, {len(rows[0])}), }}"
    header += " " * ((64 - (10 + len(header) + 1) % 64) % 64) + "\n"
    b = bytearray(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode())
    code = "d" if dtype.endswith("8") else "f"
    for r in rows:
        b += struct.pack("<" + code * len(r), *r)
    return bytes(b)


def read_npy_rows(path, n):
    raw = path.read_bytes()
    hlen = struct.unpack_from("<H", raw, 8)[0]
    start = 10 + hlen
    return [list(struct.unpack_from("<3d", raw, start + 24 * i)) for i in range(n)]


def npy_seeds():
    rows = read_npy_rows(DATA / "3dmatch_geotransformer_demo" / "src.npy", N)
    out("npy", "src.f8.npy", npy_bytes(rows))
    out("npy", "src.f4.npy", npy_bytes(rows[:50], "<f4"))
    for method, tag in [(zipfile.ZIP_STORED, "stored"), (zipfile.ZIP_DEFLATED, "deflated")]:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", method) as z:
            z.writestr("points.npy", npy_bytes(rows))
            z.writestr("labels.npy", npy_bytes([[1.0, 2.0]]))
        out("npz", f"src.{tag}.npz", buf.getvalue())
    return rows


def kitti_seeds(rows):
    out("kitti", "src.bin", b"".join(struct.pack("<4f", *r, 0.5) for r in rows))


def read_obj(path, n=200):
    v, f = [], []
    for line in path.read_text(errors="replace").splitlines():
        t = line.split()
        if not t:
            continue
        if t[0] == "v" and len(v) < n:
            v.append([float(x) for x in t[1:4]])
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) - 1 for x in t[1:]]
            if all(0 <= i < n for i in idx) and len(idx) >= 3:
                for k in range(1, len(idx) - 1):
                    f.append([idx[0], idx[k], idx[k + 1]])
    return v, f


def mesh_seeds():
    for name in ["human_man.obj", "nefertiti-lowres.obj", "base.obj"]:
        lines = (DATA / "human_meshes" / name).read_text(errors="replace").splitlines()
        v, kept = 0, []
        for l in lines:
            if l.startswith("v "):
                v += 1
                if v > N:
                    continue
            if l.startswith("f "):
                idx = [int(x.split("/")[0]) for x in l.split()[1:]]
                if any(i > N or i < -N for i in idx):
                    continue
            kept.append(l)
            if len(kept) > 3000:
                break
        out("obj", name, ("\n".join(kept) + "\n").encode())
    v, f = read_obj(DATA / "human_meshes" / "human_man.obj")
    text = ["solid human_man"]
    for t in f:
        text += ["facet normal 0 0 0", " outer loop"] + [f"  vertex {v[i][0]} {v[i][1]} {v[i][2]}" for i in t] + [" endloop", "endfacet"]
    out("stl", "human_man.ascii.stl", ("\n".join(text + ["endsolid human_man"]) + "\n").encode())
    b = bytearray(b"binary STL cut from human_man.obj".ljust(80, b" ") + struct.pack("<I", len(f)))
    for t in f:
        b += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *v[i]) for i in t) + b"\0\0"
    out("stl", "human_man.binary.stl", bytes(b))


def converted_seeds(ggs, rows):
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "src.xyz"
        src.write_text("\n".join(" ".join(repr(x) for x in r) for r in rows) + "\n")
        for target, ext in [("las", "las"), ("las", "laz"), ("e57", "e57")]:
            dst = Path(d) / f"src.{ext}"
            subprocess.run([ggs, "convert", "--quiet", str(src), str(dst)], check=True)
            out(target, f"src.{ext}", dst.read_bytes())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ggs", default=str(ROOT.parent / "target" / "release" / "ggs"))
    a = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"error: {DATA} not found (../shared beside the work tree)")
    ply_seeds()
    pcd_seeds()
    text_seeds()
    rows = npy_seeds()
    kitti_seeds(rows)
    mesh_seeds()
    converted_seeds(a.ggs, rows)
    for t in sorted((ROOT / "corpus").iterdir()):
        files = list(t.iterdir())
        print(f"{t.name:6} {len(files):3} seeds, {sum(f.stat().st_size for f in files) / 1e3:8.1f} kB")


if __name__ == "__main__":
    main()
