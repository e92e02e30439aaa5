"""``pgc sweep``: scenes x configurations x steps as tasks, in-process or on Dask distributed, gathered into
one table.

Modules: :mod:`spec` (the sweep file, validated before any work), :mod:`work` (work folders shared by
configurations, the task functions), :mod:`engine` (runs a task graph here or on a Dask cluster: retries,
progress, pinned threads; also used by ``pgc bench --scheduler``), :mod:`table` (records -> JSON, CSV,
HTML and plots) and :mod:`runner` (:func:`~pgc.sweep.runner.run_sweep`). Format: docs/sweeps.md.
"""
