"""Import the outputs of external systems (ORB-SLAM2, MonoGS, Photo-SLAM, ...) as run folders.

An import validates the estimate (TUM file: parseable, finite, sorted) and optional renders
(``%06d.png`` named by frame index), then writes a finished :class:`RunFolder` that
``egs-bench eval`` and ``egs-bench leaderboard`` treat like any other run.
"""

from __future__ import annotations

import re
from pathlib import Path

from egs_bench.errors import InputError
from egs_bench.geometry import read_tum
from egs_bench.images import read_ldr_image
from egs_bench.runs.folder import RunFolder

_RENDER = re.compile(r"^(\d+)\.png$")


def import_tum_run(
    estimate: str | Path,
    out_dir: str | Path,
    *,
    method: str,
    sequence_name: str,
    sequence_path: str | Path | None = None,
    groundtruth: str | Path | None = None,
    renders_dir: str | Path | None = None,
    overwrite: bool = False,
) -> RunFolder:
    """Create a finished run folder from an external TUM trajectory (and optional renders).

    Args:
        estimate: the external system's trajectory, TUM format (seconds, ``T_wc``).
        out_dir: run folder to create.
        method: method name for leaderboards.
        sequence_name: sequence name for leaderboards.
        sequence_path: canonical sequence folder (ground truth and reference images), or
        groundtruth: a TUM ground-truth file (for sequences that exist only as trajectories).
        renders_dir: folder of ``<frame index>.png`` renders to copy (any zero padding).
        overwrite: replace an existing run folder written by egs-bench.

    Raises:
        InputError: unreadable estimate / ground truth, or badly named renders.
        OutputError: ``out_dir`` exists (without ``overwrite``) or is (or contains) an input.
    """
    if sequence_path is None and groundtruth is None:
        raise InputError(out_dir, "an import needs a sequence folder or a ground-truth file")
    trajectory = read_tum(estimate, min_poses=3)
    if groundtruth is not None:
        read_tum(groundtruth, min_poses=3)
    renders: dict[int, Path] = {}
    if renders_dir is not None:
        renders_dir = Path(renders_dir)
        if not renders_dir.is_dir():
            raise InputError(renders_dir, "renders folder not found")
        for f in sorted(renders_dir.iterdir()):
            m = _RENDER.match(f.name)
            if f.suffix.lower() == ".png" and not m:
                raise InputError(f, "render names must be the frame index, e.g. 000005.png")
            if m:
                renders[int(m.group(1))] = f
    run = RunFolder.create(out_dir, method=method, sequence_name=sequence_name,
                           sequence_path=sequence_path, groundtruth=groundtruth,
                           config={"imported_from": str(Path(estimate).resolve())},
                           overwrite=overwrite,
                           inputs=[p for p in (estimate, renders_dir) if p is not None])
    with run.failure_guard():
        run.write_trajectory(trajectory.timestamps, trajectory.poses)
        for index, src in renders.items():
            run.write_render(index, read_ldr_image(src))
        run.log(f"imported {len(trajectory)} poses from {estimate}"
                + (f" and {len(renders)} renders from {renders_dir}" if renders else ""))
        run.mark_done()
    return run
