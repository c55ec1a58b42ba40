"""``calib.yaml``: the calibration of a real event + RGB-D + mocap rig.

Every transform ``T_a_b`` is a 4x4 rigid transform mapping points from frame ``b`` to frame
``a`` (Kalibr's naming): ``p_a = T_a_b @ p_b``. Times: ``t_event_clock = t_sensor + offset``.

```yaml
event_camera:              # the sensor whose pixel grid the sequence uses
  width: 346
  height: 260
  intrinsics: [fx, fy, cx, cy]    # pixels; pixel (0, 0)'s centre at (0, 0) (OpenCV, ROS)
  distortion_model: radtan        # none | radtan (4, 5 or 8 coefficients) | equidistant (4)
  distortion: [k1, k2, p1, p2]
depth_camera:              # a camera like the above, or the word `event` (depth on the event grid)
  width: 640
  height: 480
  intrinsics: [fx, fy, cx, cy]
  distortion_model: none
  distortion: []
  depth_scale: 1000        # 16-bit depth units per metre (RealSense: 1000); float depth: metres
frame_camera: null         # null: frames come from the event sensor (DAVIS APS); else a camera
T_event_depth: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]   # depth camera -> event camera
T_event_frame: null        # frame camera -> event camera (only with frame_camera)
T_body_event: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]    # event camera -> mocap body
time_offsets_us:           # added to a sensor's stamps to put them on the event clock
  depth: 0
  frames: 0
  mocap: 0
```

Nothing that changes the imported data has a default: ``T_body_event``, ``time_offsets_us.depth``
and ``time_offsets_us.mocap`` are always required, ``T_event_depth`` with a depth camera (it must
be absent or the identity with ``depth_camera: event``), ``T_event_frame`` and
``time_offsets_us.frames`` with a frame camera, and ``depth_scale`` whenever the depth maps are
16-bit integers (the importer checks that, since only the data says so). Write the identity or
0 explicitly where it is the true value; ``egs-bench make-calib`` writes every key.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from egs_bench.errors import InputError
from egs_bench.fileio import read_yaml_mapping
from egs_bench.recordings.camera import CameraModel

#: a rotation whose R^T R differs from I by more than this is not a rotation
ROTATION_TOL = 1e-4


@dataclass(frozen=True)
class RecordingCalib:
    """A parsed, validated ``calib.yaml`` (see the module docstring for the schema).

    Attributes:
        event_camera: the camera whose pixel grid the imported sequence uses.
        depth_camera: the depth sensor's camera (may be the event camera itself).
        depth_scale: 16-bit depth units per metre; ``None`` when the file gives none (float
            depth in metres needs none; the importer refuses 16-bit depth without it).
        frame_camera: the camera of the frames, ``None`` when they come from the event sensor.
        T_event_depth, T_event_frame, T_body_event: [4, 4] float64 (see module docstring).
        time_offsets_us: ``depth``, ``frames``, ``mocap`` offsets in microseconds.
        path: the file it was read from (for error messages), ``None`` if built in code.
    """

    event_camera: CameraModel | None
    depth_camera: CameraModel | None = None
    depth_scale: float | None = None
    frame_camera: CameraModel | None = None
    T_event_depth: np.ndarray = field(default_factory=lambda: np.eye(4))
    T_event_frame: np.ndarray = field(default_factory=lambda: np.eye(4))
    T_body_event: np.ndarray = field(default_factory=lambda: np.eye(4))
    time_offsets_us: dict[str, int] = field(
        default_factory=lambda: {"depth": 0, "frames": 0, "mocap": 0})
    path: Path | None = None
    depth_on_event_grid: bool = False

    @property
    def label(self) -> str:
        return str(self.path) if self.path is not None else "calibration"

    def error(self, problem: str) -> InputError:
        """An :class:`InputError` naming this calibration's file."""
        return InputError(self.path or Path("calib.yaml"), problem)

    def to_dict(self) -> dict[str, Any]:
        """The calibration as plain data (recorded in the sequence's ``meta.yaml``)."""
        cam = self.event_camera.to_dict() if self.event_camera else None
        if self.depth_on_event_grid:
            depth: Any = "event"
        else:
            depth = self.depth_camera.to_dict() if self.depth_camera else None
        if isinstance(depth, dict):
            depth["depth_scale"] = self.depth_scale
        return {
            "event_camera": cam,
            "depth_camera": depth,
            "frame_camera": self.frame_camera.to_dict() if self.frame_camera else None,
            "T_event_depth": self.T_event_depth.tolist(),
            "T_event_frame": self.T_event_frame.tolist() if self.frame_camera else None,
            "T_body_event": self.T_body_event.tolist(),
            "time_offsets_us": dict(self.time_offsets_us),
            **({"depth_scale": self.depth_scale} if depth == "event" else {}),
        }


