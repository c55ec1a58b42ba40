"""The Gaussian map: raw (optimisable) parameters, activations, insertion from depth, pruning."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import torch
import torch.nn.functional as F
from scipy.spatial import cKDTree

from egs_bench.geometry import Intrinsics

if TYPE_CHECKING:
    from egs_bench.render.rasterize import RasterResult

PARAM_NAMES = ("means", "quats", "log_scales", "opacity_logits", "colors")


@dataclass
class GaussianMap:
    """N 3-D Gaussians with linear (HDR) RGB colour and no spherical harmonics.

    The raw tensors are what an optimiser updates; the activated values are what
    :func:`egs_bench.render.rasterize` takes.

    Attributes:
        means: [N, 3] world positions (m).
        quats: [N, 4] rotations ``(w, x, y, z)``, not necessarily normalised.
        log_scales: [N, 3] log standard deviations (log m); activation ``exp``.
        opacity_logits: [N]; activation ``sigmoid``.
        colors: [N, 3] linear RGB, used as is (no activation; may exceed 1).
        keyframe_ids: [N] int64 id of the keyframe that created each Gaussian (-1: none).
    """

    means: torch.Tensor
    quats: torch.Tensor
    log_scales: torch.Tensor
    opacity_logits: torch.Tensor
    colors: torch.Tensor
    keyframe_ids: torch.Tensor = field(default_factory=lambda: torch.zeros(0, dtype=torch.int64))

    def __post_init__(self) -> None:
        n = self.means.shape[0]
        if self.keyframe_ids.numel() == 0 and n > 0:
            self.keyframe_ids = torch.full((n,), -1, dtype=torch.int64)
        shapes = {"means": (n, 3), "quats": (n, 4), "log_scales": (n, 3),
                  "opacity_logits": (n,), "colors": (n, 3), "keyframe_ids": (n,)}
        for name, shape in shapes.items():
            if tuple(getattr(self, name).shape) != shape:
                raise ValueError(
                    f"GaussianMap.{name} has shape {tuple(getattr(self, name).shape)}, "
                    f"expected {shape}"
                )

    # ---------------------------------------------------------------- construction
    @classmethod
    def empty(cls, dtype: torch.dtype = torch.float32, device: str | torch.device = "cpu"
              ) -> GaussianMap:
        """A map with no Gaussians."""
        def z(*s: int) -> torch.Tensor:
            return torch.zeros(*s, dtype=dtype, device=device)
        return cls(z(0, 3), z(0, 4), z(0, 3), z(0), z(0, 3),
                   torch.zeros(0, dtype=torch.int64, device=device))

    def __len__(self) -> int:
        return int(self.means.shape[0])

    @property
    def dtype(self) -> torch.dtype:
        return self.means.dtype

    @property
    def device(self) -> torch.device:
        return self.means.device

    # ---------------------------------------------------------------- activations
    @property
    def scales(self) -> torch.Tensor:
        """[N, 3] standard deviations (m) = ``exp(log_scales)``."""
        return torch.exp(self.log_scales)

    @property
    def opacities(self) -> torch.Tensor:
        """[N] opacities in (0, 1) = ``sigmoid(opacity_logits)``."""
        return torch.sigmoid(self.opacity_logits)

    @property
    def rotations(self) -> torch.Tensor:
        """[N, 4] unit quaternions ``(w, x, y, z)``."""
        return F.normalize(self.quats, dim=-1)

    def parameters(self) -> dict[str, torch.Tensor]:
        """The raw optimisable tensors by name (``PARAM_NAMES``)."""
        return {name: getattr(self, name) for name in PARAM_NAMES}

    def requires_grad_(self, flag: bool = True) -> GaussianMap:
        """Make the raw tensors leaf tensors that do (or do not) require grad; returns self."""
        for name in PARAM_NAMES:
            setattr(self, name, getattr(self, name).detach().requires_grad_(flag))
        return self

    def render(
        self,
        viewmats: torch.Tensor,
        Ks: torch.Tensor,
        width: int,
        height: int,
        **kwargs: object,
    ) -> RasterResult:
        """``rasterize`` this map into cameras ``viewmats`` [C,4,4] (world-to-camera) with
        intrinsics ``Ks`` [C,3,3]; ``kwargs`` go to :func:`egs_bench.render.rasterize`."""
        from egs_bench.render.rasterize import rasterize

        return rasterize(self.means, self.quats, self.scales, self.opacities, self.colors,
                         viewmats, Ks, width, height, **kwargs)  # type: ignore[arg-type]

    def frozen(self) -> FrozenGaussians:
        """The activated parameters, detached: for loops that render a fixed map many times
        (tracking), so the activations are computed once rather than per call."""
        return FrozenGaussians(self.means.detach(), self.quats.detach(),
                               self.scales.detach(), self.opacities.detach(),
                               self.colors.detach())

    def to(self, device: str | torch.device | None = None, dtype: torch.dtype | None = None
           ) -> GaussianMap:
        """A detached copy on ``device`` with float tensors in ``dtype`` (ids stay int64)."""
        def conv(t: torch.Tensor) -> torch.Tensor:
            return t.detach().to(device=device, dtype=dtype).clone()
        params = {n: conv(getattr(self, n)) for n in PARAM_NAMES}
        return GaussianMap(**params, keyframe_ids=self.keyframe_ids.detach().to(device=device)
                           .clone())

    def clone(self) -> GaussianMap:
        """A detached copy."""
        return self.to()

    # ---------------------------------------------------------------- editing
    def append(self, other: GaussianMap) -> None:
        """Append the Gaussians of ``other`` (new tensors; rebuild optimiser state after)."""
        for name in (*PARAM_NAMES, "keyframe_ids"):
            a, b = getattr(self, name), getattr(other, name)
            setattr(self, name, torch.cat([a.detach(), b.detach().to(a.device, a.dtype)], 0))

    def prune(self, remove: torch.Tensor) -> int:
        """Remove the Gaussians where ``remove`` [N] bool is True; returns how many were removed.

        The raw tensors are replaced by new (detached) ones, so an optimiser holding the old
        tensors must be rebuilt or have its state indexed with ``~remove``.
        """
        if remove.shape != (len(self),) or remove.dtype != torch.bool:
            raise ValueError(f"prune mask must be bool [{len(self)}], got "
                             f"{remove.dtype} {tuple(remove.shape)}")
        keep = ~remove.to(self.device)
        for name in (*PARAM_NAMES, "keyframe_ids"):
            setattr(self, name, getattr(self, name).detach()[keep])
        return int(remove.sum())

    def add_from_depth(
        self,
        rgb: np.ndarray | torch.Tensor,
        depth: np.ndarray | torch.Tensor,
        intrinsics: Intrinsics,
        T_wc: np.ndarray,
        downsample: int = 64,
        point_size: float = 0.05,
        opacity: float = 0.5,
        keyframe_id: int = -1,
        generator: torch.Generator | None = None,
    ) -> int:
        """Add Gaussians back-projected from a depth image, MonoGS-style.

        Valid pixels (``depth > 0``) are back-projected through their centres (``u + 0.5``)
        with ``intrinsics`` and moved to the world with ``T_wc``; a random ``1/downsample`` of
        them is kept (MonoGS: 32 for the first frame, 64 for later keyframes on Replica). Each new
        Gaussian is isotropic with variance ``point_size * d2``, ``d2`` = mean squared distance
        to its 3 nearest neighbours among the *new* points (clamped at 1e-7 m^2), identity
        rotation, the given opacity and the pixel's colour.

        Args:
            rgb: [H, W, 3] linear RGB (float; uint8 is rejected to avoid sRGB mix-ups).
            depth: [H, W] metres, 0 = invalid.
            intrinsics: camera of the images (pixel centres at ``u + 0.5``).
            T_wc: [4, 4] camera-to-world pose.
            downsample: keep about one valid pixel in ``downsample`` (>= 1).
            point_size: factor on the squared neighbour distance (MonoGS: 0.05).
            opacity: initial opacity in (0, 1).
            keyframe_id: stored in ``keyframe_ids``.
            generator: torch RNG for the subsampling (seed it for reproducible maps).

        Returns:
            The number of Gaussians added.
        """
        rgb_np = rgb.detach().cpu().numpy() if isinstance(rgb, torch.Tensor) else np.asarray(rgb)
        dep = depth.detach().cpu().numpy() if isinstance(depth, torch.Tensor) else np.asarray(
            depth)
        h, w = intrinsics.height, intrinsics.width
        if dep.shape != (h, w) or rgb_np.shape != (h, w, 3):
            raise ValueError(f"add_from_depth: rgb {rgb_np.shape} / depth {dep.shape} do not "
                             f"match the intrinsics' {h}x{w}")
        if not np.issubdtype(rgb_np.dtype, np.floating):
            raise ValueError("add_from_depth: rgb must be linear float RGB, not "
                             f"{rgb_np.dtype} (convert sRGB uint8 to linear first)")
        if downsample < 1 or not 0.0 < opacity < 1.0:
            raise ValueError("add_from_depth: need downsample >= 1 and 0 < opacity < 1")
        valid = np.flatnonzero((dep > 0) & np.isfinite(dep))
        n_keep = int(math.ceil(valid.size / downsample)) if valid.size else 0
        if n_keep == 0:
            return 0
        perm = torch.randperm(valid.size, generator=generator, device="cpu")[:n_keep].numpy()
        idx = np.sort(valid[perm])
        pts_cam = intrinsics.backproject(dep).reshape(-1, 3)[idx]
        pose = np.asarray(T_wc, dtype=np.float64)
        pts = pts_cam @ pose[:3, :3].T + pose[:3, 3]
        cols = rgb_np.reshape(-1, 3)[idx].astype(np.float64)

        d2 = _mean_sq_knn(pts, k=3)
        log_s = 0.5 * np.log(np.maximum(d2, 1e-7) * point_size)

        def t(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(x, dtype=self.dtype, device=self.device)

        n = idx.size
        quats = torch.zeros(n, 4, dtype=self.dtype, device=self.device)
        quats[:, 0] = 1.0
        new = GaussianMap(
            t(pts), quats, t(np.repeat(log_s[:, None], 3, axis=1)),
            torch.full((n,), math.log(opacity / (1 - opacity)), dtype=self.dtype,
                       device=self.device),
            t(cols), torch.full((n,), keyframe_id, dtype=torch.int64, device=self.device),
        )
        self.append(new)
        return n


@dataclass(frozen=True)
class FrozenGaussians:
    """Activated, detached Gaussian parameters (see :meth:`GaussianMap.frozen`); shapes as the
    arguments of :func:`egs_bench.render.rasterize`."""

    means: torch.Tensor
    quats: torch.Tensor
    scales: torch.Tensor
    opacities: torch.Tensor
    colors: torch.Tensor

    @property
    def dtype(self) -> torch.dtype:
        return self.means.dtype

    @property
    def device(self) -> torch.device:
        return self.means.device

    def render(self, viewmats: torch.Tensor, Ks: torch.Tensor, width: int,
               height: int, **kwargs: object) -> RasterResult:
        """``rasterize`` these Gaussians into cameras ``viewmats`` [C,4,4] with ``Ks``."""
        from egs_bench.render.rasterize import rasterize

        return rasterize(self.means, self.quats, self.scales, self.opacities, self.colors,
                         viewmats, Ks, width, height, **kwargs)  # type: ignore[arg-type]


def frame_map(gmap: GaussianMap, width: int, height: int) -> tuple[np.ndarray, Intrinsics]:
    """A camera-to-world pose [4,4] and intrinsics that show the whole map: axes aligned with the
    world, placed behind the map's bounding box on -z, 60 degree horizontal field of view."""
    pts = gmap.means.detach().cpu().double().numpy()
    if pts.shape[0] == 0:
        lo = hi = np.zeros(3)
    else:
        lo, hi = np.percentile(pts, 1, axis=0), np.percentile(pts, 99, axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-3)
    f = 0.5 * width / np.tan(np.radians(30))
    pose = np.eye(4)
    pose[:3, 3] = [centre[0], centre[1], lo[2] - 1.2 * half / np.tan(np.radians(30))]
    return pose, Intrinsics(f, f, width / 2, height / 2, width, height)


def _mean_sq_knn(points: np.ndarray, k: int = 3) -> np.ndarray:
    """Mean squared distance [M] from each point [M,3] to its k nearest other points (fewer
    if the cloud is smaller; 0 for a single point)."""
    m = points.shape[0]
    if m < 2:
        return np.zeros(m)
    kk = min(k, m - 1)
    dist, _ = cKDTree(points).query(points, k=kk + 1)
    return (dist[:, 1:] ** 2).mean(axis=1)


