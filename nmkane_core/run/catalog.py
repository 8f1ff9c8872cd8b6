"""The catalog of what a run can ask for: systems, integrators, projections, limits."""

from __future__ import annotations

from ..errors import InputError
from ..integrate.methods import INTEGRATORS
from ..integrate.projection import PRESETS
from ..kernel.built import built
from ..kernel.forces import compile_forces
from ..schema import LIMITS
from .initial import default_state
from .registry import get_system, system_names

__all__ = ["catalog"]


def catalog() -> dict:
    """Systems with parameters, variants, constraint names, integrators, limits (for /api/systems)."""
    out = []
    for name in system_names():
        s = get_system(name)
        b = built(s)
        out.append(
            {
                "name": s.name,
                "title": s.title,
                "description": s.description,
                "option": s.option,
                s.option + "s": list(s.variants),
                "default_" + s.option: s.default_variant,
                "parameters": [
                    {
                        "name": p.name,
                        "default": p.default,
                        "min": p.min,
                        "max": p.max,
                        "min_inclusive": p.min_inclusive,
                        "unit": p.unit,
                        "description": p.description,
                    }
                    for p in s.parameters
                ],
                "coordinates": list(b.coordinates),
                "speeds": list(b.speeds),
                "independent": list(b.independent),
                "default_initial": default_state(s),
                "constraint_names": {v: list(b.constraint_names(v)) for v in s.variants},
                "forces": _forces(s),
                "what_to_try": s.what_to_try,
                "stability": None
                if s.stability is None
                else {  # what `nmkane stability` sweeps by default
                    "over": s.stability.over,
                    "unit": s.stability.unit,
                    "start": s.stability.start,
                    "stop": s.stability.stop,
                    "count": s.stability.count,
                    "keep": list(s.stability.keep),
                    "reference": dict(s.stability.reference),
                },
                "defaults": {
                    "dt": s.default_dt,
                    "t_final": s.default_t_final,
                    "integrator": s.default_integrator,
                    "gamma": s.default_gamma,
                    "gamma1": s.default_gamma1,
                    "gamma2": s.default_gamma2,
                },
            }
        )
    return {
        "systems": out,
        "integrators": {k: v.description for k, v in INTEGRATORS.items()},
        "projections": list(PRESETS),
        "limits": dict(LIMITS),
    }


def _forces(system) -> dict:
    """Variant → the physical forces it declares at points (name, component labels and the
    reported names NAME.LABEL, route, what they act on, description), and the drawing hints."""
    out: dict = {}
    for v in system.variants:
        try:
            compiled = compile_forces(system, v)
        except InputError as e:  # a plug-in's broken declaration: said here, raised by its runs
            out[v] = [{"error": str(e)}]
            continue
        out[v] = (
            []
            if compiled is None
            else [
                {
                    "name": f["name"],
                    "components": list(f["columns"]),
                    "labels": list(f["labels"]),
                    "route": f["route"],
                    "on": f["on"],
                    "description": f["description"],
                    "unit": "N",
                    "shown": compiled.show,
                }
                for f in compiled.forces
            ]
        )
    return out
