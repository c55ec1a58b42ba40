"""CLI commands of experiments at scale: ``sweep``, ``paper-tables``, ``regress``, ``figure``.

Thin wrappers over :mod:`egs_bench.experiments`.
"""

from __future__ import annotations

from pathlib import Path

import typer

from egs_bench.cli.app import app, comma_list
from egs_bench.cli.app import out as _out
from egs_bench.cli.choices import FigureKind, Protocol, SubmititCluster, SweepBackend, TableWidth


@app.command("sweep")
def sweep_cmd(
    sweep_file: Path = typer.Argument(..., help="Sweep file (YAML): methods, sequences, seeds, "
                                                "presets, devices, overrides, backends."),
    out: Path | None = typer.Option(None, "--out", "-o",
                                    help="Output folder (default: the file's 'out', else "
                                         "sweeps/<file stem>)."),
    backend: SweepBackend = typer.Option("local", "--backend", "-b",
                                help="local (process pool) or slurm (submitit job array)."),
    shard: str | None = typer.Option(None, "--shard",
                                     help="Run only shard i of N (i/N, 0 <= i < N), for "
                                          "several machines without a scheduler."),
    jobs: int | None = typer.Option(None, "--jobs", "-j",
                                    help="Parallel runs of the local pool (default: one per "
                                         "GPU for CUDA runs, else from the CPU budget)."),
    threads_per_job: int | None = typer.Option(None, "--threads-per-job",
                                               help="CPU threads of each run (default: the "
                                                    "budget divided by the jobs)."),
    options: list[str] = typer.Option([], "--set",
                                      help="SLAM option override for every run, KEY=VALUE "
                                           "(repeatable; part of each run's configuration)."),
    force: bool = typer.Option(False, "--force",
                               help="Rerun finished and stale runs (replaces the run folders "
                                    "this sweep created)."),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="Rerun failed runs."),
    dry_run: bool = typer.Option(False, "--dry-run", help="List what would run; run nothing."),
    status: bool = typer.Option(False, "--status",
                                help="Only print the summary of the run folders as they are."),
    no_wait: bool = typer.Option(False, "--no-wait",
                                 help="slurm: return after submitting (check later with "
                                      "--status)."),
    cluster: SubmititCluster = typer.Option("slurm", "--cluster",
                                help="submitit cluster of the slurm backend: slurm, or local / "
                                     "debug to try the backend on this machine."),
) -> None:
    """Run (or resume) a sweep: methods x sequences x seeds x settings, one process per run."""
    from egs_bench.experiments.spec import command_line_options, load_sweep, parse_shard
    from egs_bench.experiments.sweep import run_sweep

    spec = load_sweep(sweep_file)
    report = run_sweep(spec, out=out, extra_options=command_line_options(spec, options),
                       backend=backend, shard=parse_shard(shard), force=force,
                       retry_failed=retry_failed, jobs=jobs, threads_per_job=threads_per_job,
                       cluster=cluster,
                       wait=not no_wait, dry_run=dry_run, status_only=status,
                       say=lambda m: _out.print(m, markup=False))
    typer.echo(report.summary_md, nl=False)
    if not dry_run:
        _out.print(f"summary: {report.out / 'sweep_summary.md'} (and .csv)")
    if (full_disk := report.full_disk()) is not None:
        raise full_disk
    # --status answers "is the sweep complete?" with the exit code, as a run does
    if not (dry_run or no_wait) and not report.all_done:
        raise typer.Exit(1)


@app.command("regress")
def regress_cmd(
    baseline: Path = typer.Argument(..., help="Baseline: a summary CSV (`leaderboard --format "
                                              "csv-summary`) or a runs folder."),
    runs: Path = typer.Argument(..., help="Runs to check: a runs folder (or a summary CSV)."),
    tolerances: Path | None = typer.Option(None, "--tolerances", "-t",
                                           help="YAML: metric -> {abs, rel} in stored units "
                                                "(ATE metres); null disables a metric."),
    metrics: str | None = typer.Option(None, "--metrics",
                                       help="Comma-separated metrics to check (default: those "
                                            "with a tolerance: ate, psnr, ssim, lpips)."),
    protocol: Protocol = typer.Option("egs", "--protocol", "-p", help="Evaluation protocol."),
    update: bool = typer.Option(False, "--update",
                                help="Write the summary of RUNS to BASELINE instead of "
                                     "checking (refreshes a committed baseline)."),
    output: Path | None = typer.Option(None, "--out", "-o", "--output",
                                       help="Also write the regression table as CSV."),
) -> None:
    """Compare runs with a baseline, metric by metric (direction-aware tolerances); exit 1 on a
    regression or a missing result."""
    from egs_bench.experiments.regress import check, failed, render, update_baseline
    from egs_bench.fileio import write_text_atomic
    from egs_bench.outputs import prepare_output

    if output is not None:  # the regression table is rewritten on every check
        prepare_output(output, "text", overwrite=True, inputs=[baseline, runs],
                       option="--out")
    if update:
        df = update_baseline(runs, baseline, protocol)
        _out.print(f"wrote {baseline} ({len(df)} rows from {runs})")
        return
    keys = [m.strip() for m in metrics.split(",") if m.strip()] if metrics else None
    table = check(baseline, runs, tolerances=tolerances, metrics=keys, protocol=protocol)
    typer.echo(render(table), nl=False)
    if output is not None:
        write_text_atomic(output, table.to_csv(index=False, lineterminator="\n"))
    if failed(table):
        raise typer.Exit(1)


