"""``pgc bench``: a matrix of implementations per role, timed and compared with a reference (speed against error).

Modules: :mod:`matrix` (the TOML matrix, validated against the registry), :mod:`measure` (timing and peak
memory), :mod:`workloads` (one module per role: the tiny/default workload, its reference and its errors),
:mod:`records` (the record schema, JSON and CSV), :mod:`report` (plots and HTML from records only) and
:mod:`runner` (runs a matrix and writes everything).
"""
