"""Public entry point: :func:`rasterize`, mirroring ``gsplat.rasterization`` (v1.5.3)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import torch

from egs_bench.render import constants as RC
from egs_bench.render.projection import project_gaussians
from egs_bench.render.work import active, book

Backend = Literal["auto", "numba", "reference", "gsplat"]


@dataclass
class RasterResult:
    """Renders of C cameras (H x W pixels) of N Gaussians.

    Attributes:
        rgb: [C, H, W, 3] linear RGB, ``sum_i w_i c_i + T_final * background``.
        depth: [C, H, W] accumulated depth ``sum_i w_i z_i`` (m, camera z; MonoGS's depth,
            gsplat's "D"). Not normalised: it shrinks where alpha < 1.
        expected_depth: [C, H, W] ``depth / alpha`` (m; 0 where alpha is ~0), differentiable
            through both: scaling every opacity of a pixel leaves it unchanged, so a loss on it
            only moves weight between Gaussians at different depths. (With alpha detached, a
            too-long depth lowered every opacity and eroded SLAM maps into holes.)
        alpha: [C, H, W] accumulated opacity ``1 - T_final`` (differentiable, as gsplat's
            ``render_alphas``; detach it when using it as a weight or a mask).
        visibility: [C, N] bool, True where the Gaussian contributed to at least one pixel
            while the transmittance right after it was above 0.5 (MonoGS's "touched"); None
            when not requested (``visibility=False``): on gsplat it costs a second pass.
        radii: [C, N] int32 screen radius in pixels (``ceil`` of the larger half extent of
            the ``alpha >= 1/255`` box), 0 where culled or off the image.
        means2d: [C, N, 2] projected centres in pixels (differentiable; call
            ``retain_grad()`` before ``backward`` for densification statistics).
        depths: [C, N] camera-frame z of every Gaussian (m).
    """

    rgb: torch.Tensor
    depth: torch.Tensor
    expected_depth: torch.Tensor
    alpha: torch.Tensor
    visibility: torch.Tensor | None
    radii: torch.Tensor
    means2d: torch.Tensor
    depths: torch.Tensor


def _check_inputs(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    viewmats: torch.Tensor,
    Ks: torch.Tensor,
    width: int,
    height: int,
) -> None:
    n = means.shape[0]
    expect = {
        "means": (means, (n, 3)),
        "quats": (quats, (n, 4)),
        "scales": (scales, (n, 3)),
        "opacities": (opacities, (n,)),
        "colors": (colors, (n, 3)),
    }
    for name, (t, shape) in expect.items():
        if tuple(t.shape) != shape:
            raise ValueError(f"rasterize: {name} has shape {tuple(t.shape)}, expected {shape}")
    if viewmats.dim() != 3 or viewmats.shape[1:] != (4, 4):
        raise ValueError(f"rasterize: viewmats has shape {tuple(viewmats.shape)}, need [C,4,4]")
    if Ks.shape != (viewmats.shape[0], 3, 3):
        raise ValueError(
            f"rasterize: Ks has shape {tuple(Ks.shape)}, need [{viewmats.shape[0]},3,3]"
        )
    if width <= 0 or height <= 0:
        raise ValueError(f"rasterize: image size {width}x{height} must be positive")
    dtypes = {t.dtype for t in (means, quats, scales, opacities, colors, viewmats)}
    if len(dtypes) != 1 or next(iter(dtypes)) not in (torch.float32, torch.float64):
        raise ValueError(
            "rasterize: means, quats, scales, opacities, colors and viewmats must share one "
            f"float32/float64 dtype, got {sorted(str(d) for d in dtypes)}"
        )


def resolve_backend(backend: Backend, device: torch.device) -> str:
    """The concrete backend name for ``backend`` on ``device`` ("auto": CUDA -> gsplat,
    CPU -> numba)."""
    if backend == "auto":
        return "gsplat" if device.type == "cuda" else "numba"
    if backend not in ("numba", "reference", "gsplat"):
        raise ValueError(
            f"rasterize: unknown backend {backend!r} (auto, numba, reference, gsplat)"
        )
    return backend


def rasterize(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    viewmats: torch.Tensor,
    Ks: torch.Tensor,  # gsplat's name
    width: int,
    height: int,
    near_plane: float = RC.NEAR_PLANE,
    far_plane: float = RC.FAR_PLANE,
    backgrounds: torch.Tensor | None = None,
    backend: Backend = "auto",
    visibility: bool = True,
    eps2d: float = RC.EPS2D,
) -> RasterResult:
    """Render N 3-D Gaussians into C pinhole cameras, differentiably.

    The arguments mirror ``gsplat.rasterization`` (v1.5.3) with ``render_mode="RGB+D"``,
    ``rasterize_mode="classic"`` and ``packed=False``. Gradients flow to
    ``means``, ``quats``, ``scales``, ``opacities``, ``colors``, ``viewmats`` and
    ``backgrounds`` (not ``Ks``). The per-pixel rule is in :mod:`egs_bench.render.constants`.

    Args:
        means: [N, 3] world positions (m).
        quats: [N, 4] rotations ``(w, x, y, z)``; need not be normalised.
        scales: [N, 3] activated standard deviations (m), e.g. ``exp(log_scales)``.
        opacities: [N] activated opacities in (0, 1), e.g. ``sigmoid(logits)``.
        colors: [N, 3] linear RGB (HDR values > 1 allowed).
        viewmats: [C, 4, 4] world-to-camera transforms ``T_cw`` (OpenCV axes).
        Ks: [C, 3, 3] intrinsics ``[[fx,0,cx],[0,fy,cy],[0,0,1]]``; pixel ``u`` has its centre
            at ``u + 0.5`` and a point projects to ``u = fx X / Z + cx``.
        width, height: image size in pixels.
        near_plane, far_plane: Gaussians with camera ``z <= near_plane`` or ``>= far_plane``
            are culled (m). MonoGS uses ``near_plane=0.2``.
        backgrounds: [C, 3] colour behind the Gaussians, or None (black).
        backend: "auto" (CUDA tensors -> "gsplat", CPU -> "numba"), "numba" (CPU tile
            kernels), "reference" (dense PyTorch oracle, tiny images only) or "gsplat".
        visibility: return which Gaussians each camera "touched" (keyframe decisions need
            it; the optimisation loops pass False: on gsplat it is a second pass).
        eps2d: pixels^2 added to every 2-D covariance (gsplat's low-pass dilation, 0.3 by
            default); an image rendered at ``s`` x the resolution keeps the same dilation in
            scene units with ``0.3 s^2``.

    Returns:
        A :class:`RasterResult`.

    Example:
        >>> import torch
        >>> from egs_bench.render import rasterize
        >>> means = torch.tensor([[0.0, 0.0, 2.0]])
        >>> out = rasterize(means, torch.tensor([[1.0, 0, 0, 0]]), torch.full((1, 3), 0.1),
        ...                 torch.tensor([0.9]), torch.tensor([[1.0, 0.5, 0.2]]),
        ...                 torch.eye(4)[None], torch.tensor([[[50.0, 0, 16], [0, 50, 12],
        ...                 [0, 0, 1]]]), 32, 24, backend="reference")
        >>> out.rgb.shape, bool(out.visibility[0, 0])
        (torch.Size([1, 24, 32, 3]), True)
    """
    _check_inputs(means, quats, scales, opacities, colors, viewmats, Ks, width, height)
    name = resolve_backend(backend, means.device)
    C = viewmats.shape[0]
    book(active(), calls=1, cameras=C, pixels=C * width * height,
         blends_counted=name == "numba")
    if name == "gsplat":
        from egs_bench.render.gsplat_backend import rasterize_gsplat

        rgb, depth, alpha, vis, radii, means2d, depths = rasterize_gsplat(
            means, quats, scales, opacities, colors, viewmats, Ks, width, height,
            near_plane, far_plane, visibility, eps2d,
        )
    else:
        # reference: the PyTorch statement of the projection; numba: its fused kernels
        if name == "reference":
            project = project_gaussians
        else:
            from egs_bench.render.numba_projection import project_gaussians_fused as project
        proj = project(
            means, quats, scales, opacities, viewmats, Ks, width, height, near_plane, far_plane,
            eps2d,
        )
        if name == "reference":
            from egs_bench.render.reference import composite_dense

            rgb, depth, alpha, vis = composite_dense(proj, opacities, colors, width, height)
        else:
            from egs_bench.render.numba_backend import composite_tiles

            rgb, depth, alpha, vis = composite_tiles(proj, opacities, colors, width, height)
        radii, means2d, depths = proj.radii, proj.means2d, proj.depths
        vis = vis if visibility else None
    if backgrounds is not None:
        if backgrounds.shape != (viewmats.shape[0], 3):
            raise ValueError(
                f"rasterize: backgrounds has shape {tuple(backgrounds.shape)}, "
                f"need [{viewmats.shape[0]},3]"
            )
        rgb = rgb + (1 - alpha)[..., None] * backgrounds[:, None, None, :].to(rgb.dtype)
    # alpha is kept in the graph; the clamp bounds the gradient 1/alpha^2 at nearly empty pixels
    expected = torch.where(alpha > 1e-10, depth / alpha.clamp(min=1e-4), torch.zeros_like(depth))
    return RasterResult(rgb, depth, expected, alpha, vis, radii, means2d, depths)
