"""Benchmarks (``make bench``): timings and memory, printed and written to bench/results/*.json. Not tests."""
