"""What the camera / settings files of external systems share.

Every external system reads its intrinsics from a configuration file, not from the data
folder; each system's module (:mod:`egs_bench.interop.monogs`, ...) writes its own file with
these helpers.

**Pixel convention.** egs-bench stores gsplat's convention (pixel ``u`` has its centre at
``u + 0.5``); OpenCV, ORB-SLAM, MonoGS/3DGS and Replica put it at the integer ``u``. The files
therefore hold ``cx - 0.5`` and ``cy - 0.5`` (:func:`opencv_camera`).

The ORB parameters (ORB-SLAM2, and ORB-SLAM3 in Photo-SLAM) are those of ORB-SLAM2's
``TUM1.yaml``; ``Camera.bf`` / ``Stereo.b`` (the virtual baseline of RGB-D ORB-SLAM) is 0.08 m,
so with ``ThDepth: 40`` points up to 3.2 m count as close (TUM1: 40 / 517.3 m x 40 = 3.1 m).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from egs_bench.geometry import Intrinsics
from egs_bench.interop.systems import CameraFileRequest

ORB_BASELINE_M = 0.08
ORB_TH_DEPTH = 40.0
_HEADER = "# Written by egs-bench export for sequence {name!r} ({w}x{h}); pixel centres at " \
          "integer coordinates (egs-bench's cx, cy minus 0.5).\n"


def opencv_camera(intr: Intrinsics) -> Intrinsics:
    """The same camera in the OpenCV convention (pixel centre at integer ``u``): ``cx - 0.5``,
    ``cy - 0.5``; egs-bench's :class:`Intrinsics` put it at ``u + 0.5``."""
    return replace(intr, cx=float(intr.cx) - 0.5, cy=float(intr.cy) - 0.5)


def opencv_real(v: float) -> str:
    """A number OpenCV's FileStorage parses as a real (always with a decimal point)."""
    text = repr(float(v))
    return text if ("." in text or "e" in text or "inf" in text or "nan" in text) else text + ".0"


def frame_rate(fps: float) -> float:
    """The frame rate to 3 decimals (Hz): frame periods are whole microseconds, so 30 Hz comes
    out as 30.00030000299998, which ORB-SLAM2 uses only as a frame count."""
    return round(float(fps), 3)


def file_header(cam: Intrinsics, name: str) -> str:
    return _HEADER.format(name=name, w=cam.width, h=cam.height)


#: where an external system's checkout finds an export (a folder relative to its checkout, as
#: MonoGS' and NICE-SLAM's own configs name their datasets)
CHECKOUT_ROOT = "datasets/egs_bench"


def checkout_path(export_dir: str | Path) -> str:
    """``datasets/egs_bench/<export folder name>``: the export as a system's config names it."""
    return f"{CHECKOUT_ROOT}/{Path(export_dir).name}"


def orb_settings_file(settings: Callable[..., str]) -> Callable[[CameraFileRequest], str]:
    """The camera-file writer of an ORB-SLAM settings function ``settings(cam, *, fps,
    depth_scale, name)`` (ORB-SLAM2's, ORB-SLAM3's in Photo-SLAM)."""
    def write(request: CameraFileRequest) -> str:
        return settings(request.camera, fps=request.frame_rate(),
                        depth_scale=request.depth_units(), name=request.sequence.name)
    return write


def orb_settings_text(lines: list[str]) -> str:
    """An ORB-SLAM settings file: ``lines`` (camera and depth keys), then the ORB extractor and
    viewer settings of ``TUM1.yaml``."""
    lines = lines + [
        "ORBextractor.nFeatures: 1000",
        "ORBextractor.scaleFactor: 1.2",
        "ORBextractor.nLevels: 8",
        "ORBextractor.iniThFAST: 20",
        "ORBextractor.minThFAST: 7",
        "",
        "Viewer.KeyFrameSize: 0.05",
        "Viewer.KeyFrameLineWidth: 1.0",
        "Viewer.GraphLineWidth: 0.9",
        "Viewer.PointSize: 2.0",
        "Viewer.CameraSize: 0.08",
        "Viewer.CameraLineWidth: 3.0",
        "Viewer.ViewpointX: 0.0",
        "Viewer.ViewpointY: -0.7",
        "Viewer.ViewpointZ: -1.8",
        "Viewer.ViewpointF: 500.0",
    ]
    return "\n".join(lines) + "\n"
