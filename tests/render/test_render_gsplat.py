"""gsplat (CUDA) backend parity with the CPU backend; skipped without gsplat and a CUDA GPU."""

from __future__ import annotations

import pytest
import torch

from egs_bench.errors import ConfigError
from egs_bench.render import rasterize
from tests.helpers.render_scenes import leaf_copy, random_scene

HAVE_CUDA = torch.cuda.is_available()


def test_gsplat_backend_rejects_cpu_tensors_or_missing_package() -> None:
    """Without gsplat installed, asking for it is a user-fixable ConfigError; with it, CPU
    tensors are a programming error (ValueError, as CUDA tensors are in the numba backend)."""
    import importlib.util

    scene = random_scene(n=10, c=1, dtype=torch.float32)
    if importlib.util.find_spec("gsplat") is None:
        with pytest.raises(ConfigError, match=r"backend 'gsplat' needs gsplat 1.5.3"):
            rasterize(**scene, backend="gsplat")
    else:
        with pytest.raises(ValueError, match="backend 'gsplat' needs CUDA tensors"):
            rasterize(**scene, backend="gsplat")


@pytest.mark.cuda
@pytest.mark.skipif(not HAVE_CUDA, reason="needs a CUDA GPU")
def test_gsplat_matches_numba_forward_and_gradients() -> None:
    pytest.importorskip("gsplat")
    # Moderate opacities: gsplat clamps alpha at 0.999 instead of 0.99, so keep o*G < 0.99.
    scene = random_scene(n=300, c=3, seed=1, dtype=torch.float32, opacity_scale=0.9)
    cpu = leaf_copy(scene)
    gpu = leaf_copy({k: v.cuda() if torch.is_tensor(v) else v for k, v in scene.items()})
    out_c = rasterize(**cpu, backend="numba")
    out_g = rasterize(**gpu, backend="gsplat")
    for f in ("rgb", "depth", "alpha"):
        torch.testing.assert_close(getattr(out_g, f).cpu(), getattr(out_c, f), atol=2e-4,
                                   rtol=1e-3)
    assert out_g.visibility is not None and out_c.visibility is not None
    agree = (out_g.visibility.cpu() == out_c.visibility).float().mean()
    assert agree > 0.995
    cot = torch.randn_like(out_c.rgb)
    (out_c.rgb * cot).sum().backward()
    (out_g.rgb * cot.cuda()).sum().backward()
    for k in ("means", "quats", "scales", "opacities", "colors", "viewmats"):
        g_c, g_g = cpu[k].grad, gpu[k].grad.cpu()
        assert (g_g - g_c).norm() / g_c.norm() < 1e-3, k
