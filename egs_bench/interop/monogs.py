"""MonoGS (Matsuki et al., CVPR 2024): Gaussian-splatting SLAM, in RGB-D mode.

**Export.** MonoGS reads the ``tum-rgbd`` and ``replica`` layouts with a YAML config of its own
(``monogs_rgbd.yaml`` / ``monogs_replica.yaml``): ``Dataset.Calibration`` (``fx fy cx cy k1 k2
p1 p2 k3 distorted width height depth_scale``, read by ``utils/dataset.py``), merged over a
base config through ``inherit_from`` (a path relative to the MonoGS checkout, where
``slam.py`` runs). Its TUM loader keeps a frame only when it is more than 1/32 s after the last
kept one (:func:`monogs_kept_frames`); its Replica loader keeps every frame.

**Import** (``--from monogs``). The result folder (or ``plot/trj_final.json``):
``{"trj_id": [frame uid...], "trj_est": [4x4 camera-to-world...], "trj_gt": [...]}`` for
**keyframes only** (``utils/eval_utils.py eval_ate``); uids index the frames MonoGS kept after
its association and 1/32 s subsampling. MonoGS saves no renders; ``render_ply`` renders its
``point_cloud/final/point_cloud.ply`` at the imported poses. Its own numbers
(``plot/stats_final.json``, ``psnr/*/final_result.json``) are kept in ``reported_metrics.json``
(not used for scoring).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

from egs_bench.errors import InputError
from egs_bench.geometry import Intrinsics
from egs_bench.interop.camera_files import CHECKOUT_ROOT, file_header
from egs_bench.interop.systems import (
    CameraFile,
    CameraFileRequest,
    ExternalEstimate,
    ExternalSystem,
    ImportOptions,
)

#: MonoGS' TUM loader keeps a frame only if it is more than this after the last kept one
MONOGS_MIN_GAP_S = 1.0 / 32.0
#: MonoGS' ``Dataset.type`` for each export layout it reads
DATASET_TYPES = {"tum-rgbd": "tum", "replica": "replica"}
#: the Gaussian map in a MonoGS result folder
GAUSSIAN_MAP = "point_cloud/final/point_cloud.ply"


def monogs_config(cam: Intrinsics, dataset_path: str, *, dataset_type: str, depth_scale: float,
                  name: str) -> str:
    """A MonoGS RGB-D config (``python slam.py --config FILE --eval`` from the MonoGS checkout).

    Args:
        dataset_path: the exported folder as MonoGS finds it, relative to the MonoGS checkout
            (:func:`checkout_path`; no path of this machine goes into a file meant to be sent
            on); a trailing ``/`` is added because MonoGS names its result folder after the
            last two path components.
        dataset_type: ``"tum"`` or ``"replica"`` (MonoGS' ``Dataset.type``).
        depth_scale: depth PNG units per metre.
    """
    base = {"tum": "configs/rgbd/tum/base_config.yaml",
            "replica": "configs/rgbd/replica/base_config.yaml"}[dataset_type]
    config = {
        "inherit_from": base,
        "Dataset": {
            "dataset_path": dataset_path.rstrip("/") + "/",
            "type": dataset_type,
            "sensor_type": "depth",
            "single_thread": True,
            "Calibration": {
                "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
                "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0, "distorted": False,
                "width": cam.width, "height": cam.height, "depth_scale": float(depth_scale),
            },
        },
        "Training": {"single_thread": True},
        "Results": {"use_gui": False},
    }
    comment = (file_header(cam, name)
               + "# MonoGS single-thread RGB-D mode (as the EGS-SLAM paper ran it). From the "
                 "MonoGS checkout, link\n# this folder where dataset_path points, then run:\n"
                 f"#   mkdir -p {CHECKOUT_ROOT} && ln -s THIS_FOLDER {dataset_path.rstrip('/')}\n"
                 "#   WANDB_MODE=disabled python slam.py --config THIS_FILE --eval\n")
    return comment + yaml.safe_dump(config, sort_keys=False)


def _config_file(request: CameraFileRequest) -> str:
    return monogs_config(request.camera, request.dataset_path,
                         dataset_type=DATASET_TYPES[request.layout],
                         depth_scale=request.depth_units(), name=request.sequence.name)


def monogs_kept_frames(stamps_s: np.ndarray) -> np.ndarray:
    """Indices of the frames MonoGS' TUM loader keeps: each one more than 1/32 s after the last
    kept one (its uids index this list)."""
    kept = [0]
    for i in range(1, len(stamps_s)):
        if stamps_s[i] - stamps_s[kept[-1]] > MONOGS_MIN_GAP_S:
            kept.append(i)
    return np.asarray(kept, dtype=np.int64)


def _monogs_json(path: Path) -> tuple[np.ndarray, np.ndarray]:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(path, f"not a MonoGS trajectory JSON ({exc})") from None
    if not isinstance(data, dict) or "trj_id" not in data or "trj_est" not in data:
        raise InputError(path, "not a MonoGS trajectory JSON (needs 'trj_id' and 'trj_est')")
    try:
        uids = np.asarray(data["trj_id"], dtype=np.int64)
        poses = np.asarray(data["trj_est"], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(path, f"malformed 'trj_id' / 'trj_est' ({exc})") from None
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) != len(uids):
        raise InputError(path, f"'trj_est' must hold one 4x4 matrix per 'trj_id' entry, got "
                               f"shape {poses.shape} for {len(uids)} ids")
    if len(uids) < 3:
        raise InputError(path, f"holds {len(uids)} poses, at least 3 needed")
    if not np.isfinite(poses).all():
        raise InputError(path, "non-finite pose values")
    rot = poses[:, :3, :3]
    err = np.abs(rot.transpose(0, 2, 1) @ rot - np.eye(3)).max(axis=(1, 2))
    if (err > 1e-4).any() or (uids < 0).any() or len(np.unique(uids)) != len(uids):
        raise InputError(path, "'trj_est' holds a matrix that is not a rigid transform, or "
                               "'trj_id' has negative or repeated ids")
    order = np.argsort(uids)
    return uids[order], poses[order]


def read_monogs(source: str | Path) -> ExternalEstimate:
    """MonoGS: a result folder (``plot/trj_final.json``, metrics, ``point_cloud``) or a
    ``trj_*.json`` file (also one written for all frames by a dump hook: then every uid is
    present and the estimate counts as all frames)."""
    source = Path(source)
    folder = source if source.is_dir() else None
    path = source / "plot" / "trj_final.json" if folder is not None else source
    if not path.is_file():
        raise InputError(path, "not found (MonoGS writes it with --eval or save_results)")
    uids, poses = _monogs_json(path)
    dense = len(uids) == int(uids.max()) + 1
    est = ExternalEstimate(poses, uids=uids, poses_kind="all" if dense else "keyframes",
                           keyframe_uids=None if dense else uids, sources=[str(path)],
                           # an intermediate trj_<n>.json: MonoGS was still running
                           written_at_end=path.name == "trj_final.json")
    if folder is not None:
        for name, rel in (("ate_stats", "plot/stats_final.json"),
                          ("rendering_before_opt", "psnr/before_opt/final_result.json"),
                          ("rendering_after_opt", "psnr/after_opt/final_result.json")):
            f = folder / rel
            if f.is_file():
                try:
                    est.reported[name] = json.loads(f.read_text())
                except json.JSONDecodeError as exc:
                    raise InputError(f, f"not valid JSON ({exc})") from None
        ply = folder / GAUSSIAN_MAP
        est.ply = ply if ply.is_file() else None
    return est


def _read(source: Path, options: ImportOptions) -> ExternalEstimate:
    return read_monogs(source)


def loaded_frames(layout: str | None, stamps_s: np.ndarray) -> np.ndarray:
    """The export frames MonoGS loads (its uids index them): its TUM loader drops frames
    closer than 1/32 s (:func:`monogs_kept_frames`), its Replica loader none."""
    if layout == "replica":
        return np.arange(len(stamps_s))
    return monogs_kept_frames(stamps_s)


SYSTEM = ExternalSystem(
    key="monogs", title="MonoGS", read=_read, loaded_frames=loaded_frames,
    output="result folder or trj_final.json", gaussian_map=GAUSSIAN_MAP,
    camera_files={"tum-rgbd": CameraFile("monogs_rgbd.yaml", _config_file),
                  "replica": CameraFile("monogs_replica.yaml", _config_file)})
