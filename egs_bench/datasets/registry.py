"""Resolve a sequence name or path to a sequence folder; built-in names are generated on demand.

``--seq`` accepts a path to a sequence folder, or a name looked up under the data root
(``$EGS_BENCH_DATA``, default ``./data``). Names of built-in synthetic sequences that are not
there yet are generated into the data root on first use (deterministic: same name, same data).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from egs_bench.errors import InputError

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence


@dataclass(frozen=True)
class BuiltinSequence:
    """Settings of a built-in synthetic sequence (arguments of ``make_synthetic``)."""

    scene: str
    description: str
    frames: int = 100
    width: int = 448
    height: int = 256
    fps: float = 30.0
    exposure_ms: float = 20.0
    speed: float = 1.0
    seed: int = 0


BUILTIN_SEQUENCES: dict[str, BuiltinSequence] = {
    "office1": BuiltinSequence("office", "office, hand-held motion, strong blur", speed=0.75,
                               seed=1),
    "office2": BuiltinSequence("office", "office, faster motion, very strong blur", speed=1.5,
                               seed=2),
    "livingroom1": BuiltinSequence("livingroom", "living room, strong blur", speed=0.75, seed=3),
    "studio1": BuiltinSequence("studio", "studio with bright lamps, strong blur", speed=0.75,
                               seed=4),
    "corridor1": BuiltinSequence("corridor", "corridor, strong blur", speed=0.75, seed=5),
    "office1-sharp": BuiltinSequence("office", "office1's motion with a 1 ms exposure (no blur)",
                                     speed=0.75, seed=1, exposure_ms=1.0),
    "demo": BuiltinSequence("office", "short low-resolution blurred sequence for `make demo`",
                            frames=40, width=224, height=128, speed=0.4, seed=7,
                            exposure_ms=25.0),
    # small variants (224x128, 40 frames, ~2-3 cm and <1 deg per frame, 25 ms exposure) for
    # CPU accuracy benchmarks
    "demo-sharp": BuiltinSequence("office", "demo's motion with a 1 ms exposure (no blur)",
                                  frames=40, width=224, height=128, speed=0.4, seed=7,
                                  exposure_ms=1.0),
    "livingroom-s": BuiltinSequence("livingroom", "small living room sequence, blurred",
                                    frames=40, width=224, height=128, speed=0.4, seed=8,
                                    exposure_ms=25.0),
    "studio-s": BuiltinSequence("studio", "small studio sequence, blurred", frames=40,
                                width=224, height=128, speed=0.4, seed=9, exposure_ms=25.0),
    "corridor-s": BuiltinSequence("corridor", "small corridor sequence, blurred", frames=40,
                                  width=224, height=128, speed=0.4, seed=10, exposure_ms=25.0),
    # demo's room three times faster: ~4 cm and 2.5 deg (up to 5.5 deg) per frame, rotational
    # blur ~4 px on average and up to ~8 px at 224x128 (the sequences above: ~1.5, up to 2.4)
    "demo-fast": BuiltinSequence("office", "demo's room with 3x faster motion (strong blur)",
                                 frames=40, width=224, height=128, speed=1.2, seed=7,
                                 exposure_ms=25.0),
    "livingroom-fast": BuiltinSequence("livingroom", "livingroom-s's motion 3x faster (strong "
                                       "blur)", frames=40, width=224, height=128, speed=1.2,
                                       seed=8, exposure_ms=25.0),
    "studio-fast": BuiltinSequence("studio", "studio-s's motion 3x faster (strong blur)",
                                   frames=40, width=224, height=128, speed=1.2, seed=9,
                                   exposure_ms=25.0),
    # `make demo`: demo-fast's room and motion, 24 frames, so that both methods run at the
    # sequence's own resolution within the demo's 5 minutes on 2 cores
    "demo-blur": BuiltinSequence("office", "short strongly blurred sequence for `make demo`",
                                 frames=24, width=224, height=128, speed=1.2, seed=7,
                                 exposure_ms=25.0),
    # Paper scale (EventReplica: 448x256, hundreds of frames): 300 frames = 10 s at 30 Hz,
    # strong hand-held blur (speed 1 with a 25 ms exposure: ~5 px mean motion per exposure at
    # 448 px), one per scene, and an unblurred twin of the first.
    "office-l": BuiltinSequence("office", "paper scale: office, 300 frames, strong blur",
                                frames=300, speed=1.0, seed=11, exposure_ms=25.0),
    "livingroom-l": BuiltinSequence("livingroom", "paper scale: living room, 300 frames, "
                                    "strong blur", frames=300, speed=1.0, seed=12,
                                    exposure_ms=25.0),
    "studio-l": BuiltinSequence("studio", "paper scale: studio, 300 frames, strong blur",
                                frames=300, speed=1.0, seed=13, exposure_ms=25.0),
    "corridor-l": BuiltinSequence("corridor", "paper scale: corridor, 300 frames, strong blur",
                                  frames=300, speed=1.0, seed=14, exposure_ms=25.0),
    "office-l-sharp": BuiltinSequence("office", "office-l's motion with a 1 ms exposure (no "
                                      "blur)", frames=300, speed=1.0, seed=11, exposure_ms=1.0),
}

PAPER_SCALE_SEQUENCES = ("office-l", "livingroom-l", "studio-l", "corridor-l")
PAPER_SCALE_UNBLURRED = "office-l-sharp"


def data_root() -> Path:
    """The folder named sequences live in: ``$EGS_BENCH_DATA`` or ``./data``."""
    return Path(os.environ.get("EGS_BENCH_DATA", "data"))


def resolve_sequence(name_or_path: str | Path, root: Path | None = None, generate: bool = True,
                     progress: bool = True) -> Path:
    """Return the sequence folder for a path or a name (generating built-in names on demand).

    Raises:
        InputError: neither an existing folder nor a known name.
    """
    candidate = Path(name_or_path)
    if candidate.is_dir():
        return candidate
    root = root or data_root()
    named = root / str(name_or_path)
    if named.is_dir():
        return named
    spec = BUILTIN_SEQUENCES.get(str(name_or_path))
    if spec is None:
        known = ", ".join(BUILTIN_SEQUENCES)
        raise InputError(candidate, f"no such sequence folder, and not a name under {root} "
                                    f"or a built-in sequence ({known})")
    if not generate:
        raise InputError(named, "built-in sequence not generated yet")
    from egs_bench.datasets.synthetic import make_synthetic

    settings = asdict(spec)
    settings.pop("description")
    return make_synthetic(out=named, progress=progress, **settings)


def load_sequence(name_or_path: str | Path, progress: bool = True) -> Sequence:
    """Open the sequence :func:`resolve_sequence` finds (generating built-in names on demand)."""
    from egs_bench.datasets.sequence import Sequence

    return Sequence.open(resolve_sequence(name_or_path, progress=progress))
