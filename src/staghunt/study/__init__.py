"""Studies: many plans at once. A sweep spec (:mod:`~staghunt.study.spec`) expands into tasks
(:mod:`~staghunt.study.tasks`, one plan plus its certificate each), run by an executor
(:mod:`~staghunt.study.executor`: in-process, or a Dask cluster) and stored append-only in a
Parquet dataset (:mod:`~staghunt.study.store`); :func:`~staghunt.study.sweep.run_sweep` ties
them together. ``staghunt compare`` runs its plans through the same task function and executors.

Layering: beside :mod:`staghunt.analysis` (which imports this package for ``compare``); it
imports the library layers below it, never :mod:`staghunt.cli` nor :mod:`staghunt.analysis`.
"""
