"""``nmkane bench``: the kernels' speed, measured (:mod:`.rows`), and the sweeps' (:mod:`.sweep`)."""

from .rows import format_table, main, run_bench

__all__ = ["format_table", "main", "run_bench"]
