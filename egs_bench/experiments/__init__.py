"""Experiments at scale: sweeps over methods x sequences x seeds x settings, paper tables,
regression checks against a baseline, comparison figures."""
