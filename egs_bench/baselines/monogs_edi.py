"""``monogs-edi``: the MonoGS-style baseline run on EDI-deblurred frames (paper Table VI).

Every observed frame is replaced by its EDI latent image at the exposure end
(:mod:`egs_bench.baselines.edi`, threshold chosen per frame by the energy search), then the
built-in ``monogs`` configuration runs unchanged. The SLAM system sees a read-only view of the
sequence (:class:`EdiSequence`) whose ``rgb(i)`` is the deblurred frame; depth, poses, events
and the exposure windows are the original ones, and the run folder points at the original
sequence, so evaluation compares with the same ground truth as every other method.

The deblurring runs inside the SLAM loop (each frame is read once, when it is tracked), so the
run's FPS includes it. The run folder additionally holds the EDI settings (``config.yaml``,
key ``edi``) and ``edi_frames.csv`` (per frame: chosen ``c``, energy, events, seconds).
"""

from __future__ import annotations

import csv
import io
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from egs_bench.baselines.edi import EdiConfig, EdiResult
from egs_bench.runs.registry import register_builtin
from egs_bench.slam.methods import BUILTIN, ConfiguredSlamMethod

if TYPE_CHECKING:
    import numpy as np

    from egs_bench.datasets.sequence import Sequence
    from egs_bench.runs.folder import RunFolder

EDI_FRAMES_FILE = "edi_frames.csv"


class EdiSequence:
    """Read-only view of a sequence whose observed frames are EDI-deblurred: a
    :class:`~egs_bench.datasets.sequence_view.SequenceView`.

    Everything except :meth:`rgb` is the wrapped sequence's. Deblurred frames are computed on
    first access and kept in a small LRU cache (the SLAM reads each frame once; evaluation
    reads the original sequence, not this view).

    Args:
        seq: an opened sequence with events.
        config: EDI settings.
        cache_frames: how many deblurred frames to keep in memory.
    """

    def __init__(self, seq: Sequence, config: EdiConfig | None = None,
                 cache_frames: int = 16) -> None:
        from egs_bench.errors import InputError

        if not seq.has_events:
            raise InputError(seq.path, "monogs-edi needs events (EDI deblurs frames with the "
                                       "events of their exposure); this sequence has none")
        self._seq = seq
        self.edi_config = config or EdiConfig()
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._cache_frames = max(1, int(cache_frames))
        self.results: dict[int, EdiResult] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self._seq, name)

    def __len__(self) -> int:
        return len(self._seq)

    def __repr__(self) -> str:
        return f"EdiSequence({self._seq!r})"

    def rgb(self, i: int) -> np.ndarray:
        """EDI latent image at the exposure end of frame ``i``: uint8 [H, W, 3], sRGB."""
        from egs_bench.baselines.edi import deblur_sequence_frame

        i = int(i)
        if i in self._cache:
            self._cache.move_to_end(i)
            return self._cache[i].copy()
        image, result = deblur_sequence_frame(self._seq, i, self.edi_config)
        self.results[i] = result
        self._cache[i] = image
        if len(self._cache) > self._cache_frames:
            self._cache.popitem(last=False)
        return image.copy()

    def frames_csv(self) -> str:
        """Per-frame EDI statistics as CSV text (``index, c, energy, events, seconds``)."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["index", "c", "energy", "events", "seconds"])
        for i in sorted(self.results):
            r = self.results[i]
            writer.writerow([i, "" if r.c is None else f"{r.c:.6f}",
                             "" if r.energy is None else f"{r.energy:.6f}", r.n_events,
                             f"{r.seconds:.4f}"])
        return buf.getvalue()


@dataclass
class MonoGsEdiMethod(ConfiguredSlamMethod):
    """The ``monogs`` configuration on EDI-deblurred frames (see the module docstring)."""

    edi: EdiConfig = field(default_factory=EdiConfig)

    def run(self, sequence: Sequence, out: Path, *, preset: str = "paper", device: str = "cpu",
            seed: int = 0, max_frames: int | None = None, progress: bool = True,
            overwrite: bool = False) -> RunFolder:
        """Deblur each frame with EDI as the SLAM reads it, run ``monogs`` (with the method's
        ``options``, as for the built-in methods)."""
        from egs_bench.fileio import write_text_atomic
        from egs_bench.runs.folder import RUN_FILE, RunFolder
        from egs_bench.slam.runner import RunSettings, run_slam

        config = self.config(preset)
        view = EdiSequence(sequence, self.edi)
        run_file = Path(out) / RUN_FILE
        before = run_file.read_bytes() if run_file.is_file() else None
        try:
            # the view is a SequenceView: the sequence's data (delegation), EDI images from rgb()
            return run_slam(view, out, method_name=self.name, config=config,
                            settings=RunSettings(preset, device, seed, max_frames, progress,
                                                 overwrite),
                            components=self.components)
        finally:
            # only a run folder this call created (a refused --out is someone else's run)
            if run_file.is_file() and run_file.read_bytes() != before:
                run = RunFolder.open(out)
                resolved = run.read_config()
                resolved["edi"] = {**self.edi.to_dict(),
                                   "reference_time": "exposure end",
                                   "method": "EDI (Pan et al. 2019), exact double integral"}
                run.write_config(resolved)
                write_text_atomic(run.artifact_path(EDI_FRAMES_FILE), view.frames_csv())


MONOGS_EDI = MonoGsEdiMethod(
    "monogs-edi",
    "MonoGS-style baseline on EDI-deblurred frames (Pan et al. 2019, c chosen per frame)",
    dict(BUILTIN["monogs"].overrides),
)
register_builtin(MONOGS_EDI)
