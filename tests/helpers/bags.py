"""Write small ROS1 bags for the recording tests with ``rosbags`` (events, images, depth, poses,
camera info, exposure), the message types a DAVIS / RealSense / mocap rig records."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from egs_bench.geometry import pose_to_tq

EVENT_MSG = "uint16 x\nuint16 y\ntime ts\nbool polarity\n"
EVENT_ARRAY_MSG = "Header header\nuint32 height\nuint32 width\ndvs_msgs/Event[] events\n"


def typestore() -> Any:  # a rosbags Typestore
    ts = get_typestore(Stores.ROS1_NOETIC)
    ts.register(get_types_from_msg(EVENT_MSG, "dvs_msgs/msg/Event")
                | get_types_from_msg(EVENT_ARRAY_MSG, "dvs_msgs/msg/EventArray"))
    return ts


def _stamp(ts: Any, t_us: int) -> Any:
    t_us = int(t_us)
    return ts.types["builtin_interfaces/msg/Time"](sec=t_us // 1_000_000,
                                                  nanosec=(t_us % 1_000_000) * 1000)


def _header(ts: Any, t_us: int, frame_id: str = "cam") -> Any:
    return ts.types["std_msgs/msg/Header"](seq=0, stamp=_stamp(ts, t_us), frame_id=frame_id)


class BagBuilder:
    """Collects messages per topic, then writes one bag in receive-time order."""

    def __init__(self) -> None:
        self.ts = typestore()
        self._msgs: list[tuple[int, str, str, object]] = []

    def _add(self, topic: str, msgtype: str, t_us: int, msg: object) -> None:
        self._msgs.append((int(t_us), topic, msgtype, msg))

    def events(self, topic: str, x: np.ndarray, y: np.ndarray, t_us: np.ndarray, p: np.ndarray,
               width: int, height: int,
               packet_us: int = 10_000) -> None:
        """Events (p in {0,1} or +-1) split into packets of ``packet_us``."""
        t_us = np.asarray(t_us, np.int64)
        Ev, Arr = self.ts.types["dvs_msgs/msg/Event"], self.ts.types["dvs_msgs/msg/EventArray"]
        bounds = np.arange(t_us[0] - t_us[0] % packet_us, t_us[-1] + packet_us, packet_us)
        idx = np.searchsorted(t_us, bounds)
        for i0, i1 in zip(idx[:-1], idx[1:], strict=True):
            if i1 <= i0:
                continue
            evs = [Ev(x=int(x[i]), y=int(y[i]), ts=_stamp(self.ts, t_us[i]),
                      polarity=bool(p[i] > 0)) for i in range(i0, i1)]
            msg = Arr(header=_header(self.ts, t_us[i1 - 1]), height=height, width=width,
                      events=evs)
            self._add(topic, "dvs_msgs/msg/EventArray", t_us[i1 - 1], msg)

    def image(self, topic: str, t_us: int, image: np.ndarray, encoding: str,
              frame_id: str = "cam") -> None:
        img = np.ascontiguousarray(image)
        h, w = img.shape[:2]
        data = img.view(np.uint8).reshape(-1)
        msg = self.ts.types["sensor_msgs/msg/Image"](
            header=_header(self.ts, t_us, frame_id), height=h, width=w, encoding=encoding,
            is_bigendian=0, step=len(data) // h, data=data)
        self._add(topic, "sensor_msgs/msg/Image", t_us, msg)

    def exposure(self, topic: str, t_us: int, exposure_us: int) -> None:
        self._add(topic, "std_msgs/msg/Int32", t_us,
                  self.ts.types["std_msgs/msg/Int32"](data=int(exposure_us)))

    def pose(self, topic: str, t_us: int, T: np.ndarray) -> None:
        t, q = pose_to_tq(T)
        types = self.ts.types
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=t[0], y=t[1], z=t[2]),
            orientation=types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))
        msg = types["geometry_msgs/msg/PoseStamped"](header=_header(self.ts, t_us, "world"),
                                                      pose=pose)
        self._add(topic, "geometry_msgs/msg/PoseStamped", t_us, msg)

    def camera_info(self, topic: str, t_us: int, width: int, height: int,
                    K: tuple[float, float, float, float], D: list[float],
                    model: str = "plumb_bob") -> None:
        types = self.ts.types
        fx, fy, cx, cy = K
        roi = types["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0,
                                                         width=0, do_rectify=False)
        msg = types["sensor_msgs/msg/CameraInfo"](
            header=_header(self.ts, t_us), height=height, width=width, distortion_model=model,
            D=np.asarray(D, np.float64),
            K=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], np.float64),
            R=np.eye(3).reshape(-1), P=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0],
                                                np.float64),
            binning_x=0, binning_y=0, roi=roi)
        self._add(topic, "sensor_msgs/msg/CameraInfo", t_us, msg)

    def write(self, path: Path) -> Path:
        path = Path(path)
        with Writer(path) as writer:
            conns = {}
            for t_us, topic, msgtype, msg in sorted(self._msgs, key=lambda m: m[0]):
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=self.ts)
                writer.write(conns[topic], t_us * 1000, self.ts.serialize_ros1(msg, msgtype))
        return path
