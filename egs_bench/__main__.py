"""``python -m egs_bench`` runs the ``egs-bench`` command."""

from egs_bench.cli import run

if __name__ == "__main__":
    run()
