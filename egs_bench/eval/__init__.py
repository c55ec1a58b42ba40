"""Evaluation: run folders, ATE, image metrics, LPIPS, protocols, leaderboards, plots.

Modules (each with one job):

- :mod:`~egs_bench.runs.folder`: the run-folder contract between methods and evaluation;
- :mod:`~egs_bench.eval.ate`: ATE with evo (association, Umeyama SE(3)/Sim(3), statistics);
- :mod:`~egs_bench.eval.image_metrics`: PSNR (full / MonoGS-masked), SSIM (3DGS / standard);
- :mod:`~egs_bench.eval.lpips`: LPIPS v0.1 (AlexNet / VGG16) without torchvision or downloads;
- :mod:`~egs_bench.eval.protocols`: named presets (``egs``, ``monogs``);
- :mod:`~egs_bench.eval.evaluate`: scores one run folder into ``metrics.json``;
- :mod:`~egs_bench.eval.results`: one robust record per run folder (status, seed, settings);
- :mod:`~egs_bench.eval.grouping`: runs grouped by (method, settings, sequence), mean +- std;
- :mod:`~egs_bench.eval.leaderboard`: Markdown / LaTeX / CSV tables over many runs;
- :mod:`~egs_bench.eval.tables`: cell formatting, ranks and LaTeX floats shared by tables;
- :mod:`~egs_bench.eval.plots`: trajectory, ATE-over-time and qualitative figures;
- :mod:`~egs_bench.eval.figures`: comparisons across methods (trajectories, zoomed grids);
- :mod:`~egs_bench.eval.compare`: two-image comparison (files read by :mod:`egs_bench.images`).

The Python API of the two trajectory metrics takes evo's and the CLI's order, ground truth
first: ``egs_bench.eval.trajectory_ate(GT, EST, align="se3")`` (= ``egs-bench ate GT EST``)
and ``egs_bench.eval.trajectory_rpe(GT, EST, relation="angle_deg")``.
"""

from typing import Any

__all__ = ["trajectory_ate", "trajectory_rpe"]


def __getattr__(name: str) -> Any:
    # imported on first use, so that importing a light module of the package (the CLI imports
    # the protocols) does not load the trajectory code
    if name == "trajectory_ate":
        from egs_bench.eval.ate import trajectory_ate

        return trajectory_ate
    if name == "trajectory_rpe":
        from egs_bench.eval.rpe import trajectory_rpe

        return trajectory_rpe
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
