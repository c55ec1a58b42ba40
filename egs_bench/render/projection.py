"""EWA projection of 3-D Gaussians into C pinhole cameras, in plain PyTorch.

Autograd through :func:`project_gaussians` gives the gradients with respect to the 3-D
parameters *and* the 4x4 world-to-camera matrices, given the gradients with respect to the 2-D
quantities that the compositing kernels consume. Written from the math (Zwicker et al., EWA
splatting; Kerbl et al., 3DGS), in gsplat's conventions (pixel ``u`` has its centre at
``u + 0.5``; ``u = fx X / Z + cx``).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from egs_bench.render import constants as RC


@dataclass
class Projected:
    """Screen-space Gaussians for C cameras and N Gaussians.

    Attributes:
        means2d: [C, N, 2] pixel coordinates of the projected centres (differentiable).
        conics: [C, N, 3] ``(a, b, c)``, the inverse of the dilated 2-D covariance
            ``[[a, b], [b, c]]^-1 = Sigma_2d + EPS2D I`` (differentiable).
        depths: [C, N] camera-frame ``z`` in metres (differentiable).
        valid: [C, N] bool, inside ``(near, far)`` with a finite positive-definite conic.
        extents: [C, N, 2] half-widths in pixels (x, y) of the box outside which
            ``alpha < ALPHA_MIN`` for sure; ``-1`` where culled (not differentiated).
        radii: [C, N] int32, ``ceil(max(extents))`` for Gaussians whose box overlaps the image,
            else 0.
    """

    means2d: torch.Tensor
    conics: torch.Tensor
    depths: torch.Tensor
    valid: torch.Tensor
    extents: torch.Tensor
    radii: torch.Tensor


def quat_to_rotmat(quats: torch.Tensor) -> torch.Tensor:
    """Rotation matrices [..., 3, 3] from quaternions [..., 4] ``(w, x, y, z)`` of any norm."""
    q = F.normalize(quats, dim=-1)
    w, x, y, z = q.unbind(-1)
    rot = torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        -1,
    )
    return rot.reshape(q.shape[:-1] + (3, 3))


def covariances_3d(quats: torch.Tensor, scales: torch.Tensor) -> torch.Tensor:
    """World-frame covariances [N, 3, 3] = R S S^T R^T from quats [N, 4] and scales [N, 3] (m)."""
    m = quat_to_rotmat(quats) * scales[:, None, :]
    return m @ m.transpose(-1, -2)


def project_gaussians(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    viewmats: torch.Tensor,
    Ks: torch.Tensor,  # gsplat's name
    width: int,
    height: int,
    near_plane: float = RC.NEAR_PLANE,
    far_plane: float = RC.FAR_PLANE,
    eps2d: float = RC.EPS2D,
) -> Projected:
    """Project N Gaussians into C cameras.

    Args:
        means: [N, 3] world positions (m).
        quats: [N, 4] rotations ``(w, x, y, z)``, any norm.
        scales: [N, 3] standard deviations along the local axes (m), activated.
        opacities: [N] in (0, 1), activated (used only for the culling extents).
        viewmats: [C, 4, 4] world-to-camera transforms (OpenCV axes).
        Ks: [C, 3, 3] pinhole intrinsics (pixels).
        width, height: image size (pixels).
        near_plane, far_plane: camera-``z`` culling range (m).
    """
    rot_wc = viewmats[:, :3, :3]  # [C,3,3] world->camera rotation
    t_wc = viewmats[:, :3, 3]
    # Broadcast products and 3-term sums rather than einsum: a batched GEMM blocks its sums
    # differently for different C, and a camera rendered alone must match the same camera in a
    # batch bit for bit (measured: einsum differed by up to 4e-6 px between C=1 and C=12).
    pc = (rot_wc[:, None, :, :] * means[None, :, None, :]).sum(-1) + t_wc[:, None, :]  # [C,N,3]
    x, y, z = pc.unbind(-1)
    in_range = (z > near_plane) & (z < far_plane)
    zs = torch.where(in_range, z, torch.ones_like(z))

    fx = Ks[:, 0, 0, None].to(means.dtype)
    fy = Ks[:, 1, 1, None].to(means.dtype)
    cx = Ks[:, 0, 2, None].to(means.dtype)
    cy = Ks[:, 1, 2, None].to(means.dtype)

    # Jacobian of the pinhole map at x/z, y/z clamped slightly beyond the image (3DGS/gsplat):
    # far off-screen Gaussians would otherwise get huge, meaningless footprints.
    tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
    lim_xp = (width - cx) / fx + RC.FOV_CLAMP * tan_x
    lim_xn = cx / fx + RC.FOV_CLAMP * tan_x
    lim_yp = (height - cy) / fy + RC.FOV_CLAMP * tan_y
    lim_yn = cy / fy + RC.FOV_CLAMP * tan_y
    tx = torch.minimum(torch.maximum(x / zs, -lim_xn), lim_xp)
    ty = torch.minimum(torch.maximum(y / zs, -lim_yn), lim_yp)
    j00, j02 = fx / zs, -fx * tx / zs
    j11, j12 = fy / zs, -fy * ty / zs

    # Sigma_2d = (J R) M M^T (J R)^T with M = R_q diag(s): with V = J R M ([C,N,2,3]) it is
    # V V^T, which avoids forming the [C,N,3,3] camera covariances (fewer, larger tensor ops).
    m_w = quat_to_rotmat(quats) * scales[:, None, :]  # [N,3,3]
    r0, r1, r2 = (rot_wc[:, None, i, :] for i in range(3))  # [C,1,3] rows of R
    jr = torch.stack([j00[..., None] * r0 + j02[..., None] * r2,
                      j11[..., None] * r1 + j12[..., None] * r2], -2)  # [C,N,2,3]
    v = (jr[..., :, :, None] * m_w[None, :, None, :, :]).sum(-2)  # [C,N,2,3]
    v0, v1 = v.unbind(-2)
    a2 = (v0 * v0).sum(-1) + eps2d
    b2 = (v0 * v1).sum(-1)
    c2 = (v1 * v1).sum(-1) + eps2d
    det = a2 * c2 - b2 * b2
    valid = in_range & (det > 0) & torch.isfinite(det)
    det_s = torch.where(valid, det, torch.ones_like(det))
    conics = torch.stack([c2 / det_s, -b2 / det_s, a2 / det_s], -1)
    means2d = torch.stack([fx * x / zs + cx, fy * y / zs + cy], -1)

    with torch.no_grad():
        extents, radii = _extents(means2d, a2, c2, opacities, valid, width, height)
    return Projected(means2d, conics, z, valid, extents, radii)


def _extents(
    means2d: torch.Tensor,
    a2: torch.Tensor,
    c2: torch.Tensor,
    opacities: torch.Tensor,
    valid: torch.Tensor,
    width: int,
    height: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-axis half extents [C,N,2] of the ``alpha >= ALPHA_MIN`` region and radii [C,N].

    ``alpha >= ALPHA_MIN`` needs ``d^T Sigma^-1 d <= 2 ln(opacity / ALPHA_MIN)``, and
    ``d^T Sigma^-1 d >= dx^2 / Sigma_xx``, so ``|dx| <= sqrt(2 ln(o / ALPHA_MIN) Sigma_xx)`` is
    exact (the box is the ellipse's bounding box). A relative margin of 1e-3 keeps float32
    rounding from dropping a boundary pixel that the dense reference would draw.
    """
    m2 = 2.0 * torch.log((opacities / RC.ALPHA_MIN).clamp(min=1.0))[None, :]
    ext = torch.stack([torch.sqrt(m2 * a2), torch.sqrt(m2 * c2)], -1) * (1.0 + 1e-3) + 1e-3
    cull = (~valid) | (m2 <= 0) | ~torch.isfinite(ext).all(-1)
    ext = torch.where(cull[..., None], torch.full_like(ext, -1.0), ext)
    lo = means2d - ext
    hi = means2d + ext
    on_image = (hi[..., 0] > 0) & (lo[..., 0] < width) & (hi[..., 1] > 0) & (lo[..., 1] < height)
    seen = (~cull) & on_image
    radii = torch.where(seen, torch.ceil(ext.amax(-1)), torch.zeros_like(ext[..., 0]))
    return ext, radii.clamp(max=float(2**31 - 1)).to(torch.int32)


def log_opacity_margin(opacities: torch.Tensor) -> torch.Tensor:
    """``2 ln(opacity / ALPHA_MIN)`` [N] (0 where opacity <= ALPHA_MIN): the largest Mahalanobis
    distance squared at which a Gaussian still reaches ``ALPHA_MIN``."""
    return 2.0 * torch.log((opacities / RC.ALPHA_MIN).clamp(min=1.0))

