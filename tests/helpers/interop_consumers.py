"""Other systems' readers of exported layouts, reproduced from their source (MonoGS
``utils/dataset.py`` TUMParser / ReplicaParser at muskie82/MonoGS@6c9254c, ORB-SLAM2
``Examples/RGB-D/rgbd_tum.cc`` LoadImages at raulmur/ORB_SLAM2@f2e6f51, ORB-SLAM3 ``Settings.cc``
type rules as in HuajianUP/Photo-SLAM@f8bfb2f), and a sequence copy with retimed frames: the
export and import tests read exports back with them."""

from __future__ import annotations

import csv
import glob
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np


def quat_wxyz_to_matrix(q: np.ndarray) -> np.ndarray:
    """trimesh.transformations.quaternion_matrix (w first), written out."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), 0.0],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), 0.0],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), 0.0],
        [0.0, 0.0, 0.0, 1.0]])


def monogs_tum_parser(datapath: str, frame_rate: float = 32
                      ) -> tuple[list[str], list[str], list[np.ndarray]]:
    """MonoGS TUMParser.load_poses: colour paths, depth paths, w2c poses of kept frames."""
    def parse_list(filepath: str, skiprows: int = 0) -> np.ndarray:
        return np.loadtxt(filepath, delimiter=" ", dtype=np.str_, skiprows=skiprows)

    pose_list = os.path.join(datapath, "groundtruth.txt")
    image_data = parse_list(os.path.join(datapath, "rgb.txt"))
    depth_data = parse_list(os.path.join(datapath, "depth.txt"))
    pose_data = parse_list(pose_list, skiprows=1)
    pose_vecs = pose_data[:, 0:].astype(np.float64)
    tstamp_image = image_data[:, 0].astype(np.float64)
    tstamp_depth = depth_data[:, 0].astype(np.float64)
    tstamp_pose = pose_data[:, 0].astype(np.float64)
    associations = []
    for i, t in enumerate(tstamp_image):
        j = np.argmin(np.abs(tstamp_depth - t))
        k = np.argmin(np.abs(tstamp_pose - t))
        if (np.abs(tstamp_depth[j] - t) < 0.08) and (np.abs(tstamp_pose[k] - t) < 0.08):
            associations.append((i, j, k))
    indices = [0]
    for i in range(1, len(associations)):
        t0 = tstamp_image[associations[indices[-1]][0]]
        t1 = tstamp_image[associations[i][0]]
        if t1 - t0 > 1.0 / frame_rate:
            indices += [i]
    colors, depths, poses = [], [], []
    for ix in indices:
        (i, j, k) = associations[ix]
        colors.append(os.path.join(datapath, image_data[i, 1]))
        depths.append(os.path.join(datapath, depth_data[j, 1]))
        T = quat_wxyz_to_matrix(np.roll(pose_vecs[k][4:], 1))
        T[:3, 3] = pose_vecs[k][1:4]
        poses.append(np.linalg.inv(T))
    return colors, depths, poses


def monogs_replica_parser(input_folder: str
                          ) -> tuple[list[str], list[str], list[np.ndarray]]:
    """MonoGS ReplicaParser: sorted JPEG / depth globs and traj.txt (c2w, inverted)."""
    colors = sorted(glob.glob(f"{input_folder}/results/frame*.jpg"))
    depths = sorted(glob.glob(f"{input_folder}/results/depth*.png"))
    with open(f"{input_folder}/traj.txt") as f:
        lines = f.readlines()
    poses = [np.linalg.inv(np.array(list(map(float, lines[i].split()))).reshape(4, 4))
             for i in range(len(colors))]
    return colors, depths, poses


def orbslam_load_images(association_file: str) -> tuple[list[str], list[str], list[float]]:
    """rgbd_tum.cc LoadImages: every non-empty line is 't rgb t depth'."""
    rgb, depth, stamps = [], [], []
    with open(association_file) as f:
        for s in f.read().split("\n"):
            if s:
                parts = s.split()
                stamps.append(float(parts[0]))
                rgb.append(parts[1])
                depth.append(parts[3])
    return rgb, depth, stamps


def orbslam3_read(fs: cv2.FileStorage, name: str, kind: str) -> float | int | str:
    """ORB-SLAM3 Settings::readParameter: aborts unless the node has the right type."""
    node = fs.getNode(name)
    assert not node.empty(), f"{name} required parameter does not exist"
    check = {"float": node.isReal, "int": node.isInt, "string": node.isString}[kind]
    assert check(), f"{name} parameter must be a {kind}"
    readers: dict[str, Callable[[], float | int | str]] = {
        "float": node.real, "int": lambda: int(node.real()), "string": node.string}
    return readers[kind]()


def retimed_copy(src: Path, dst: Path, period_us: int) -> Path:
    """A copy of a sequence whose frames are ``period_us`` apart (events untouched)."""
    shutil.copytree(src, dst)
    with (dst / "frames.csv").open() as f:
        rows = list(csv.DictReader(f))
    t_end = int(rows[0]["t_end_us"]) + period_us * np.arange(len(rows))
    exposure = int(rows[0]["t_end_us"]) - int(rows[0]["t_start_us"])
    for r, t in zip(rows, t_end, strict=True):
        r["t_end_us"], r["t_start_us"] = int(t), int(t) - min(exposure, period_us - 1000)
    with (dst / "frames.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    from egs_bench.geometry import read_tum, write_tum

    gt = read_tum(dst / "groundtruth.txt")
    write_tum(dst / "groundtruth.txt", t_end * 1e-6, gt.poses)
    return dst
