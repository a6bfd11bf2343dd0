"""Studies built on the public API: the paper's tables, adaptive sequences,
branches, benchmarks, stability at the extremes, figures."""
