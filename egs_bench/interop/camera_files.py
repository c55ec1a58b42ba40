"""The camera / settings files external systems need next to an exported sequence.

Every system below reads its intrinsics from a configuration file, not from the data folder:

* MonoGS: ``Dataset.Calibration`` in its YAML config (``fx fy cx cy k1 k2 p1 p2 k3 distorted
  width height depth_scale``, read by ``utils/dataset.py``), merged over a base config through
  ``inherit_from`` (a path relative to the MonoGS checkout, where ``slam.py`` runs);
* ORB-SLAM2: an OpenCV ``FileStorage`` YAML like ``Examples/RGB-D/TUM1.yaml``
  (``Camera.fx ...``, ``DepthMapFactor``); values are read without type checks;
* Photo-SLAM: ORB-SLAM3's ``File.version: "1.0"`` settings (``Camera1.fx ...``,
  ``RGBD.DepthMapFactor``), read by ``ORB-SLAM3/src/Settings.cc``, which aborts unless reals
  are written as reals (with a decimal point) and integers as integers;
* RampVO: ``K.yaml`` with ``cam0: {intrinsics: [fx, fy, cx, cy], resolution: [w, h]}``;
* NICE-SLAM: a ``cam:`` block (``H W fx fy cx cy png_depth_scale``) and the scene ``bound``.

**Pixel convention.** egs-bench stores gsplat's convention (pixel ``u`` has its centre at
``u + 0.5``); OpenCV, ORB-SLAM, MonoGS/3DGS and Replica put it at the integer ``u``. The files
therefore hold ``cx - 0.5`` and ``cy - 0.5`` (:func:`opencv_camera`).

The ORB parameters are those of ORB-SLAM2's ``TUM1.yaml``; ``Camera.bf`` / ``Stereo.b``
(the virtual baseline of RGB-D ORB-SLAM) is 0.08 m, so with ``ThDepth: 40`` points up to
3.2 m count as close (TUM1: 40 / 517.3 m x 40 = 3.1 m).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import yaml

from egs_bench.geometry import Intrinsics

ORB_BASELINE_M = 0.08
ORB_TH_DEPTH = 40.0
_HEADER = "# Written by egs-bench export for sequence {name!r} ({w}x{h}); pixel centres at " \
          "integer coordinates (egs-bench's cx, cy minus 0.5).\n"


def opencv_camera(intr: Intrinsics) -> Intrinsics:
    """The same camera in the OpenCV convention (pixel centre at integer ``u``): ``cx - 0.5``,
    ``cy - 0.5``; egs-bench's :class:`Intrinsics` put it at ``u + 0.5``."""
    return replace(intr, cx=float(intr.cx) - 0.5, cy=float(intr.cy) - 0.5)


def _real(v: float) -> str:
    """A number OpenCV's FileStorage parses as a real (always with a decimal point)."""
    text = repr(float(v))
    return text if ("." in text or "e" in text or "inf" in text or "nan" in text) else text + ".0"


def _frame_rate(fps: float) -> float:
    """The frame rate to 3 decimals (Hz): frame periods are whole microseconds, so 30 Hz comes
    out as 30.00030000299998, which ORB-SLAM2 uses only as a frame count."""
    return round(float(fps), 3)


def _header(cam: Intrinsics, name: str) -> str:
    return _HEADER.format(name=name, w=cam.width, h=cam.height)


#: where an external system's checkout finds an export (a folder relative to its checkout, as
#: MonoGS' and NICE-SLAM's own configs name their datasets)
CHECKOUT_ROOT = "datasets/egs_bench"


def checkout_path(export_dir: str | Path) -> str:
    """``datasets/egs_bench/<export folder name>``: the export as a system's config names it."""
    return f"{CHECKOUT_ROOT}/{Path(export_dir).name}"


def monogs_config(cam: Intrinsics, dataset_path: str, *, dataset_type: str, depth_scale: float,
                  name: str) -> str:
    """A MonoGS RGB-D config (``python slam.py --config FILE --eval`` from the MonoGS checkout).

    Args:
        dataset_path: the exported folder as MonoGS finds it, relative to the MonoGS checkout
            (:func:`checkout_path`; no path of this machine goes into a file meant to be sent
            on); a trailing ``/`` is added because MonoGS names its result folder after the
            last two path components.
        dataset_type: ``"tum"`` or ``"replica"`` (MonoGS' ``Dataset.type``).
        depth_scale: depth PNG units per metre.
    """
    base = {"tum": "configs/rgbd/tum/base_config.yaml",
            "replica": "configs/rgbd/replica/base_config.yaml"}[dataset_type]
    config = {
        "inherit_from": base,
        "Dataset": {
            "dataset_path": dataset_path.rstrip("/") + "/",
            "type": dataset_type,
            "sensor_type": "depth",
            "single_thread": True,
            "Calibration": {
                "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
                "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0, "distorted": False,
                "width": cam.width, "height": cam.height, "depth_scale": float(depth_scale),
            },
        },
        "Training": {"single_thread": True},
        "Results": {"use_gui": False},
    }
    comment = (_header(cam, name)
               + "# MonoGS single-thread RGB-D mode (as the EGS-SLAM paper ran it). From the "
                 "MonoGS checkout, link\n# this folder where dataset_path points, then run:\n"
                 f"#   mkdir -p {CHECKOUT_ROOT} && ln -s THIS_FOLDER {dataset_path.rstrip('/')}\n"
                 "#   WANDB_MODE=disabled python slam.py --config THIS_FILE --eval\n")
    return comment + yaml.safe_dump(config, sort_keys=False)


