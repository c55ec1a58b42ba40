"""Real event + RGB-D recordings: readers (AEDAT4, ROS1 bags, folders), the rig calibration
(``calib.yaml``), depth reprojection, dataset presets and the importer into the canonical
sequence format.

```python
from egs_bench.recordings import RecordingSpec, import_recording

spec = RecordingSpec(events=Path("rec.aedat4"), depth=Path("rec.bag"), gt=Path("mocap.txt"),
                     calib=Path("calib.yaml"), preset="davis-realsense")
import_recording(spec, "data/my_sequence")
```
"""

from egs_bench.recordings.calib import RecordingCalib, dump_calib, load_calib
from egs_bench.recordings.camera import CameraModel
from egs_bench.recordings.depth import reproject_depth, warp_to_depth_camera
from egs_bench.recordings.importer import RecordingSpec, apply_preset, import_recording
from egs_bench.recordings.presets import PRESETS, RecordingPreset, get_preset

__all__ = [
    "PRESETS",
    "CameraModel",
    "RecordingCalib",
    "RecordingPreset",
    "RecordingSpec",
    "apply_preset",
    "dump_calib",
    "get_preset",
    "import_recording",
    "load_calib",
    "reproject_depth",
    "warp_to_depth_camera",
]
