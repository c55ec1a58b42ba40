"""Interoperability with external SLAM systems: export a sequence in the layouts they read
(:mod:`~egs_bench.interop.export`) with the camera files they need
(:mod:`~egs_bench.interop.camera_files`). Importing their outputs as run folders lives in
:mod:`egs_bench.baselines.import_runs`."""