def _orb_block(lines: list[str]) -> None:
    lines += [
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


def orbslam2_settings(cam: Intrinsics, *, fps: float, depth_scale: float, name: str) -> str:
    """ORB-SLAM2 RGB-D settings (``./Examples/RGB-D/rgbd_tum VOC THIS_FILE DIR ASSOC``).

    ``Camera.RGB: 0``: ``rgbd_tum`` loads images with ``cv::imread``, i.e. in BGR order.
    """
    lines = ["%YAML:1.0", _header(cam, name).rstrip("\n"),
             f"Camera.fx: {_real(cam.fx)}", f"Camera.fy: {_real(cam.fy)}",
             f"Camera.cx: {_real(cam.cx)}", f"Camera.cy: {_real(cam.cy)}",
             "Camera.k1: 0.0", "Camera.k2: 0.0", "Camera.p1: 0.0", "Camera.p2: 0.0",
             "Camera.k3: 0.0",
             f"Camera.width: {cam.width}", f"Camera.height: {cam.height}",
             f"Camera.fps: {_real(_frame_rate(fps))}",
             f"Camera.bf: {_real(ORB_BASELINE_M * cam.fx)}",
             "Camera.RGB: 0",
             f"ThDepth: {_real(ORB_TH_DEPTH)}",
             f"DepthMapFactor: {_real(depth_scale)}", ""]
    _orb_block(lines)
    return "\n".join(lines) + "\n"


def orbslam3_settings(cam: Intrinsics, *, fps: float, depth_scale: float, name: str) -> str:
    """ORB-SLAM3 ``File.version "1.0"`` RGB-D settings, as Photo-SLAM's ``tum_rgbd`` reads
    them (``Camera.RGB: 1``: Photo-SLAM converts the BGR image to RGB before tracking; no
    distortion keys, so ORB-SLAM3 does not undistort)."""
    lines = ["%YAML:1.0", _header(cam, name).rstrip("\n"),
             'File.version: "1.0"', 'Camera.type: "PinHole"',
             f"Camera1.fx: {_real(cam.fx)}", f"Camera1.fy: {_real(cam.fy)}",
             f"Camera1.cx: {_real(cam.cx)}", f"Camera1.cy: {_real(cam.cy)}",
             f"Camera.width: {cam.width}", f"Camera.height: {cam.height}",
             f"Camera.fps: {max(1, round(fps))}",
             "Camera.RGB: 1",
             f"Stereo.ThDepth: {_real(ORB_TH_DEPTH)}",
             f"Stereo.b: {_real(ORB_BASELINE_M)}",
             f"RGBD.DepthMapFactor: {_real(depth_scale)}", ""]
    _orb_block(lines)
    return "\n".join(lines) + "\n"


def rampvo_k_yaml(cam: Intrinsics, *, name: str) -> str:
    """RampVO's ``K.yaml`` (read by ``evaluate.py:set_global_params``)."""
    data = {"cam0": {"intrinsics": [cam.fx, cam.fy, cam.cx, cam.cy],
                     "resolution": [cam.width, cam.height]}}
    return _header(cam, name) + yaml.safe_dump(data, sort_keys=False)


def nice_slam_config(cam: Intrinsics, input_folder: str, *, depth_scale: float,
                     bound: list[list[float]], name: str) -> str:
    """A NICE-SLAM scene config (``python run.py THIS_FILE`` from the NICE-SLAM checkout, with
    the export linked at ``input_folder``, relative to it: :func:`checkout_path`); ``bound``
    [[xmin, xmax], [ymin, ymax], [zmin, zmax]] in metres encloses the scene."""
    config = {
        "inherit_from": "configs/Replica/replica.yaml",
        "mapping": {"bound": bound, "marching_cubes_bound": bound},
        # replica.yaml ignores 100 px borders of a 1200x680 image in tracking: scale them
        "tracking": {"ignore_edge_W": round(100 * cam.width / 1200),
                     "ignore_edge_H": round(100 * cam.height / 680)},
        "meshing": {"eval_rec": False},  # needs Replica's ground-truth mesh
        "cam": {"H": cam.height, "W": cam.width, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx,
                "cy": cam.cy, "png_depth_scale": float(depth_scale), "crop_edge": 0},
        "data": {"input_folder": input_folder, "output": f"output/egs_bench/{name}"},
    }
    return _header(cam, name) + yaml.safe_dump(config, sort_keys=False,
                                               default_flow_style=None)
