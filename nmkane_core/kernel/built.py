"""What nmkane builds from a system's declaration: its models, derivations and compiled kernels.

A :class:`~nmkane_core.declare.system.System` is what a user wrote and nothing else.  The
things made from it — each variant's :class:`~nmkane_core.symbolic.model.MechanicalModel`
(built by the variant's function: sympy work), its
:class:`~nmkane_core.symbolic.derivation.Derivation` (the paper's steps 1–5), its compiled
kernel and :class:`~nmkane_core.kernel.info.ModelInfo`, and the key that names the kernel
in the on-disk cache — are made once, on first use, and kept here in a :class:`Built`
(``built(system)``).  A kernel found in the disk cache is loaded without building the model
at all, so a later process needs no sympy.

The names a user sets and reads (coordinates, speeds, the independent values) come from the
models, so they are here too.
"""

from __future__ import annotations

import inspect
import threading
import weakref
from typing import TYPE_CHECKING, Any

from ..errors import InputError

if TYPE_CHECKING:  # sympy is imported only when a model is actually built
    import numpy as np

    from ..declare.system import System
    from ..symbolic.derivation import Derivation
    from ..symbolic.model import MechanicalModel
    from .info import ModelInfo

__all__ = ["Built", "built"]


class Built:
    """The models, derivations and kernels of one system, each made once per variant.

    ``variant=None`` everywhere means the system's default variant."""

    def __init__(self, system: System):
        self.system = system
        self._models: dict[str, MechanicalModel] = {}
        self._derivations: dict[str, Derivation] = {}
        self._kernels: dict[str, tuple[Any, ModelInfo]] = {}
        self._lock = threading.RLock()
        #: variant → (q_dependent, u_independent) picked numerically for a model that declares no
        #: partition (set by the run layer: nmkane_core.run.partition)
        self.partitions: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {}

    # ------------------------------------------------------------------ models, derivations, kernels
    def model(self, variant: str | None = None) -> MechanicalModel:
        """The symbolic description of a variant (built once; needs sympy)."""
        variant = self.system.check_variant(variant)
        with self._lock:
            if variant not in self._models:
                self._models[variant] = self._build_model(variant)
            return self._models[variant]

    def _build_model(self, variant: str) -> MechanicalModel:
        name = self.system.name
        try:
            model = self.system.variants[variant]()
        except InputError:
            raise
        except Exception as e:
            raise InputError(
                f"{name}: variant {variant}",
                type(e).__name__,
                "a function that builds a MechanicalModel",
                f"building it failed: {e}",
            ) from e
        if not hasattr(model, "q") or not hasattr(model, "Q"):
            raise InputError(f"{name}: variant {variant}", type(model).__name__, "a MechanicalModel", "not a model")
        return model

    def derivation(self, variant: str | None = None) -> Derivation:
        """The paper's procedure applied to a variant (symbolic, once)."""
        from ..symbolic.derivation import derive

        variant = self.system.check_variant(variant)
        with self._lock:
            if variant not in self._derivations:
                self._derivations[variant] = derive(self.model(variant))
            return self._derivations[variant]

    def kernel(self, variant: str | None = None) -> tuple[Any, ModelInfo]:
        """(compiled kernel module, :class:`ModelInfo`) of a variant: loaded from the on-disk
        cache when the model is unchanged (no sympy work at all), otherwise derived,
        generated, compiled and cached."""
        found = self._kernels.get(self.system.default_variant if variant is None else variant)
        if found is not None:  # loaded before: no lock (a run asks for it a few dozen times)
            return found
        from .loader import kernel

        variant = self.system.check_variant(variant)
        with self._lock:
            if variant not in self._kernels:
                self._kernels[variant] = kernel(
                    self.key(variant), lambda: self.derivation(variant), (self.system.name, variant)
                )
            return self._kernels[variant]

    def module(self, variant: str | None = None):
        """The compiled kernel of a variant (a :class:`~nmkane_core.kernel.cmodel.CModel`)."""
        return self.kernel(variant)[0]

    def info(self, variant: str | None = None) -> ModelInfo:
        """What the numeric side knows of a variant's model: names and counts (no sympy)."""
        return self.kernel(variant)[1]

    # ------------------------------------------------------------------ the kernel's key
    def key(self, variant: str | None = None) -> str | None:
        """A key that changes whenever the variant's compiled kernel would.

        It hashes the files that define the variant (no sympy needed); for a model typed
        interactively or given as an object it hashes the model's expressions instead.
        Other caches derived from a model (the web app's rendered matrices, the compiled
        visuals and events) key on it."""
        from .loader import fingerprint, model_fingerprint

        variant = self.system.check_variant(variant)
        files = self._files(variant)
        if files is not None:
            return fingerprint(self.system.name, variant, files, extra=self._factory_identity(variant))
        return model_fingerprint(self.system.name, variant, self.model(variant))

    def _files(self, variant: str) -> tuple[str, ...] | None:
        """The files a variant is built from (None: not known, e.g. typed interactively)."""
        if variant in self.system.given_models:
            return None
        try:
            f = inspect.getsourcefile(self.system.variants[variant])
        except TypeError:
            f = None
        if f is None or f.startswith("<"):
            return None
        return (f, *self.system.source_files)

    def _factory_identity(self, variant: str) -> str:
        """Which function of those files builds the variant: its name, code and simple closure
        values (two models defined in one file, or one function called with other arguments
        in a lambda, must not share a cached kernel)."""
        fn = self.system.variants[variant]
        code = getattr(fn, "__code__", None)
        parts = [getattr(fn, "__qualname__", repr(type(fn)))]
        if code is not None:
            parts.append(code_identity(code))
        for cell in getattr(fn, "__closure__", None) or ():
            try:
                value = cell.cell_contents
            except ValueError:
                continue
            if isinstance(value, (str, int, float, bool, tuple)):
                parts.append(repr(value))
        return "\0".join(parts)

    # ------------------------------------------------------------------ names, from the models
    @property
    def coordinates(self) -> tuple[str, ...]:
        return self.info(self.system.completion_variant).q

    @property
    def speeds(self) -> tuple[str, ...]:
        return self.info(self.system.completion_variant).u

    @property
    def independent(self) -> tuple[str, ...]:
        """The values a user sets: coordinates not solved from holonomic constraints and u_I (of
        the declared partition, or of the one picked numerically: ``partitions``)."""
        variant = self.system.completion_variant
        info = self.info(variant)
        q_dep, u_ind = self.partitions.get(variant, (info.q_dependent, info.u_independent))
        return tuple(q for q in info.q if q not in q_dep) + (u_ind if info.m else info.u)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.coordinates + self.speeds

    def constraint_names(self, variant: str | None = None) -> tuple[str, ...]:
        """Names of the reported violations: the constraints, then any monitors."""
        return self.info(variant).viol_names

    def param_vector(self, variant: str | None, params) -> np.ndarray:
        """The numeric parameter vector of a variant's kernel, bound by name (the model's order)."""
        import numpy as np

        return np.array([float(params[name]) for name in self.info(variant).params], dtype=float)

    def check_params(self, variant: str) -> None:
        """The variant's parameter symbols must be exactly the declared parameters."""
        model_params = self.info(variant).params
        declared = self.system.param_names
        missing = [p for p in model_params if p not in declared]
        extra = [p for p in declared if p not in model_params]
        if missing or extra:
            what = []
            if missing:
                what.append(f"declare {', '.join(missing)}")
            if extra:
                what.append(f"remove {', '.join(extra)} (no symbol of the model)")
            raise InputError(
                f"{self.system.name}: parameters",
                list(declared),
                f"the parameter symbols of the {variant} {self.system.option}: {', '.join(model_params)}",
                "; ".join(what),
            )


_BUILT: dict[int, tuple[weakref.ref, Built]] = {}
_LOCK = threading.Lock()


def built(system: System) -> Built:
    """The :class:`Built` of a system (made on first use, kept while the system lives)."""
    with _LOCK:
        entry = _BUILT.get(id(system))
        if entry is not None and entry[0]() is system:
            return entry[1]
        for k in [k for k, (ref, _) in _BUILT.items() if ref() is None]:
            del _BUILT[k]  # systems gone: their ids may be reused
        made = Built(system)
        _BUILT[id(system)] = (weakref.ref(system), made)
        return made


def code_identity(code) -> str:
    """A function's compiled code as text, without the path of its file (nested functions'
    too): the same model in another checkout of the repository, or after the folder moved,
    keeps its cache keys (the files' text is hashed beside it)."""
    import marshal
    import types

    def pathless(c: types.CodeType) -> types.CodeType:
        consts = tuple(pathless(k) if isinstance(k, types.CodeType) else k for k in c.co_consts)
        return c.replace(co_filename="", co_consts=consts)

    return marshal.dumps(pathless(code)).hex()
