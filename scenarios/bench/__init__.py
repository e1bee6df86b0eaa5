"""Benchmarks, one module per ``offtrack bench`` command, each returning one JSON-ready dict of speed figures."""
