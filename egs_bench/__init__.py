"""egs-bench: event + RGB-D Gaussian Splatting SLAM toolkit and benchmark.

Subpackages (dependencies point one way, top to bottom):

- ``egs_bench.slam``, ``egs_bench.baselines``, ``egs_bench.eval``: methods and scoring;
- ``egs_bench.render``, ``egs_bench.datasets``: rasteriser and sequence data;
- ``egs_bench.geometry``: poses, trajectories, intrinsics.
"""

from importlib.metadata import PackageNotFoundError, version

#: the name the package is installed under (pyproject.toml's ``project.name``)
DISTRIBUTION = "egs-bench"
#: shown for a source tree that was never installed (no metadata to read the version from)
UNKNOWN_VERSION = "0+unknown"


def installed_version() -> str:
    """The installed distribution's version (pyproject.toml's, through the package metadata),
    or :data:`UNKNOWN_VERSION` when egs-bench runs from a source tree that was never installed."""
    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return UNKNOWN_VERSION


# The one place the version comes from; `egs-bench --version`, run.yaml, generated sequences'
# meta.yaml and metrics.json all report this value.
__version__ = installed_version()
