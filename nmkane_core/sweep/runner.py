"""A sweep from start to finish: check the specification, prepare the kernels, stream the
runs through an executor into the output, skipping points already there (resume)."""

from __future__ import annotations

import contextlib
import itertools
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..errors import InputError
from ..kernel.built import built
from .executors import batch_size, make_executor
from .output import SweepWriter
from .spec import SweepSpec, apply_point, point_key

__all__ = ["SweepResult", "check_spec", "constraint_columns", "run_sweep"]

VALIDATE_VALUES = 64  # an axis with more values is checked at its ends and a few inside
_VARIANT_FIELDS = ("model", "formulation")


@dataclass
class SweepResult:
    """What a sweep did: runs in the specification, skipped (already in the output), run now."""

    total: int
    skipped: int
    ran: int = 0
    wall_s: float = 0.0
    statuses: dict[str, int] = field(default_factory=dict)
    workers: int = 1
    executor: str = "serial"


def _option(spec: SweepSpec, name: str) -> str:
    return "--sample" if name in spec.sample else "--grid"


def _axis_values(spec: SweepSpec):
    for a in spec.axes:
        vals = a.values
        if len(vals) > VALIDATE_VALUES:
            step = len(vals) / (VALIDATE_VALUES - 1)
            vals = tuple(vals[min(len(vals) - 1, round(i * step))] for i in range(VALIDATE_VALUES))
        yield a.name, vals
    yield from spec.sample.items()


def check_spec(base: dict, spec: SweepSpec) -> None:
    """Every varied value (at most `VALIDATE_VALUES` per axis; the ends of a sample
    range) is resolved against the base settings: a value the system refuses is an
    [`InputError`][nmkane_core.InputError] naming the option, before any run starts."""
    from ..run.plan import resolve

    resolve(base)
    for name, values in _axis_values(spec):
        for v in values:
            try:
                resolve(apply_point(base, {name: v}))
            except InputError as e:
                raise InputError(f"{_option(spec, name)} {name}", v, e.allowed, e.reason) from None


def _variants(base: dict, spec: SweepSpec) -> list[dict]:
    """One settings dict per variant × integrator the sweep uses (to load their kernels)."""
    choices = [(a.name, a.values) for a in spec.axes if a.name in (*_VARIANT_FIELDS, "integrator")]
    names = [n for n, _ in choices]
    combos = itertools.product(*[v for _, v in choices])
    return [apply_point(base, dict(zip(names, combo, strict=True))) for combo in combos]


def constraint_columns(base: dict, spec: SweepSpec) -> list[str]:
    """Constraint names over every variant the sweep uses, in first-seen order."""
    from ..run.plan import resolve

    out: list[str] = []
    for s in _variants(base, spec):
        plan = resolve(s)
        for c in built(plan.system).constraint_names(plan.variant):
            if c not in out:
                out.append(c)
    return out


def run_sweep(
    base: dict,
    spec: SweepSpec,
    out,
    *,
    systems=(),
    dask: str | None = None,
    workers: int | None = None,
    progress: bool | None = None,
    time_limit: float | None = None,
    resume: bool = True,
    on_rows: Callable[[list[dict]], None] | None = None,
    executor=None,
) -> SweepResult:
    """Run every point of ``spec`` over ``base`` run settings, rows streamed to ``out``: a file
    name (`SweepWriter`) or any object with ``done`` (keys already there) and
    ``write(rows)``, e.g. the service's store.

    ``systems``: plug-in system files or modules (loaded by every worker); ``dask``: None
    (local processes, ``workers`` of them; 1 = this process), ``local``, ``local:N`` or a
    scheduler address; ``resume``: skip points already in ``out`` (False: start the file
    anew); ``on_rows``: called with each batch of rows as it is written; ``executor``: an
    executor to use instead of making one (left open)."""
    from ..run.plan import resolve
    from ..run.simulate import prepare

    check_spec(base, spec)
    warm = _variants(base, spec)
    for s in warm:  # compile (first use) here, once, not in every worker
        prepare(resolve(s))
    constraints = constraint_columns(base, spec)
    names = spec.names
    total = len(spec)
    sink = SweepWriter(out, names, constraints, resume=resume) if isinstance(out, (str, os.PathLike)) else None
    with sink if sink is not None else contextlib.nullcontext(out) as writer:
        done = writer.done
        todo = (p for p in spec.points() if point_key(p, names) not in done) if done else spec.points()
        skipped = min(len(done), total)
        result = SweepResult(total, skipped)
        if progress is None:
            progress = sys.stderr.isatty()
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=total, initial=skipped, unit="run", desc="sweep", smoothing=0.05)
        own = executor is None
        ex = executor or make_executor(dask, workers, systems=systems, warm=tuple(warm), time_limit=time_limit)
        result.workers, result.executor = ex.workers, ex.name
        t0 = time.perf_counter()
        try:
            size = batch_size(total - skipped, ex.workers)
            for rows in ex.rows(base, todo, size):
                writer.write(rows)
                result.ran += len(rows)
                for r in rows:
                    result.statuses[r["status"]] = result.statuses.get(r["status"], 0) + 1
                if bar is not None:
                    bar.update(len(rows))
                if on_rows is not None:
                    on_rows(rows)
        finally:
            result.wall_s = time.perf_counter() - t0
            if bar is not None:
                bar.close()
            if own:
                ex.close()
    return result
