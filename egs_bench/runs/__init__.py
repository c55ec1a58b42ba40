"""Runs: the run-folder contract every method writes and evaluation reads
(:mod:`~egs_bench.runs.folder`: its files in :mod:`~egs_bench.runs.contract`, the writers' lock,
heartbeat and liveness in :mod:`~egs_bench.runs.coordination`), where run folders go
(:mod:`~egs_bench.runs.locations`) and the method registry (:mod:`~egs_bench.runs.registry`)."""
