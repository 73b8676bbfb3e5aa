"""Benchmarks: `make bench` runs every `bench_*.py` module here and prints its tables.

Each module exposes ``run() -> None``. Timings are measured and printed, never asserted.
"""
