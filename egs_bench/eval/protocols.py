"""Named evaluation protocols: which frames are scored, against what, with which metric variants.

Every ``metrics.json`` records the full protocol it was computed under, so numbers from different
conventions are never mixed silently.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

from egs_bench.errors import ConfigError

# The choices of a protocol's fields. They live here, in a module without heavy imports, so
# that the metric modules and the command line share them.
AteFrames = Literal["all", "keyframes"]
Alignment = Literal["se3", "sim3", "none"]  # Umeyama SE(3), Sim(3) (with scale), none
RpeFrames = Literal["all"]
ReferenceImages = Literal["sharp", "rgb"]
PsnrVariant = Literal["masked", "full"]
SsimVariant = Literal["3dgs", "standard"]
LpipsNet = Literal["alex", "vgg"]


@dataclass(frozen=True)
class Protocol:
    """An evaluation protocol.

    Attributes:
        name: preset name.
        description: one line for tables and reports.
        ate_frames: ``"all"`` tracked frames or ``"keyframes"`` only.
        ate_alignment: ``"se3"``, ``"sim3"`` or ``"none"`` (Umeyama, evo).
        ate_max_diff_s: timestamp association tolerance, seconds (ATE and RPE).
        rpe_frames: poses the RPE uses: ``"all"`` estimated poses (RPE per frame and per metre,
            translation and rotation, no alignment; :func:`egs_bench.eval.rpe.standard_rpe`).
        render_stride: score renders of frames ``0, stride, 2 stride, ...``.
        render_skip_keyframes: leave keyframes out of the rendering evaluation.
        reference_images: ``"sharp"`` (sharp ground truth at exposure end) or ``"rgb"`` (the
            observed, possibly blurred, frames: what MonoGS' evaluation loads).
        psnr: ``"masked"`` (MonoGS: elements with reference > 0) or ``"full"``.
        ssim: ``"3dgs"`` (zero padding) or ``"standard"`` (Wang / scikit-image).
        lpips_net: ``"alex"`` or ``"vgg"``; inputs in [0, 1].
    """

    name: str
    description: str
    ate_frames: AteFrames = "all"
    ate_alignment: Alignment = "se3"
    ate_max_diff_s: float = 0.01
    rpe_frames: RpeFrames = "all"
    render_stride: int = 5
    render_skip_keyframes: bool = False
    reference_images: ReferenceImages = "sharp"
    psnr: PsnrVariant = "masked"
    ssim: SsimVariant = "3dgs"
    lpips_net: LpipsNet = "alex"

    def to_dict(self) -> dict[str, Any]:
        """Plain dict for ``metrics.json``."""
        return asdict(self)


PROTOCOLS: dict[str, Protocol] = {
    "egs": Protocol(
        name="egs",
        description="ATE on all frames; every 5th frame rendered and compared with the sharp GT",
        ate_frames="all",
        render_skip_keyframes=False,
        reference_images="sharp",
    ),
    "monogs": Protocol(
        name="monogs",
        description="MonoGS: ATE on keyframes; every 5th non-keyframe compared with the observed "
                    "frame",
        ate_frames="keyframes",
        render_skip_keyframes=True,
        reference_images="rgb",
    ),
}
DEFAULT_PROTOCOL = "egs"


def get_protocol(name: str) -> Protocol:
    """The protocol preset called ``name``.

    Raises:
        ConfigError: unknown name (the message lists the known ones).
    """
    if not isinstance(name, str) or name not in PROTOCOLS:  # a YAML list is not hashable
        raise ConfigError(f"unknown protocol {name!r}; choose one of "
                          f"{', '.join(sorted(PROTOCOLS))}")
    return PROTOCOLS[name]
