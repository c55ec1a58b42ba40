"""What an external SLAM system is to egs-bench: the types of the registry
(:mod:`egs_bench.interop.registry`).

An :class:`ExternalSystem` names the system (its ``--from`` key and its leaderboard title),
says how to read its output (``read``: the output as an :class:`ExternalEstimate`, before it is
mapped onto the sequence) and which camera files it needs next to each export layout it reads
(``camera_files``: layout -> :class:`CameraFile`). Each system lives in a module of its own
(``interop/monogs.py``, ``interop/orbslam2.py``, ...) that defines these and one
``SYSTEM = ExternalSystem(...)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from egs_bench.geometry import Intrinsics

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence


@dataclass
class ExternalEstimate:
    """An external system's output, before it is mapped onto the sequence.

    Attributes:
        poses: camera-to-world poses, [N, 4, 4].
        stamps_s: the system's time stamps (export time base), [N]; or None when
        uids: it identifies frames by index (MonoGS uids), [N].
        poses_kind: ``"all"`` (every processed frame), ``"keyframes"`` or ``"subset"``.
        keyframe_stamps_s / keyframe_uids: keyframes, when the system lists them separately.
        renders: render file per keyframe image name or uid (``name_or_uid -> path``).
        scale_free: monocular estimate (metric scale unknown).
        reported: the system's own metrics, kept for reference.
        sources: files read.
        ply: the system's Gaussian map, if any.
        stamps_unit_unknown: the time stamps are in an unknown unit (seconds times a power of
            ten): the import finds the one that matches the export's stamps.
        settings: how the output was read (e.g. a column order), recorded in the run's
            ``config.yaml``.
        written_at_end: the output is a file the system writes once it has read its whole
            input (at shutdown): a keyframe-only estimate then counts every frame the system
            read as processed, not only those up to the last keyframe.
    """

    poses: np.ndarray
    stamps_s: np.ndarray | None = None
    uids: np.ndarray | None = None
    poses_kind: str = "all"
    keyframe_stamps_s: np.ndarray | None = None
    keyframe_uids: np.ndarray | None = None
    renders: dict[str | int, Path] = field(default_factory=dict)
    scale_free: bool = False
    reported: dict[str, Any] = field(default_factory=dict)
    sources: list[str] = field(default_factory=list)
    ply: Path | None = None
    stamps_unit_unknown: bool = False
    settings: dict[str, Any] = field(default_factory=dict)
    written_at_end: bool = False


@dataclass(frozen=True)
class ImportOptions:
    """Options of an import that only some systems read.

    Attributes:
        quaternion: RampVO's quaternion columns, ``"rampvo"`` (as its code writes them) or
            ``"wxyz"``.
    """

    quaternion: str = "rampvo"


@dataclass(frozen=True)
class CameraFileRequest:
    """What a system's camera file is written from, for one export.

    Attributes:
        camera: the intrinsics in the OpenCV pixel convention
            (:func:`egs_bench.interop.camera_files.opencv_camera`).
        sequence: the exported sequence.
        frames: how many of its frames the export holds.
        layout: the export layout (``tum-rgbd``, ``replica``, ``eds``).
        dataset_path: the export as the system's checkout names it
            (:func:`egs_bench.interop.camera_files.checkout_path`).
        depth_scale: depth PNG units per metre of the layout (None: it holds no depth).
        fps: the frame rate of the exported time stamps, Hz (None: the layout's frames carry
            no time stamps, or a system does not read them).
    """

    camera: Intrinsics
    sequence: Sequence
    frames: int
    layout: str
    dataset_path: str
    depth_scale: float | None = None
    fps: float | None = None

    def depth_units(self) -> float:
        """:attr:`depth_scale`, for a system that reads depth (a layout without depth has no
        such system)."""
        if self.depth_scale is None:
            raise ValueError(f"the {self.layout} layout holds no depth")
        return self.depth_scale

    def frame_rate(self) -> float:
        """:attr:`fps`, for a system that reads it."""
        if self.fps is None:
            raise ValueError(f"the {self.layout} export has no frame rate")
        return self.fps


class CameraFile(NamedTuple):
    """A file a system reads next to an export: its name in the export folder and its writer."""

    name: str
    write: Callable[[CameraFileRequest], str]


@dataclass(frozen=True)
class ExternalSystem:
    """One external SLAM system.

    Attributes:
        key: its name in egs-bench: ``import-run --from KEY`` and its entry in an export's
            list of camera files.
        title: its name on leaderboards (the method of an imported run).
        read: reads its output (a file or folder) into an :class:`ExternalEstimate`; None for
            a system egs-bench only exports to.
        camera_files: per export layout it reads, the camera file it needs.
        loaded_frames: for a system whose output names frames by uid: the export frames it
            loads, which the uids index (``(export layout, export time stamps [N] s) ->
            indices``); None: every frame.
        output: what ``import-run SOURCE`` takes as its output (files or a folder), as the
            ``--from`` help lists it; empty: the help shows the key alone.
        gaussian_map: the Gaussian map (3DGS ``.ply``) its output folder may hold, as a path
            in that folder, which ``--render-ply`` renders at the imported poses (its reader
            sets :attr:`ExternalEstimate.ply` when it is there); None: it writes none.
    """

    key: str
    title: str
    read: Callable[[Path, ImportOptions], ExternalEstimate] | None = None
    camera_files: Mapping[str, CameraFile] = field(default_factory=dict)
    loaded_frames: Callable[[str | None, np.ndarray], np.ndarray] | None = None
    output: str = ""
    gaussian_map: str | None = None
