"""NICE-SLAM (Zhu et al., CVPR 2022): neural implicit RGB-D SLAM; egs-bench exports to it (it
writes no output egs-bench imports).

**Export.** NICE-SLAM reads the ``replica`` layout with a scene config (``nice_slam.yaml``): a
``cam:`` block (``H W fx fy cx cy png_depth_scale``) and the scene ``bound``, which
:func:`scene_bound` measures from the camera centres and depth maps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import yaml

from egs_bench.geometry import Intrinsics
from egs_bench.interop.camera_files import file_header
from egs_bench.interop.systems import CameraFile, CameraFileRequest, ExternalSystem

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence


def nice_slam_config(cam: Intrinsics, input_folder: str, *, depth_scale: float,
                     bound: list[list[float]], name: str) -> str:
    """A NICE-SLAM scene config (``python run.py THIS_FILE`` from the NICE-SLAM checkout, with
    the export linked at ``input_folder``, relative to it: :func:`checkout_path`); ``bound``
    [[xmin, xmax], [ymin, ymax], [zmin, zmax]] in metres encloses the scene."""
    config = {
        "inherit_from": "configs/Replica/replica.yaml",
        "mapping": {"bound": bound, "marching_cubes_bound": bound},
        # replica.yaml ignores 100 px borders of a 1200x680 image in tracking: scale them
        "tracking": {"ignore_edge_W": round(100 * cam.width / 1200),
                     "ignore_edge_H": round(100 * cam.height / 680)},
        "meshing": {"eval_rec": False},  # needs Replica's ground-truth mesh
        "cam": {"H": cam.height, "W": cam.width, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx,
                "cy": cam.cy, "png_depth_scale": float(depth_scale), "crop_edge": 0},
        "data": {"input_folder": input_folder, "output": f"output/egs_bench/{name}"},
    }
    return file_header(cam, name) + yaml.safe_dump(config, sort_keys=False,
                                               default_flow_style=None)


def scene_bound(seq: Sequence, n: int, margin: float = 0.2) -> list[list[float]]:
    """Axis-aligned world box of the camera centres and the valid depth points of (up to 20)
    frames, plus a margin (NICE-SLAM's ``mapping.bound``)."""
    centres = seq.poses[:n, :3, 3]
    lo, hi = centres.min(0), centres.max(0)
    intr = seq.intrinsics
    for i in np.unique(np.linspace(0, n - 1, min(n, 20)).astype(int)):
        depth = seq.depth(int(i))[::4, ::4]
        pts = intr.backproject(seq.depth(int(i)))[::4, ::4][depth > 0]
        if len(pts) == 0:
            continue
        pose = seq.poses[int(i)]
        world = pts @ pose[:3, :3].T + pose[:3, 3]
        lo, hi = np.minimum(lo, world.min(0)), np.maximum(hi, world.max(0))
    return [[round(float(a) - margin, 2), round(float(b) + margin, 2)]
            for a, b in zip(lo, hi, strict=True)]


def _config_file(request: CameraFileRequest) -> str:
    return nice_slam_config(request.camera, request.dataset_path,
                            depth_scale=request.depth_units(),
                            bound=scene_bound(request.sequence, request.frames),
                            name=request.sequence.name)


SYSTEM = ExternalSystem(key="nice_slam", title="NICE-SLAM",
                        camera_files={"replica": CameraFile("nice_slam.yaml", _config_file)})
