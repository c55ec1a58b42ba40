"""CLI commands of the SLAM area: ``run``, ``list methods`` / ``list-methods`` (thin wrappers)."""

from __future__ import annotations

from pathlib import Path

import typer
from typer._click.core import ParameterSource

from egs_bench.cli.app import QUIET, SEED_MAX, app
from egs_bench.cli.choices import ListWhat, SlamPreset


@app.command("run")
def run_cmd(
    ctx: typer.Context,
    method: str | None = typer.Option(None, "--method", "-m",
                                      help="Method name (see `egs-bench list methods`) or an "
                                           "import path module:attribute (required unless "
                                           "--config)."),
    seq: str | None = typer.Option(None, "--seq", "-s",
                                   help="Sequence folder, or a name under $EGS_BENCH_DATA "
                                        "(default ./data); required unless --config, whose "
                                        "run's sequence it replaces."),
    preset: SlamPreset = typer.Option("auto", "--preset",
                               help="Compute budget: auto (paper on CUDA, cpu on a CPU), "
                                    "paper (the paper's iterations and resolution, GPU-sized) "
                                    "or cpu (same method, reduced resolution/iterations)."),
    out: Path | None = typer.Option(None, "--out", "-o",
                                    help="Run folder to write (default runs/<seq>/<method>)."),
    device: str = typer.Option("auto", "--device",
                               help="auto (CUDA when present), cpu, cuda or cuda:N."),
    seed: int = typer.Option(0, "--seed", min=0, max=SEED_MAX,
                             help="Random seed (CPU runs are deterministic)."),
    max_frames: int | None = typer.Option(None, "--max-frames", min=1,
                                          help="Process only the first N frames (N >= 1)."),
    evaluate: bool = typer.Option(False, "--eval",
                                  help="Evaluate the run afterwards: writes metrics.json and "
                                       "prints the table `eval` prints."),
    quiet: bool = QUIET,
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing run folder at --out (only one "
                                        "written by egs-bench; other files in it are kept)."),
    options: list[str] = typer.Option([], "--set",
                                      help="Override one configuration field, KEY=VALUE "
                                           "(repeatable; methods with a SLAM configuration, "
                                           "their components' own fields included), e.g. "
                                           "--set lambda_d=0.05."),
    config: Path | None = typer.Option(None, "--config",
                                       help="Re-run a stored configuration, RUN/config.yaml: "
                                            "its method, preset, seed, device, frame count "
                                            "and settings (then --preset, --seed, --device, "
                                            "--max-frames and --set may not be given; "
                                            "--method says where to find a method that is not "
                                            "registered under its name)."),
) -> None:
    """Run a SLAM method on a sequence and write its run folder."""
    from egs_bench.cli.eval_cmds import evaluate_and_print
    from egs_bench.datasets.registry import load_sequence
    from egs_bench.errors import ConfigError
    from egs_bench.runs.locations import run_location
    from egs_bench.runs.registry import describe_run, get_method, supports_overwrite, with_options
    from egs_bench.slam.methods import parse_method_options

    if config is not None:
        from egs_bench.slam.methods import rerun

        given = [f"--{name.replace('_', '-')}" for name in RERUN_FIXED
                 if ctx.get_parameter_source(name) is ParameterSource.COMMANDLINE]
        if given:
            raise ConfigError(f"--config re-runs the stored {', '.join(given)}; leave "
                              f"{'it' if len(given) == 1 else 'them'} out")
        run = rerun(config, out, sequence=seq, method=method, progress=not quiet,
                    overwrite=overwrite)
        typer.echo(f"run folder: {run.path}")
        if evaluate:
            evaluate_and_print(run.path, progress=not quiet)
        return
    if method is None or seq is None:
        raise ConfigError("run needs --method and --seq (or --config RUN/config.yaml)")
    chosen = get_method(method)
    m = with_options(chosen, parse_method_options(chosen, options))
    if overwrite and not supports_overwrite(m):
        raise ConfigError(f"method {m.name!r} does not support --overwrite; choose a new --out")
    sequence = load_sequence(seq, progress=not quiet)
    out_dir = out or run_location(Path(), sequence.name, m.name)
    extra: dict = {"overwrite": True} if overwrite else {}
    typer.echo(describe_run(m, sequence, preset=preset, device=device, seed=seed))
    run = m.run(sequence, out_dir, preset=preset, device=device, seed=seed,
                max_frames=max_frames, progress=not quiet, **extra)
    typer.echo(f"run folder: {run.path}")
    if evaluate:
        evaluate_and_print(run.path, progress=not quiet)


#: what a stored configuration fixes (``run --config``); options of these names may not be given
RERUN_FIXED = ("preset", "seed", "device", "max_frames", "options")


def _echo_methods() -> None:
    from egs_bench.runs.registry import available_methods

    for name, desc in available_methods().items():
        typer.echo(f"{name:24s} {desc}")


@app.command("list")
def list_cmd(
    what: ListWhat = typer.Argument(..., help="What to list: methods (SLAM methods) or scenes "
                                         "(built-in synthetic scenes)."),
) -> None:
    """List registered things: `egs-bench list methods`, `egs-bench list scenes`."""
    if what == "methods":
        _echo_methods()
    else:  # scenes (typer refuses other values)
        from egs_bench.datasets.synthetic import list_scenes

        for name, desc in list_scenes().items():
            typer.echo(f"{name:24s} {desc}")


@app.command("list-methods")
def list_methods_cmd() -> None:
    """List the registered SLAM methods (alias of `egs-bench list methods`)."""
    _echo_methods()
