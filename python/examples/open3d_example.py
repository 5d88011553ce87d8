"""Register two Open3D point clouds with ggs and draw them (Open3D only if installed).

    python python/examples/open3d_example.py SOURCE TARGET [VOXEL]

Without arguments it uses the bundled PCL bunny pair (tests/data). Open3D reads the files
and, unless GGS_NO_WINDOW is set, shows the aligned pair; ggs takes Open3D's PointCloud as it
is (anything with ``.points``). Without Open3D (``pip install open3d``) it says so and exits
with status 0.
"""

import os
import sys
from pathlib import Path

import ggs

try:
    import open3d as o3d
except ImportError:  # an optional dependency: the example is skipped, not failed
    o3d = None


def main(argv):
    if o3d is None:
        print("open3d is not installed (pip install open3d): skipping this example")
        return None
    data = Path(__file__).resolve().parents[2] / "tests" / "data"
    src_path = argv[1] if len(argv) > 1 else str(data / "bun0.pcd")
    tgt_path = argv[2] if len(argv) > 2 else str(data / "bun4.pcd")
    voxel = float(argv[3]) if len(argv) > 3 else 0.006
    source = o3d.io.read_point_cloud(src_path)
    target = o3d.io.read_point_cloud(tgt_path)
    result = ggs.register(source, target, voxel=voxel)
    print(result)
    source.transform(result.transformation)
    if not os.environ.get("GGS_NO_WINDOW"):
        source.paint_uniform_color([1.0, 0.55, 0.0])
        target.paint_uniform_color([0.15, 0.45, 1.0])
        o3d.visualization.draw_geometries([source, target])
    return result


if __name__ == "__main__":
    main(sys.argv)
