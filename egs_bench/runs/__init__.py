"""Runs: the run-folder contract every method writes and evaluation reads
(:mod:`~egs_bench.runs.folder`), and the method registry (:mod:`~egs_bench.runs.registry`)."""
