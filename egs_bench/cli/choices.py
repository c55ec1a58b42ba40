"""The fixed choices of command-line options, as ``Literal`` types: typer lists them in the help
(``<se3|sim3|none>``) and refuses anything else as a usage error naming the option.

The evaluation protocol's choices are the library's own types (:mod:`egs_bench.eval.protocols`
imports nothing heavy); each other one mirrors a constant of a library module that the CLI does
not import before a command runs. The library still checks its own arguments for Python
callers; ``tests/cli/test_cli_edges.py`` checks that the two agree. ``import-run --from`` is
not here: its choices are the systems of :mod:`egs_bench.interop.registry`, built-in or
registered, read when the command runs (``cli/eval_cmds.py``).
"""

from __future__ import annotations

from typing import Literal

from egs_bench.eval.protocols import Alignment as Alignment  # light: no numpy, no evo
from egs_bench.eval.protocols import LpipsNet as LpipsNet

Protocol = Literal["egs", "monogs"]  # eval.protocols.PROTOCOLS
SlamPreset = Literal["auto", "paper", "cpu"]  # "auto" + slam.config.PRESETS
PoseRelation = Literal["trans_part", "angle_deg", "angle_rad", "rot_part", "full",
                       "point_distance"]  # eval.rpe.RELATIONS
DeltaUnit = Literal["f", "frames", "m", "meters", "d", "deg", "degrees", "r", "rad",
                    "radians"]  # eval.rpe.DELTA_UNITS
BoardFormat = Literal["md", "latex", "csv", "csv-summary"]  # eval.leaderboard.FORMATS
BoardLayout = Literal["sequence", "method"]  # eval.leaderboard.LAYOUTS
TableWidth = Literal["auto", "natural", "column", "page"]  # eval.tables.WIDTHS
QuaternionOrder = Literal["rampvo", "wxyz"]  # interop.rampvo.QUATERNION_ORDERS
ExportFormat = Literal["tum-rgbd", "replica", "eds"]  # interop.export.FORMATS
Retime = Literal["auto", "never", "always"]
MapColors = Literal["auto", "linear", "display"]
MapBackend = Literal["auto", "numba", "gsplat"]
SweepBackend = Literal["local", "slurm"]  # experiments.sweep.BACKENDS
SubmititCluster = Literal["slurm", "local", "debug"]
Interpolator = Literal["depth", "flow"]  # datasets.eventreplica.interpolate.INTERPOLATORS
RgbdLayout = Literal["replica", "tum-rgbd", "generic"]  # datasets.rgbd_layouts.LAYOUTS
TimesUnit = Literal["us", "ms", "s", "ns"]
FrameStamp = Literal["start", "mid", "end"]
ListWhat = Literal["methods", "scenes"]
FigureKind = Literal["trajectories", "qualitative"]
EnslamFrames = Literal["rgbd", "davis"]  # recordings.enslam.FRAME_SOURCES
