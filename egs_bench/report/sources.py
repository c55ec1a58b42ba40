"""What several pages of a report read: the runs' sequences and ATE results, each computed
once per report. A sequence or trajectory that cannot be read gives a note for the pages that
needed it, never an exception."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from egs_bench.errors import EgsBenchError, reraise_interruption
from egs_bench.eval.ate import AteResult
from egs_bench.eval.protocols import get_protocol
from egs_bench.eval.results import EVALUATED
from egs_bench.report.collect import RunRecord


class RunSources:
    """Sequences by folder and ATE results by run folder, under one protocol.

    Attributes:
        protocol: the protocol whose ATE settings are used.
        notes: run folder or sequence folder (as text) -> lines on what could not be read.
    """

    def __init__(self, protocol: str) -> None:
        self.protocol = get_protocol(protocol)
        self.notes: dict[str, list[str]] = {}
        self._sequences: dict[Path, Any] = {}
        self._ates: dict[Path, AteResult | None] = {}

    def _note(self, where: Path, exc: BaseException) -> None:
        reraise_interruption(exc)
        text = str(exc) if isinstance(exc, EgsBenchError) else f"{where}: {exc}"
        self.notes.setdefault(str(where), []).append(text)

    def sequence_path(self, record: RunRecord) -> Path | None:
        seq = record.info.get("sequence")
        path = seq.get("path") if isinstance(seq, dict) else None
        return Path(path) if isinstance(path, str) and path else None

    def sequence(self, record: RunRecord) -> Any:
        """The run's :class:`~egs_bench.datasets.sequence.Sequence`, or ``None`` when it has
        none or it cannot be opened (noted under the sequence folder)."""
        from egs_bench.eval.evaluate import open_sequence

        path = self.sequence_path(record)
        if path is None:
            return None
        if path not in self._sequences:
            try:
                self._sequences[path] = open_sequence(path)
            except Exception as exc:
                self._note(path, exc)
                self._sequences[path] = None
        return self._sequences[path]

    def ate(self, record: RunRecord) -> AteResult | None:
        """The run's ATE (aligned positions, per-pose errors) for an evaluated run, else
        ``None`` (and a note when it could not be computed)."""
        from egs_bench.eval.evaluate import compute_run_ate
        from egs_bench.runs.folder import RunFolder

        path = record.result.path
        if record.result.status not in EVALUATED:
            return None
        if path not in self._ates:
            try:
                self._ates[path] = compute_run_ate(RunFolder.open(path), self.protocol,
                                                   self.sequence(record))
            except Exception as exc:
                self._note(path, exc)
                self._ates[path] = None
        return self._ates[path]