def _camera(path: Path, key: str, raw: Any) -> CameraModel:
    if not isinstance(raw, dict):
        raise InputError(path, f"{key} must be a mapping (width, height, intrinsics, "
                               "distortion_model, distortion)")
    missing = [k for k in ("width", "height", "intrinsics") if k not in raw]
    if missing:
        raise InputError(path, f"{key}: missing {', '.join(missing)}")
    intr = raw["intrinsics"]
    if not (isinstance(intr, list) and len(intr) == 4
            and all(isinstance(v, int | float) for v in intr)):
        raise InputError(path, f"{key}.intrinsics must be [fx, fy, cx, cy], got {intr!r}")
    for k in ("width", "height"):
        if not isinstance(raw[k], int) or raw[k] <= 0:
            raise InputError(path, f"{key}.{k} must be a positive integer, got {raw[k]!r}")
    coeffs = raw.get("distortion") or []
    if not isinstance(coeffs, list) or not all(isinstance(v, int | float) for v in coeffs):
        raise InputError(path, f"{key}.distortion must be a list of numbers")
    try:
        fx, fy, cx, cy = (float(v) for v in intr)
        return CameraModel(int(raw["width"]), int(raw["height"]), fx, fy, cx, cy,
                           model=str(raw.get("distortion_model") or "none"), coeffs=tuple(coeffs))
    except ValueError as exc:
        raise InputError(path, f"{key}: {exc}") from None


