"""Workflows built on the methods: sweeps, mesh studies, benchmarks, the paper's experiment."""
