"""The data of the report's 3D views (``static/viewer.js``, built from ``viewer_src/``).

A page opened from ``file://`` may neither fetch files nor load ES modules, so each view's
data is a classic script next to its page, ``<page>.view.js``, that sets ``window.EGS_VIEW``.

* A **run view** holds the run's own map, quantised (:func:`encode_splats`: 17 bytes per
  Gaussian, base64), in display colours through the run's camera response exactly as
  ``egs-bench export-map`` writes them (:func:`egs_bench.slam.map_export.display_colors`);
  the estimated camera-to-world pose of every frame in the map's frame; the run's camera
  (intrinsics at the resolution of its renders, near plane); the ground-truth positions moved
  into the map's frame by the inverse of the run's ATE alignment (so estimate and ground truth
  sit relative to each other as the ATE scores them); the keyframes; and per frame the
  report's images of the observed frame, the render and the sharp ground truth.
* A **sequence view** holds every run's estimated positions after its ATE alignment and the
  ground-truth positions, in the ground truth's frame.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from egs_bench.report.assets import AssetStore
from egs_bench.report.collect import RunRecord
from egs_bench.report.sources import RunSources

#: File suffix of a page's view data, next to the page.
VIEW_SUFFIX = ".view.js"
#: Bytes per Gaussian of :func:`encode_splats`.
SPLAT_BYTES = 17
#: Most frames whose images a run view stores (evenly spaced over the rendered frames).
MAX_IMAGE_FRAMES = 8


@dataclass(frozen=True)
class EncodedSplats:
    """A quantised map (see :func:`encode_splats`) and the ranges that decode it."""

    count: int
    data: bytes
    bbox_min: list[float]
    bbox_max: list[float]
    ln_scale_min: float
    ln_scale_max: float
    color_min: list[float]
    color_max: list[float]

    def to_json(self) -> dict[str, Any]:
        return {"count": self.count, "data": base64.b64encode(self.data).decode("ascii"),
                "bbox_min": self.bbox_min, "bbox_max": self.bbox_max,
                "ln_scale_min": self.ln_scale_min, "ln_scale_max": self.ln_scale_max,
                "color_min": self.color_min, "color_max": self.color_max}


def _quantise(values: np.ndarray, lo: np.ndarray, hi: np.ndarray, levels: int) -> np.ndarray:
    span = np.where(hi > lo, hi - lo, 1.0)
    return np.rint(np.clip((values - lo) / span, 0.0, 1.0) * levels)


def encode_splats(means: np.ndarray, rotations: np.ndarray, log_scales: np.ndarray,
                  opacities: np.ndarray, colors: np.ndarray) -> EncodedSplats:
    """Quantise a map into the viewer's layout (struct of arrays, little endian).

    Args:
        means: [N, 3] positions, m: uint16 over their bounding box (step: box size / 65535).
        rotations: [N, 4] unit quaternions ``(w, x, y, z)``: int8 ``round(127 q)``.
        log_scales: [N, 3] log standard deviations, log m: uint8 over their range.
        opacities: [N] in [0, 1]: uint8 ``round(255 o)``.
        colors: [N, 3] display colours (may leave [0, 1]): uint8 over each channel's range.

    Returns:
        the bytes (``17 N``: positions ``6 N``, scales ``3 N``, colours ``3 N``, opacities
        ``N``, rotations ``4 N``) and the ranges; Gaussians with a non-finite value or a zero
        quaternion are left out (``N`` counts the others).
    """
    means = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    log_scales = np.asarray(log_scales, dtype=np.float64).reshape(-1, 3)
    colors = np.asarray(colors, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(rotations, dtype=np.float64).reshape(-1, 4)
    opacities = np.asarray(opacities, dtype=np.float64).reshape(-1)
    # a Gaussian with a non-finite value cannot be drawn (and would stretch the ranges)
    norm = np.linalg.norm(q, axis=1)
    keep = (np.isfinite(means).all(1) & np.isfinite(log_scales).all(1)
            & np.isfinite(colors).all(1) & np.isfinite(opacities) & np.isfinite(norm)
            & (norm > 0))
    means, log_scales, colors, opacities = means[keep], log_scales[keep], colors[keep], \
        opacities[keep]
    q = q[keep] / norm[keep, None]
    n = len(means)
    if n == 0:
        return EncodedSplats(0, b"", [0.0] * 3, [0.0] * 3, 0.0, 0.0, [0.0] * 3, [0.0] * 3)
    lo, hi = means.min(0), means.max(0)
    s0, s1 = float(log_scales.min()), float(log_scales.max())
    c0, c1 = colors.min(0), colors.max(0)
    parts = [
        _quantise(means, lo, hi, 65535).astype("<u2"),
        _quantise(log_scales, np.full(3, s0), np.full(3, s1), 255).astype(np.uint8),
        _quantise(colors, c0, c1, 255).astype(np.uint8),
        np.rint(np.clip(opacities, 0, 1) * 255).astype(np.uint8),
        np.rint(np.clip(q, -1, 1) * 127).astype(np.int8),
    ]
    data = b"".join(np.ascontiguousarray(p).tobytes() for p in parts)
    return EncodedSplats(n, data, lo.tolist(), hi.tolist(), s0, s1, c0.tolist(), c1.tolist())


def map_splats(run_dir: Path) -> tuple[EncodedSplats, Any] | None:
    """The run's ``map.ply`` quantised in display colours, and its :class:`MapSource`, or
    ``None`` when the run folder holds no map.

    The colours are the ones ``egs-bench export-map`` writes (the run's camera response,
    :func:`~egs_bench.slam.map_export.display_colors`); without the run's appearance file they
    follow the file's colour space as ``render-map`` shows them (linear ones sRGB-encoded).
    """
    import torch

    from egs_bench.color import linear_to_srgb
    from egs_bench.slam.appearance import MAP_FILE
    from egs_bench.slam.map_export import color_space, display_colors, open_map

    if not (run_dir / MAP_FILE).is_file():
        return None
    src = open_map(run_dir)
    gmap = src.gmap
    with torch.no_grad():
        if src.appearance is not None:
            colors = display_colors(gmap, src.appearance).cpu().numpy()
        elif color_space(src) == "linear":
            colors = linear_to_srgb(gmap.colors.detach().cpu().numpy())
        else:
            colors = gmap.colors.detach().cpu().numpy()
        encoded = encode_splats(gmap.means.cpu().numpy(), gmap.rotations.cpu().numpy(),
                                gmap.log_scales.cpu().numpy(), gmap.opacities.cpu().numpy(),
                                colors)
    return encoded, src


def _rows(poses: np.ndarray) -> list[list[float]]:
    """[N, 4, 4] poses as JSON rows of 16 row-major values."""
    return [[round(float(v), 6) for v in p.reshape(16)] for p in np.asarray(poses)]


def _points(xyz: np.ndarray) -> list[list[float]]:
    """[N, 3] positions as JSON rows, rounded to 10 micrometres."""
    return [[round(float(v), 5) for v in p] for p in np.asarray(xyz).reshape(-1, 3)]


def run_view(record: RunRecord, sources: RunSources, store: AssetStore) -> dict[str, Any] | None:
    """The data of a run page's 3D view, or ``None`` for a run without a trajectory.

    Frames are the trajectory's poses (frame indices from the run's appearance file when it
    has one, else one pose per frame from frame 0, as ``render-map --frame`` reads them).
    """
    from egs_bench.errors import EgsBenchError, reraise_interruption
    from egs_bench.runs.folder import RunFolder
    from egs_bench.slam.map_export import frame_pose

    if record.result.status in ("broken", "failed", "running", "interrupted"):
        return None
    path = record.result.path
    run = RunFolder.open(path)
    try:
        traj = run.read_trajectory()
        opened = map_splats(path)
    except Exception as exc:  # a view is optional: the page says why it is missing
        reraise_interruption(exc)
        text = str(exc) if isinstance(exc, EgsBenchError) else f"{path}: {exc}"
        sources.notes.setdefault(str(path), []).append(f"no 3D view: {text}")
        return None
    seq = sources.sequence(record)
    encoded, src = opened if opened is not None else (None, None)
    app = src.appearance if src is not None else None
    if src is not None and app is not None:
        indices = [int(f) for f in app.frames]
        poses = np.stack([frame_pose(src, f) for f in indices])
        cam, near = app.camera, float(app.near_plane)
    else:
        indices, poses = list(range(len(traj))), np.asarray(traj.poses)
        cam, near = (seq.intrinsics if seq is not None else None), 0.01
    if cam is None:
        return None
    if not np.isfinite(poses).all():
        sources.notes.setdefault(str(path), []).append(
            f"no 3D view: {run.trajectory_path} holds non-finite poses")
        return None
    frames: list[dict[str, Any]] = [{"index": f, "pose": p} for f, p in zip(indices, _rows(poses),
                                                                            strict=True)]
    _attach_images(frames, run, seq, sources, store)
    position = {f: k for k, f in enumerate(indices)}
    data: dict[str, Any] = {
        "kind": "run", "root": "../",
        "camera": {"width": cam.width, "height": cam.height, "fx": cam.fx, "fy": cam.fy,
                   "cx": cam.cx, "cy": cam.cy, "near": near},
        "frames": frames, "est": _points(poses[:, :3, 3]),
        "keyframes": [position[k] for k in record.keyframes if k in position],
        "map": encoded.to_json() if encoded is not None else None,
    }
    ate = sources.ate(record)
    if ate is not None:
        # x_aligned = s R x + t  <=>  x = R^T (x_aligned - t) / s
        gt = (ate.gt_positions - ate.translation) @ ate.rotation / ate.scale
        data["gt"] = _points(gt)
    return data


def _attach_images(frames: list[dict[str, Any]], run: Any, seq: Any, sources: RunSources,
                   store: AssetStore) -> None:
    """Observed, render and sharp images of up to :data:`MAX_IMAGE_FRAMES` rendered frames;
    every frame names the nearest of them in ``images_from`` (its own position when it has
    them)."""
    rendered = set(run.render_indices())
    have = [k for k, f in enumerate(frames) if f["index"] in rendered]
    if len(have) > MAX_IMAGE_FRAMES:
        pick = np.unique(np.linspace(0, len(have) - 1, MAX_IMAGE_FRAMES).round().astype(int))
        have = [have[i] for i in pick]
    sharp = sources.protocol.reference_images == "sharp"
    for k in have:
        f = frames[k]
        f["render"] = store.image(run.read_render(f["index"]))
        if seq is not None and 0 <= f["index"] < len(seq):
            f["observed"] = store.image(seq.rgb(f["index"]))
            ref = seq.sharp(f["index"]) if sharp else None
            if ref is not None:
                f["sharp"] = store.image(ref)
    if not have:
        return
    stored = np.asarray(have)
    for k, f in enumerate(frames):
        f["images_from"] = int(stored[np.argmin(np.abs(stored - k))])


def sequence_view(records: list[RunRecord], labels: list[str], sources: RunSources
                  ) -> dict[str, Any] | None:
    """The data of a sequence page's 3D view: each run's aligned estimate (``labels`` name
    them) and the ground truth, in the ground truth's frame; ``None`` when no run has an
    ATE."""
    runs, gt = [], None
    for record, label in zip(records, labels, strict=True):
        ate = sources.ate(record)
        if ate is None:
            continue
        runs.append({"label": label, "est": _points(ate.est_positions)})
        seq = sources.sequence(record)
        if gt is None:
            gt = np.asarray(seq.poses)[:, :3, 3] if seq is not None else ate.gt_positions
    if not runs:
        return None
    return {"kind": "sequence", "runs": runs,
            "gt": _points(gt) if gt is not None else []}


def write_view_script(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as the classic script ``window.EGS_VIEW = {...};`` at ``path``."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    path.write_text(f"window.EGS_VIEW = {text};\n", encoding="utf-8")
