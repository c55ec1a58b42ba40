"""egs-bench: event + RGB-D Gaussian Splatting SLAM toolkit and benchmark.

Subpackages (dependencies point one way, top to bottom):

- ``egs_bench.slam``, ``egs_bench.baselines``, ``egs_bench.eval``: methods and scoring;
- ``egs_bench.render``, ``egs_bench.datasets``: rasteriser and sequence data;
- ``egs_bench.geometry``: poses, trajectories, intrinsics.
"""

__version__ = "0.1.0"
