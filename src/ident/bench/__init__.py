"""Benchmark functions and the optimizer comparison campaign of the paper (Tables 4-9).

``ident.bench.functions``: the 36 table functions (and the appendix order) in a registry;
``ident.bench.campaign``: seeded runs, parallel execution, statistics;
``ident.bench.report``: tables, plots and the Markdown/HTML report;
``ident.bench.paper_tables``: the paper's published numbers, for side-by-side comparison.

The package re-exports the public API of ``ident.bench.functions``.
"""

from __future__ import annotations

from ident.bench.functions import *  # noqa: F403 - the registry's public API, listed once there
from ident.bench.functions import __all__ as __all__
