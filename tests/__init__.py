"""The egs-bench test suite: a package, so that test modules import ``tests.helpers``."""
