"""CLI commands of this area (registered on the shared app by import)."""

from egs_bench.cli.app import app  # noqa: F401