def _transform(path: Path, key: str, raw: Any) -> np.ndarray:
    if raw is None:
        return np.eye(4)
    try:
        T = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(path, f"{key} must be a 4x4 matrix of numbers") from None
    if T.shape == (16,):
        T = T.reshape(4, 4)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise InputError(path, f"{key} must be a 4x4 matrix (4 rows of 4 numbers), got shape "
                               f"{T.shape}")
    if not np.allclose(T[3], [0, 0, 0, 1]):
        raise InputError(path, f"{key}: last row must be [0, 0, 0, 1]")
    R = T[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > ROTATION_TOL or np.linalg.det(R) < 0:
        raise InputError(path, f"{key}: the upper-left 3x3 block is not a rotation")
    return T


def load_calib(path: str | Path) -> RecordingCalib:
    """Read and validate ``calib.yaml``.

    Raises:
        InputError: naming the file and the problem (missing keys, malformed matrices,
            non-rotations, unknown distortion models, bad sizes).
    """
    path = Path(path)
    raw = read_yaml_mapping(path, "calibration file")
    known = {"event_camera", "depth_camera", "frame_camera", "T_event_depth", "T_event_frame",
             "T_body_event", "time_offsets_us", "depth_scale"}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise InputError(path, f"unknown keys: {', '.join(unknown)} (known: "
                               f"{', '.join(sorted(known))})")
    event = _camera(path, "event_camera", raw["event_camera"]) \
        if raw.get("event_camera") is not None else None
    depth_raw = raw.get("depth_camera")
    on_event = depth_raw == "event"
    depth_scale = raw.get("depth_scale")
    if on_event:
        depth = event
    elif depth_raw is None:
        depth = None
    else:
        depth = _camera(path, "depth_camera", depth_raw)
        depth_scale = depth_raw.get("depth_scale", depth_scale)
    if depth_scale is not None and (not isinstance(depth_scale, int | float)
                                    or not depth_scale > 0):
        raise InputError(path, f"depth_scale must be a positive number, got {depth_scale!r}")
    frame = _camera(path, "frame_camera", raw["frame_camera"]) \
        if raw.get("frame_camera") is not None else None
    offsets = _offsets(path, raw.get("time_offsets_us"), with_frames=frame is not None)
    if raw.get("T_event_frame") is not None and frame is None:
        raise InputError(path, "T_event_frame given without frame_camera")
    T_event_depth = _required_transform(
        path, raw, "T_event_depth", depth is not None and not on_event,
        "depth camera -> event camera")
    if on_event and not np.allclose(T_event_depth, np.eye(4)):
        raise InputError(path, "depth_camera: event puts depth on the event camera's grid, so "
                               "T_event_depth must be absent or the identity")
    return RecordingCalib(
        event_camera=event, depth_camera=depth,
        depth_scale=None if depth_scale is None else float(depth_scale), frame_camera=frame,
        T_event_depth=T_event_depth,
        T_event_frame=_required_transform(path, raw, "T_event_frame", frame is not None,
                                          "frame camera -> event camera"),
        T_body_event=_required_transform(path, raw, "T_body_event", True,
                                         "event camera -> mocap body; the identity when the "
                                         "poses are the event camera's"),
        time_offsets_us=offsets, path=path, depth_on_event_grid=on_event,
    )


def _required_transform(path: Path, raw: dict, key: str, required: bool,
                        meaning: str) -> np.ndarray:
    """``raw[key]`` as a checked 4x4 transform; a missing required one is an error (an
    identity guessed here would move every pose or depth value without a word)."""
    if raw.get(key) is None:
        if required:
            raise InputError(path, f"missing {key} ({meaning}): write the 4x4 matrix, the "
                                   "identity if that is the true value")
        return np.eye(4)
    return _transform(path, key, raw[key])


def _offsets(path: Path, raw: Any, with_frames: bool) -> dict[str, int]:
    """``time_offsets_us`` -> ``{depth, frames, mocap}`` microseconds. ``depth`` and ``mocap``
    are required, ``frames`` only with a frame camera (frames from the event sensor share its
    clock, offset 0)."""
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise InputError(path, "time_offsets_us must be a mapping with depth, frames, mocap")
    bad = sorted(set(raw) - {"depth", "frames", "mocap"})
    if bad:
        raise InputError(path, f"time_offsets_us: unknown keys {', '.join(bad)} "
                               "(depth, frames, mocap)")
    offsets = {}
    for key in ("depth", "frames", "mocap"):
        if key not in raw and (key != "frames" or with_frames):
            raise InputError(path, f"missing time_offsets_us.{key} (microseconds added to that "
                                   "sensor's stamps; 0 if it shares the event camera's clock)")
        value = raw.get(key, 0)
        if not isinstance(value, int | float) or isinstance(value, bool) \
                or not np.isfinite(value):
            raise InputError(path, f"time_offsets_us.{key} must be a number of microseconds")
        offsets[key] = int(round(value))
    return offsets


def dump_calib(calib: RecordingCalib) -> str:
    """``calib.yaml`` text for ``calib`` (round-trips through :func:`load_calib`)."""
    data = calib.to_dict()
    if data.get("depth_scale") is None:
        data.pop("depth_scale", None)
    if data["T_event_frame"] is None:
        data.pop("T_event_frame")
    return "# egs-bench recording calibration; see `egs-bench import-recording --help`\n" \
        + yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def camera_from_kalibr(path: str | Path, camera: str = "cam0") -> CameraModel:
    """A camera from a Kalibr ``camchain.yaml`` (``intrinsics: [fu, fv, pu, pv]``,
    ``distortion_model``, ``distortion_coeffs``, ``resolution: [w, h]``), e.g. MVSEC's
    ``camchain-imucam-indoor_flying.yaml``. Kalibr uses OpenCV's pixel convention."""
    path = Path(path)
    raw = read_yaml_mapping(path, "Kalibr file")
    if camera not in raw or not isinstance(raw[camera], dict):
        raise InputError(path, f"no camera {camera!r} (found: {', '.join(map(str, raw))})")
    cam = raw[camera]
    try:
        w, h = (int(v) for v in cam["resolution"])
        fx, fy, cx, cy = (float(v) for v in cam["intrinsics"])
        return CameraModel(w, h, fx, fy, cx, cy, model=str(cam.get("distortion_model", "none")),
                           coeffs=tuple(cam.get("distortion_coeffs") or ()))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(path, f"{camera}: not a Kalibr camera entry ({exc})") from None


def camera_from_ros_yaml(path: str | Path) -> CameraModel:
    """A camera from a ROS ``camera_calibration_parsers`` yaml (``image_width``,
    ``camera_matrix.data``, ``camera_model`` / ``distortion_model``,
    ``distortion_coefficients.data``), e.g. VECtor's ``*_intrinsic_results.yaml``."""
    path = Path(path)
    raw = read_yaml_mapping(path, "ROS calibration file")
    try:
        k = [float(v) for v in raw["camera_matrix"]["data"]]
        model = raw.get("distortion_model") or raw.get("camera_model") or "plumb_bob"
        coeffs = tuple(float(v) for v in raw["distortion_coefficients"]["data"])
        return CameraModel(int(raw["image_width"]), int(raw["image_height"]), k[0], k[4], k[2],
                           k[5], model=str(model), coeffs=coeffs)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(path, f"not a ROS camera calibration yaml ({exc})") from None


def write_calib_template(out: str | Path, *, kalibr: str | Path | None = None,
                         camera: str = "cam0", ros_yaml: str | Path | None = None,
                         depth_on_event: bool = False, preset: str | None = None,
                         overwrite: bool = False) -> Path:
    """Write an editable ``calib.yaml``: the event camera from a Kalibr or ROS calibration file
    when given (else placeholders for a DAVIS346), identity transforms, zero time offsets.

    ``preset`` is a name of :data:`egs_bench.recordings.presets.PRESETS`; ``"mvsec-indoor"``
    implies ``depth_on_event`` (MVSEC's depth maps are on the DAVIS grid). The file is only a
    starting point: extrinsics and offsets must be filled in. An existing ``out`` is replaced
    only with ``overwrite`` and only if it is a text file (``outputs.prepare_output``).

    Raises:
        ConfigError: an unknown preset, or both ``kalibr`` and ``ros_yaml``.
        OutputError: ``out`` exists (without ``overwrite``) or may not be replaced.
    """
    from egs_bench.errors import ConfigError
    from egs_bench.fileio import write_text_atomic
    from egs_bench.outputs import prepare_output
    from egs_bench.recordings.presets import PRESETS

    out = Path(out)
    if preset is not None and preset not in PRESETS:
        raise ConfigError(f"unknown --preset {preset!r}; choose one of {', '.join(PRESETS)}")
    if kalibr is not None and ros_yaml is not None:
        raise ConfigError("give --kalibr or --ros-yaml, not both")
    prepare_output(out, "text", overwrite=overwrite, inputs=[kalibr, ros_yaml], option="--out")
    if preset == "mvsec-indoor":
        depth_on_event = True
    if kalibr is not None:
        event = camera_from_kalibr(kalibr, camera)
    elif ros_yaml is not None:
        event = camera_from_ros_yaml(ros_yaml)
    else:  # placeholders: a DAVIS346 with a 4.5 mm lens
        event = CameraModel(346, 260, 250.0, 250.0, 172.5, 129.5, "radtan", (0.0, 0.0, 0.0, 0.0))
    depth = None if depth_on_event else \
        CameraModel(640, 480, 385.0, 385.0, 319.5, 239.5)  # placeholders: a D435 at 640x480
    # depth_scale 1000: the RealSense / Azure Kinect millimetres, a value to check like the rest
    calib = RecordingCalib(event_camera=event, depth_camera=event if depth_on_event else depth,
                           depth_scale=1000.0, depth_on_event_grid=depth_on_event)
    write_text_atomic(out, dump_calib(calib))
    return out
