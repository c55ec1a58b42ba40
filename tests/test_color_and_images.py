"""The colour module (one sRGB, luma and quantisation rule for numpy and torch) and the image
I/O module (one codec; 8-bit colour and 16-bit depth checked on read)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from egs_bench.color import (
    LdrResponse,
    from_uint8,
    linear_to_srgb,
    linear_to_srgb8,
    luma,
    srgb_to_linear,
    to_uint8,
)
from egs_bench.errors import InputError
from egs_bench.images import (
    image_size,
    read_depth_png,
    read_ldr_image,
    write_depth_png,
    write_ldr_image,
)


def test_srgb_reference_points_and_roundtrip() -> None:
    # IEC 61966-2-1: encoded 0.04045 <-> linear 0.0031308; encoded 0.5 -> linear 0.214041
    assert float(srgb_to_linear(np.array(0.04045))) == pytest.approx(0.0031308, abs=1e-7)
    assert float(srgb_to_linear(np.array(0.5))) == pytest.approx(0.214041, abs=1e-6)
    assert float(linear_to_srgb(np.array(1.0))) == pytest.approx(1.0, abs=1e-12)
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-12)
    # out-of-range inputs are clipped, not extrapolated
    np.testing.assert_allclose(linear_to_srgb(np.array([-1.0, 2.0])), [0.0, 1.0], atol=1e-15)


def test_numpy_and_torch_give_the_same_values_and_dtypes() -> None:
    rng = np.random.default_rng(0)
    x = rng.random((5, 7, 3)).astype(np.float32)
    t = torch.from_numpy(x)
    for fn in (srgb_to_linear, linear_to_srgb, luma):
        a, b = fn(x), fn(t)
        assert isinstance(b, torch.Tensor) and a.dtype == np.float32 and b.dtype == torch.float32
        np.testing.assert_allclose(a, b.numpy(), rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(to_uint8(x), to_uint8(t).numpy())
    assert srgb_to_linear(x.astype(np.float64)).dtype == np.float64  # float dtype kept
    np.testing.assert_allclose(luma(np.array([1.0, 0.0, 0.0])), 0.299)
    np.testing.assert_allclose(luma(np.array([0.2, 0.5, 0.8])),
                               0.299 * 0.2 + 0.587 * 0.5 + 0.114 * 0.8)


def test_linear_to_srgb_has_a_finite_gradient_at_black() -> None:
    x = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    linear_to_srgb(x).sum().backward()
    assert x.grad is not None
    assert torch.isfinite(x.grad).all() and float(x.grad[0]) == pytest.approx(12.92)


def test_quantisation_rounds_half_to_even_and_clips() -> None:
    # 0.5 / 255 and 1.5 / 255 are ties: to even gives 0 and 2 (+0.5 truncation would give 1, 2)
    values = np.array([0.5, 1.5, 2.5, 254.5]) / 255.0
    np.testing.assert_array_equal(to_uint8(values), [0, 2, 2, 254])
    np.testing.assert_array_equal(to_uint8(np.array([-0.3, 1.7])), [0, 255])
    np.testing.assert_array_equal(to_uint8(torch.tensor(values)).numpy(), [0, 2, 2, 254])
    img = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(to_uint8(from_uint8(img)), img)
    # linear 0.5 -> sRGB 0.735357 -> 187.52 -> 188
    np.testing.assert_array_equal(linear_to_srgb8(np.array([[0.0, 0.5, 1.0, 3.0]])),
                                  [[0, 188, 255, 255]])


def test_ldr_response_matches_the_colour_functions() -> None:
    rad = np.array([[0.1, 0.2, 0.6]], np.float32)
    response = LdrResponse(gain=2.0)
    np.testing.assert_array_equal(response.to_ldr(rad), to_uint8(linear_to_srgb(rad * 2.0)))
    np.testing.assert_allclose(response.inverse(response.to_ldr(rad))[0, :2], rad[0, :2],
                               rtol=0.02)


def test_ldr_image_roundtrip_and_refusals(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (6, 9, 3), dtype=np.uint8)
    write_ldr_image(tmp_path / "a.png", img)
    np.testing.assert_array_equal(read_ldr_image(tmp_path / "a.png"), img)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), img)  # RGB order
    assert image_size(tmp_path / "a.png") == (9, 6)
    Image.fromarray(img[:, :, 0]).save(tmp_path / "grey.png")
    np.testing.assert_array_equal(read_ldr_image(tmp_path / "grey.png"),
                                  np.repeat(img[:, :, :1], 3, axis=2))
    Image.fromarray(img[:, :, 0].astype(np.uint16) * 257).save(tmp_path / "deep.png")
    with pytest.raises(InputError, match="deep.png: expected an 8-bit image, found uint16"):
        read_ldr_image(tmp_path / "deep.png")
    (tmp_path / "junk.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(InputError, match="junk.png: cannot read image"):
        read_ldr_image(tmp_path / "junk.png")
    with pytest.raises(InputError, match="none.png: image not found"):
        read_ldr_image(tmp_path / "none.png")
    with pytest.raises(ValueError, match="uint8"):
        write_ldr_image(tmp_path / "f.png", img.astype(np.float32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "deep.png", "grey.png",
                                                          "junk.png"]


def test_depth_png_roundtrip_and_refusal(tmp_path: Path) -> None:
    raw = np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000
    write_depth_png(tmp_path / "d.png", raw)
    np.testing.assert_array_equal(read_depth_png(tmp_path / "d.png"), raw)
    write_ldr_image(tmp_path / "c.png", np.zeros((3, 4, 3), np.uint8))
    with pytest.raises(InputError, match="c.png: depth PNG must be single-channel uint16"):
        read_depth_png(tmp_path / "c.png")
