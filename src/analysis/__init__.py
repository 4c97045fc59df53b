"""Analysis: the gap and its evidence, candidate effects, the model search, reports, error models.

One sub-package a job, in import layers (pyproject.toml's contract; each imports only from those
below it). Each has a public face: its ``__init__`` re-exports under ``__all__`` the names other
packages use, and its modules are private (``_name``, imported only inside it).

``search`` | ``report``
    The model search: which candidates explain a gap, chosen on the choose split | reports and
    figures of result datasets (the paper-style report, variant comparison, error-model bands).
``candidates`` | ``errormodel``
    The candidate effects, their fits and the registry keyed by effect name | error models for
    control software.
``gap``
    Where the gap lies, its size and its evidence; the comparable items and evidence channels.
``thresholds``, ``paper``
    The diagnosis's units and thresholds, each defined once, and the paper's reference numbers
    (Table 2, the high-precision thresholds): modules every package may import.
"""