@app.command("paper-tables")
def paper_tables_cmd(
    sweep_dir: Path = typer.Argument(..., help="A sweep folder (its runs/) or any runs folder."),
    out: Path | None = typer.Option(None, "--out", "-o",
                                    help="Folder for the tables (default SWEEP_DIR/tables)."),
    tables: str = typer.Option("ate,rendering,ablation_events,ablation_crf,edi", "--tables",
                               help="Comma-separated tables to make (those the runs can fill)."),
    protocol: Protocol = typer.Option("egs", "--protocol", "-p", help="Evaluation protocol."),
    width: TableWidth = typer.Option("auto", "--width",
                              help="LaTeX width: auto, natural, column or page (table*)."),
    label_prefix: str = typer.Option("tab:", "--label-prefix",
                                     help="LaTeX labels are <prefix><table name>."),
    check: bool = typer.Option(False, "--check",
                               help="Compile tables.tex with pdflatex and report overfull "
                                    "tables (needs pdflatex)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace existing table files."),
) -> None:
    """The paper's table layouts (ATE, rendering, event and CRF ablations, EDI) as LaTeX and
    Markdown, with mean ± std over seeds."""
    from egs_bench.experiments.paper_tables import build_tables, render_markdown, write_tables

    made, skipped = build_tables(sweep_dir, protocol,
                                 tables=comma_list(tables, "--tables"))
    target = out or Path(sweep_dir) / "tables"
    paths = write_tables(made, target, label_prefix=label_prefix, width=width,
                         overwrite=overwrite)
    for table in made.values():
        typer.echo(render_markdown(table))
    for line in skipped:
        _out.print(line, markup=False)
    _out.print(f"wrote {len(paths)} files to {target} (compile {target / 'tables.tex'} to "
               "check)", markup=False)
    if check:
        from egs_bench.experiments.latex_check import compile_latex

        log = compile_latex([(target / f"{n}.tex").read_text() for n in made],
                            target / "check")
        overfull = log.count("Overfull \\hbox")
        _out.print(f"pdflatex: compiled; {overfull} overfull box(es)", markup=False)
        if overfull:
            raise typer.Exit(1)


def _crops(values: list[str]) -> list[tuple[int, int, int, int]]:
    from egs_bench.errors import ConfigError

    out = []
    for v in values:
        parts = v.split(",")
        if len(parts) != 4 or not all(p.strip().lstrip("-").isdigit() for p in parts):
            raise ConfigError(f"--crop must be x,y,w,h in pixels, got {v!r}")
        x, y, w, h = (int(p) for p in parts)
        out.append((x, y, w, h))
    return out


@app.command("figure")
def figure_cmd(
    kind: FigureKind = typer.Argument(..., help="trajectories (several methods on one plot) or "
                                         "qualitative (renders side by side, zoomed crops, "
                                         "PSNR)."),
    run_dirs: list[Path] = typer.Argument(..., help="Run folders of one sequence."),
    output: Path = typer.Option(..., "--out", "-o", "--output",
                                help="Figure file: .pdf, .svg or .png."),
    frames: str = typer.Option("0", "--frames", help="qualitative: comma-separated frames."),
    crop: list[str] = typer.Option([], "--crop",
                                   help="qualitative: zoom box x,y,w,h in pixels "
                                        "(repeatable, up to 4)."),
    label: list[str] = typer.Option([], "--label",
                                    help="Legend/column label per run (default: the method)."),
    protocol: Protocol = typer.Option("egs", "--protocol", "-p",
                                 help="ATE settings and reference images of this protocol."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing figure."),
) -> None:
    """Comparison figures across methods on one sequence."""
    from egs_bench.errors import ConfigError
    from egs_bench.eval.figures import qualitative_figure, trajectory_figure
    from egs_bench.outputs import prepare_output

    prepare_output(output, "figure", overwrite=overwrite, inputs=run_dirs, option="--out")
    if label and len(label) != len(run_dirs):
        raise ConfigError(f"--label given {len(label)} times for {len(run_dirs)} run folders")
    if kind == "trajectories":
        path = trajectory_figure(run_dirs, output, protocol, label or None)
    elif kind == "qualitative":
        try:
            picked = [int(f) for f in frames.split(",") if f.strip()]
        except ValueError:
            raise ConfigError(f"--frames must be comma-separated integers, got {frames!r}") \
                from None
        path = qualitative_figure(run_dirs, output, picked, _crops(crop), protocol,
                                  label or None)
    else:
        raise ConfigError(f"unknown figure {kind!r}: choose trajectories or qualitative")
    _out.print(f"wrote {path}", markup=False)
