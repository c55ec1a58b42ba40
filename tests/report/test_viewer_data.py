"""The 3D view's map layout (egs_bench.report.viewer.encode_splats): every value decodes back
to within half a quantisation step, at the byte offsets the viewer's script reads."""

from __future__ import annotations

import base64

import numpy as np

from egs_bench.report.viewer import SPLAT_BYTES, encode_splats


def _decode(enc: dict) -> dict[str, np.ndarray]:
    """What viewer_src/src/viewer.js (packSplats) reads, restated with numpy."""
    raw = base64.b64decode(enc["data"])
    n = enc["count"]
    lo, hi = np.array(enc["bbox_min"]), np.array(enc["bbox_max"])
    c0, c1 = np.array(enc["color_min"]), np.array(enc["color_max"])
    s0, s1 = enc["ln_scale_min"], enc["ln_scale_max"]
    pos = np.frombuffer(raw, "<u2", 3 * n, 0).reshape(n, 3) / 65535 * (hi - lo) + lo
    scl = np.frombuffer(raw, np.uint8, 3 * n, 6 * n).reshape(n, 3) / 255 * (s1 - s0) + s0
    col = np.frombuffer(raw, np.uint8, 3 * n, 9 * n).reshape(n, 3) / 255 * (c1 - c0) + c0
    opa = np.frombuffer(raw, np.uint8, n, 12 * n) / 255
    rot = np.frombuffer(raw, np.int8, 4 * n, 13 * n).reshape(n, 4) / 127
    return {"means": pos, "log_scales": scl, "colors": col, "opacities": opa, "rotations": rot}


def test_encoded_map_decodes_within_half_a_step() -> None:
    rng = np.random.default_rng(3)
    n = 1000
    means = rng.uniform(-2.0, 5.0, (n, 3))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    log_scales = rng.uniform(-6.0, -1.0, (n, 3))
    opacities = rng.uniform(0.0, 1.0, n)
    colors = rng.uniform(-0.1, 1.7, (n, 3))  # display colours may leave [0, 1]
    enc = encode_splats(means, q, log_scales, opacities, colors)
    assert enc.count == n and len(enc.data) == SPLAT_BYTES * n
    got = _decode(enc.to_json())
    span = means.max(0) - means.min(0)
    assert (np.abs(got["means"] - means).max(0) <= span / 65535 / 2 + 1e-9).all()
    sspan = log_scales.max() - log_scales.min()
    assert np.abs(got["log_scales"] - log_scales).max() <= sspan / 255 / 2 + 1e-9
    cspan = colors.max(0) - colors.min(0)
    assert (np.abs(got["colors"] - colors).max(0) <= cspan / 255 / 2 + 1e-9).all()
    assert np.abs(got["opacities"] - opacities).max() <= 0.5 / 255 + 1e-9
    assert np.abs(got["rotations"] - q).max() <= 0.5 / 127 + 1e-9


def test_empty_map() -> None:
    enc = encode_splats(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0),
                        np.zeros((0, 3)))
    assert enc.count == 0 and enc.data == b""


def test_gaussians_that_cannot_be_drawn_are_left_out() -> None:
    means = np.array([[0.0, 0, 0], [np.nan, 0, 0], [1, 1, 1], [2, 2, 2]])
    q = np.array([[1.0, 0, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0], [0, 1, 0, 0]])
    enc = encode_splats(means, q, np.full((4, 3), -3.0), np.full(4, 0.5), np.full((4, 3), 0.5))
    assert enc.count == 2 and enc.bbox_min == [0.0] * 3 and enc.bbox_max == [2.0] * 3
