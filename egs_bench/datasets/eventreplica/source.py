"""``ReplicaSource``: a time-continuous latent RGB-D source built from a Replica-layout scene.

Strided frame ``j`` (original frame ``first + j * stride``) sits at ``t_j = round(j * 1e6 / fps)``
microseconds. At those times :meth:`ReplicaSource.render` returns the original frame (sRGB
decoded to linear light, resized and cropped) and its depth exactly; in between it asks the
interpolator for the view at fraction ``alpha = (t - t_j) / (t_{j+1} - t_j)`` and the pose is
slerp/lerp between the neighbours' poses (the constant-velocity model of EGS-SLAM's exposure
trajectory). It satisfies :class:`egs_bench.datasets.pipeline.LatentSource`.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from egs_bench.color import srgb_to_linear
from egs_bench.datasets.eventreplica.interpolate import (
    DepthWarpInterpolator,
    FrameInterpolator,
    KeyFrame,
    PairInterpolator,
)
from egs_bench.datasets.eventreplica.resize import ResizeCrop
from egs_bench.datasets.pipeline import DEFAULT_DEPTH_SCALE, LatentFrame
from egs_bench.datasets.replica import ReplicaScene
from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Intrinsics, interpolate_pose


class ReplicaSource:
    """Latent source over a Replica-layout scene (see the module docstring).

    Args:
        scene: an opened scene (:func:`egs_bench.datasets.replica.read_replica`).
        fps: rate of the *strided* frames (Hz).
        stride: use every ``stride``-th original frame.
        first: first original frame to use.
        num_frames: number of strided frames to use (default: all that remain).
        geometry: resize + crop applied to every frame.
        interpolator: in-between view synthesis (default: depth-based forward warping).
        cache_size: key frames kept decoded in memory.

    Attributes:
        intrinsics: output intrinsics (egs-bench convention).
        frame_indices: [M] original frame index of each strided frame.
        key_times_us: [M] int64 time of each strided frame.
    """

    def __init__(
        self,
        scene: ReplicaScene,
        *,
        fps: float,
        stride: int = 1,
        first: int = 0,
        num_frames: int | None = None,
        geometry: ResizeCrop | None = None,
        interpolator: FrameInterpolator | None = None,
        cache_size: int = 4,
    ) -> None:
        if not (np.isfinite(fps) and fps > 0):
            raise ConfigError(f"fps must be a positive number, got {fps}")
        if stride < 1 or first < 0:
            raise ConfigError(f"stride must be >= 1 and first >= 0 (got {stride}, {first})")
        indices = np.arange(first, len(scene), stride)
        if num_frames is not None:
            indices = indices[:num_frames]
        if len(indices) < 2:
            raise ConfigError(
                f"{scene.path}: need at least 2 frames after first={first}, stride={stride}"
                f"{'' if num_frames is None else f', num_frames={num_frames}'} "
                f"(the scene has {len(scene)})"
            )
        self.scene = scene
        self.geometry = geometry or ResizeCrop()
        self.interpolator = interpolator or DepthWarpInterpolator()
        self.intrinsics: Intrinsics = self.geometry.intrinsics(scene.intrinsics)
        self.frame_indices = indices
        self.key_times_us = np.round(np.arange(len(indices)) * (1e6 / fps)).astype(np.int64)
        self.key_poses = scene.poses[indices]
        self._frames: OrderedDict[int, KeyFrame] = OrderedDict()
        self._cache_size = max(2, cache_size)
        self._pair: tuple[int, PairInterpolator] | None = None

    def __len__(self) -> int:
        return len(self.frame_indices)

    def key_frame(self, j: int) -> KeyFrame:
        """Strided frame ``j``: linear colour [H, W, 3], depth [H, W] (m), pose [4, 4]."""
        if j in self._frames:
            self._frames.move_to_end(j)
            return self._frames[j]
        idx = int(self.frame_indices[j])
        src = self.scene.intrinsics
        linear = srgb_to_linear(self.scene.rgb(idx).astype(np.float32) / 255.0)
        depth = self.scene.depth(idx)
        frame = KeyFrame(
            rgb=self.geometry.rgb(linear, src),
            depth=self._usable_depth(self.geometry.depth(depth, src), depth, idx),
            pose=self.key_poses[j].copy(),
        )
        self._frames[j] = frame
        while len(self._frames) > self._cache_size:
            self._frames.popitem(last=False)
        return frame

    def _usable_depth(self, depth: np.ndarray, source: np.ndarray, idx: int) -> np.ndarray:
        """``depth`` (the output frame's, metres) when the output can keep some of it.

        A frame whose depth the sequence cannot store (all zero, or all beyond the 16-bit
        range of its PNGs: a ``depth_scale`` off by a factor of 1000 gives kilometres) would
        be written as a frame without depth, on which SLAM cannot start or map.

        Raises:
            InputError: naming the input depth file and what its values are.
        """
        far = 65535.0 / DEFAULT_DEPTH_SCALE
        if ((depth > 0) & (depth <= far)).any():
            return depth
        path = self.scene.depth_paths[idx]
        valid = source[source > 0]
        if valid.size == 0:
            raise InputError(path, "holds no depth: every pixel is 0 (invalid)")
        if (valid > far).all():
            raise InputError(path, f"every depth is beyond the {far:g} m a sequence stores "
                                   f"({valid.min():.6g} to {valid.max():.6g} m at depth_scale "
                                   f"{self.scene.depth_scale:g} per metre): is the depth "
                                   "scale right?")
        raise InputError(path, "holds no valid depth inside the output crop")

    def _locate(self, t_us: int) -> tuple[int, float]:
        """Segment index ``j`` and fraction ``alpha`` in [0, 1) of ``t_us`` (``alpha = 0`` at
        key times; the last key time maps to the last frame with ``alpha = 0``)."""
        times = self.key_times_us
        if t_us < times[0] or t_us > times[-1]:
            raise ValueError(f"time {t_us} us outside [{times[0]}, {times[-1]}]")
        j = int(np.searchsorted(times, t_us, side="right")) - 1
        if j == len(times) - 1:
            return j, 0.0
        return j, (t_us - times[j]) / float(times[j + 1] - times[j])

    def pose(self, t_us: int) -> np.ndarray:
        """Camera-to-world pose [4, 4] at ``t_us`` (slerp/lerp between strided frames)."""
        j, alpha = self._locate(int(t_us))
        if alpha == 0.0:
            return self.key_poses[j].copy()
        return interpolate_pose(self.key_poses[j], self.key_poses[j + 1], alpha)

    def render(self, t_us: int) -> LatentFrame:
        """Latent frame at ``t_us``: the original frame at key times, interpolated between."""
        j, alpha = self._locate(int(t_us))
        if alpha == 0.0:
            key = self.key_frame(j)
            return LatentFrame(rgb=key.rgb.copy(), depth=key.depth.copy(), pose=key.pose.copy())
        if self._pair is None or self._pair[0] != j:
            self._pair = (j, self.interpolator.prepare(
                self.key_frame(j), self.key_frame(j + 1), self.intrinsics))
        rgb, depth = self._pair[1](alpha)
        pose = interpolate_pose(self.key_poses[j], self.key_poses[j + 1], alpha)
        return LatentFrame(rgb=rgb, depth=depth, pose=pose)
