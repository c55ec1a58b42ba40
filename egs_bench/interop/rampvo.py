"""RampVO (Pellerito et al., 2024): event + image visual odometry, on the ``eds`` layout.

**Export.** RampVO reads the ``eds`` layout with ``K.yaml`` (``cam0: {intrinsics: [fx, fy, cx,
cy], resolution: [w, h]}``, read by ``evaluate.py:set_global_params``).

**Import** (``--from rampvo``). ``stamped_traj_estimate.txt`` (``np.savetxt`` of ``t x y z``
and four quaternion columns). RampVO@9353aaa labels them w-first (evo's
``orientations_quat_wxyz``) but fills them with lietorch's ``x y z w`` permuted by
``(1, 2, 3, 0)``, i.e. the columns hold ``qy qz qw qx``; ``quaternion="rampvo"`` (default)
undoes that, ``"wxyz"`` reads a true w-first file (e.g. its ``stamped_groundtruth.txt``, or a
fixed fork). Its time column is the image stamp in seconds times 1e-9 on EDS
(``save_results`` multiplies by ``10 ** -9``); the unit is detected against the export's
stamps. Monocular VO: marked scale-free, so evaluation aligns with Sim(3), as RampVO's own ATE
does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Intrinsics, pose_from_tq
from egs_bench.interop.camera_files import file_header
from egs_bench.interop.systems import (
    CameraFile,
    CameraFileRequest,
    ExternalEstimate,
    ExternalSystem,
    ImportOptions,
)

#: the quaternion column orders :func:`read_rampvo` reads
QUATERNION_ORDERS = ("rampvo", "wxyz")


def rampvo_k_yaml(cam: Intrinsics, *, name: str) -> str:
    """RampVO's ``K.yaml`` (read by ``evaluate.py:set_global_params``)."""
    data = {"cam0": {"intrinsics": [cam.fx, cam.fy, cam.cx, cam.cy],
                     "resolution": [cam.width, cam.height]}}
    return file_header(cam, name) + yaml.safe_dump(data, sort_keys=False)


def _k_file(request: CameraFileRequest) -> str:
    return rampvo_k_yaml(request.camera, name=request.sequence.name)


def read_rampvo(source: str | Path, quaternion: str = "rampvo") -> ExternalEstimate:
    """RampVO's ``stamped_traj_estimate.txt`` (see the module docstring for its columns and
    time unit)."""
    if quaternion not in QUATERNION_ORDERS:
        raise ConfigError(f"quaternion order must be one of {', '.join(QUATERNION_ORDERS)}, "
                          f"not {quaternion!r}")
    path = Path(source)
    if path.is_dir():
        path = path / "stamped_traj_estimate.txt"
    if not path.is_file():
        raise InputError(path, "not found")
    try:
        data = np.loadtxt(path, ndmin=2)
    except ValueError as exc:
        raise InputError(path, f"not a table of numbers ({exc})") from None
    if data.shape[1] != 8:
        raise InputError(path, f"expected 8 columns (t x y z and a quaternion), found "
                               f"{data.shape[1]}")
    if len(data) < 3 or not np.isfinite(data).all():
        raise InputError(path, "needs at least 3 finite poses")
    data = data[np.argsort(data[:, 0], kind="stable")]
    c = data[:, 4:8]
    q_xyzw = c[:, [3, 0, 1, 2]] if quaternion == "rampvo" else c[:, [1, 2, 3, 0]]
    if (np.linalg.norm(q_xyzw, axis=1) < 1e-6).any():
        raise InputError(path, "zero quaternion")
    return ExternalEstimate(pose_from_tq(data[:, 1:4], q_xyzw), stamps_s=data[:, 0],
                            poses_kind="subset", scale_free=True, sources=[str(path)],
                            stamps_unit_unknown=True,
                            settings={"quaternion_columns": quaternion})


def _read(source: Path, options: ImportOptions) -> ExternalEstimate:
    return read_rampvo(source, options.quaternion)


SYSTEM = ExternalSystem(key="rampvo", title="RampVO", read=_read,
                        output="stamped_traj_estimate.txt",
                        camera_files={"eds": CameraFile("K.yaml", _k_file)})
