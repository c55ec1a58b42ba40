"""Shared helpers of the tests: generated scenes and sequences, fake methods, bag writers, CLI
and subprocess helpers. Not collected by pytest (no ``test_`` modules)."""
