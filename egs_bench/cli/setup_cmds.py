"""CLI command of the installation: ``warm-up`` (run by ``make setup``)."""

from __future__ import annotations

from egs_bench.cli.app import app
from egs_bench.cli.app import out as _out
from egs_bench.errors import EXIT_INTERNAL


@app.command("warm-up")
def warm_up() -> None:
    """Compile the numba kernels into the cache (NUMBA_CACHE_DIR) so that a first run compiles
    nothing; run once after installing or upgrading."""
    import typer

    from egs_bench.warmup import warm_up as warm

    report = warm(say=_out.print)
    _out.print(f"numba kernels: {len(report.compiled)} compiled, {len(report.loaded)} already "
               f"cached ({report.seconds:.0f} s)")
    for name in report.missing:
        _out.print(f"not warmed (no warm-up path calls it): {name}")
    if report.missing:
        raise typer.Exit(EXIT_INTERNAL)
