"""EventReplica generator: blurred E-RGB-D sequences from RGB-D + pose data (Replica, TUM RGB-D
or a generic layout).

Pipeline (paper §V.A, with an offline interpolator instead of FILM): read the scene
(:mod:`egs_bench.datasets.replica`), decode sRGB to linear light, resize + centre-crop with
consistent intrinsics (:class:`ResizeCrop`), upsample in time between strided frames
(:class:`DepthWarpInterpolator` or :class:`FlowInterpolator` behind :class:`FrameInterpolator`)
inside a :class:`ReplicaSource`, and hand that source to the shared generation pipeline
(adaptive sampling, ESIM events, blur, camera response, canonical writer).
"""

from egs_bench.datasets.eventreplica.generate import (
    exposure_windows,
    make_eventreplica,
    make_eventreplica_scenes,
)
from egs_bench.datasets.eventreplica.interpolate import (
    INTERPOLATORS,
    DepthWarpInterpolator,
    FlowInterpolator,
    FrameInterpolator,
    KeyFrame,
    PairInterpolator,
    make_interpolator,
)
from egs_bench.datasets.eventreplica.resize import ResizeCrop
from egs_bench.datasets.eventreplica.source import ReplicaSource
from egs_bench.datasets.replica import export_replica_layout, read_replica
from egs_bench.datasets.rgbd_layouts import RGBDInput, read_generic_rgbd, read_tum_rgbd

__all__ = [
    "INTERPOLATORS",
    "DepthWarpInterpolator",
    "FlowInterpolator",
    "FrameInterpolator",
    "KeyFrame",
    "PairInterpolator",
    "RGBDInput",
    "ReplicaSource",
    "ResizeCrop",
    "exposure_windows",
    "export_replica_layout",
    "make_eventreplica",
    "make_eventreplica_scenes",
    "make_interpolator",
    "read_generic_rgbd",
    "read_replica",
    "read_tum_rgbd",
]
