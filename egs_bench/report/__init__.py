"""The HTML report of runs and sweeps (``egs-bench report``): static pages that work offline
from ``file://`` (no server, no network, no script library).

* :mod:`~egs_bench.report.collect` reads the runs into typed records;
* :mod:`~egs_bench.report.overview`, :mod:`~egs_bench.report.sequence_page` and
  :mod:`~egs_bench.report.run_page` decide what each page shows;
* :mod:`~egs_bench.report.figures` draws the report's own plots, :mod:`~egs_bench.report.assets`
  stores images once, downscaled, named by content;
* :mod:`~egs_bench.report.pages` renders the templates, :mod:`~egs_bench.report.build` writes
  the folder atomically.
"""

from egs_bench.report.build import (
    SIDE_REPORT_DIR,
    ReportResult,
    build_report,
    is_report_folder,
    write_side_report,
)

__all__ = ["SIDE_REPORT_DIR", "ReportResult", "build_report", "is_report_folder",
           "write_side_report"]
