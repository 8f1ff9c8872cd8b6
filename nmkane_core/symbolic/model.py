"""A mechanical model described with sympy, in the paper's terms.

A `MechanicalModel` is pure description: the generalized coordinates ``q`` and
speeds ``u``, the kinematical equations (1) ``q̇ = C(q,t) u + D(q,t)``, the equations of
the *holonomic* (unconstrained) system (41)–(43) ``Q(q,t) u̇ = P(q,u,t)``, the
nonholonomic constraints φ(q,u,t) = 0 (possibly nonlinear in u), the holonomic
constraints ψ(q,t) = 0 and the partition u = [u_I, u_D] (16).  Nothing here derives
anything; [`derive`][nmkane_core.derive] does that, once per model.

Two ways to give the holonomic equations:

* explicitly, ``Q`` and ``P`` (the paper's (99)–(100) for example);
* from sympy.physics.mechanics bodies, particles and loads with
  `MechanicalModel.from_mechanics`, which runs ``KanesMethod`` on the
  *unconstrained* system (no velocity constraints) to obtain Q (``mass_matrix``) and P
  (``forcing``).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp
from sympy.core.function import AppliedUndef

from ..errors import InputError

__all__ = ["MechanicalModel", "plain_symbols"]


def plain_symbols(names: str | Sequence[str]) -> tuple[sp.Symbol, ...]:
    """Real sympy symbols, the kind a model is written in.

    Parameters
    ----------
    names : str or sequence of str
        Names as `sympy.symbols` takes them: ``"x y z"``, ``"u1:4"`` or a list.

    Returns
    -------
    tuple of sympy.Symbol
        One real symbol per name (a tuple even for one name: ``(z,) = plain_symbols("z")``).
    """
    syms = sp.symbols(names, real=True)
    return tuple(syms) if isinstance(syms, (tuple, list)) else (syms,)


def _as_matrix(value, rows: int | None = None) -> sp.Matrix:
    m = sp.Matrix(value)
    if rows is not None and m.shape[0] != rows and m.shape == (1, rows):
        m = m.T
    return m


@dataclass(frozen=True, kw_only=True)
class MechanicalModel:
    """A constrained system: kinematics, holonomic equations, constraints, partition.

    Every argument is keyword-only; all expressions are sympy expressions in ``q``, ``u``,
    ``params`` and ``t`` (nothing else may appear in them: construction refuses any other
    symbol, a function of time such as a ``dynamicsymbol`` and a derivative, naming the
    field and the symbol; the symbols of ``q``, ``u``, ``params`` and ``t`` are all distinct,
    by name too).

    Parameters
    ----------
    q, u : tuple of sympy.Symbol
        Generalized coordinates and speeds, n of each (plain real sympy symbols, see
        [`plain_symbols`][nmkane_core.plain_symbols]; their names are the state names of runs).
    params : tuple of sympy.Symbol
        Parameter symbols, in the order numeric parameter vectors use; every symbol of the
        expressions that is not in ``q``, ``u`` or ``t`` must be one of them.
    C, D : sympy.Matrix
        (1) ``q̇ = C u + D``; ``C`` n×n invertible, ``D`` n×1 (``sp.eye(n)``,
        ``sp.zeros(n, 1)`` when the speeds are the coordinates' rates).
    Q, P : sympy.Matrix
        (42) the holonomic (unconstrained) system ``Q u̇ = P``: Q n×n symmetric positive
        definite, P n×1 (applied and inertia forces).
    nonholonomic : mapping of str to sympy.Expr, optional
        Named constraints φ_i(q, u, t) = 0: any smooth function of the speeds —
        linear, polynomial, or not polynomial at all (square roots such as the speed
        along a path √(u1² + u2²) − v, trigonometric, rational, exponential).  Where a
        constraint's expression is not defined (the argument of a square root below
        zero, a zero denominator) a run ends with a status.
    holonomic : mapping of str to sympy.Expr, optional
        Named ψ_i(q, t) = 0.
    u_independent : tuple of sympy.Symbol, optional
        u_I of (16); the remaining speeds (in the order of ``u``) are u_D, solved from
        the constraints: choose them so that J2 = ∂[φ; ψ̇]/∂u_D is invertible along the
        motion (runs report where it is not, status ``singular``).  Optional: left out
        (with constraints), the partition is picked by pivoting on the constraint Jacobian.
        More constraints than dependent speeds (n − p < m) declares redundant equations:
        the number of independent speeds is then n − rank, checked numerically at the
        default state (``docs/closed-loops.md``).
    energy : sympy.Expr, optional
        Optional total energy E(q, u, t), reported with its drift (diagnostics only).
    outputs : mapping of str to sympy.Expr, optional
        Optional extra reported quantities, name → expression of q, u, t (e.g. a minimal
        formulation reports the coordinates and speeds it does not integrate).
    monitors : mapping of str to sympy.Expr, optional
        Optional extra named quantities reported beside the constraint values, e.g. the
        surface equation for a minimal formulation that satisfies it by construction.
    q_dependent : tuple of sympy.Symbol, optional
        Coordinates solved from the holonomic constraints when completing an initial
        state (one per holonomic constraint); chosen by pivoting on ∂ψ/∂q when not given.
    singular_positions : bool, optional
        Declare that the motion may pass positions where the constraints lose rank (a
        mechanism through a dead centre or a bifurcation: the N-four-bar at its horizontal
        position).  Kept for compatibility: every model with constraints now has the
        rank-robust solve, a declared partition being the preferred one
        (``docs/closed-loops.md`` §7.5).
    name : str, optional
        Optional short name (``"nonlinear"``, ``"linear"``, ``"nonminimal"``), shown in
        generated code and messages; a system names its variants itself.
    t : sympy.Symbol, optional
        The time symbol (default ``Symbol("t", real=True)``).
    description : str, optional
        Optional text about the model.

    Raises
    ------
    InputError
        Naming the field, the value and what is allowed, when the shapes or symbols do not
        fit (a ``ValueError``).
    """

    name: str = ""
    q: tuple[sp.Symbol, ...]
    u: tuple[sp.Symbol, ...]
    params: tuple[sp.Symbol, ...]
    C: sp.Matrix
    D: sp.Matrix
    Q: sp.Matrix
    P: sp.Matrix
    nonholonomic: Mapping[str, sp.Expr] = field(default_factory=dict)
    holonomic: Mapping[str, sp.Expr] = field(default_factory=dict)
    u_independent: tuple[sp.Symbol, ...] = ()
    energy: sp.Expr | None = None
    outputs: Mapping[str, sp.Expr] = field(default_factory=dict)
    q_dependent: tuple[sp.Symbol, ...] = ()
    monitors: Mapping[str, sp.Expr] = field(default_factory=dict)
    singular_positions: bool = False
    t: sp.Symbol = sp.Symbol("t", real=True)  # noqa: RUF009 (an immutable symbol, shared on purpose)
    description: str = ""

    def __post_init__(self):
        n = len(self.q)
        object.__setattr__(self, "q", tuple(self.q))
        object.__setattr__(self, "u", tuple(self.u))
        object.__setattr__(self, "params", tuple(self.params))
        object.__setattr__(self, "C", _as_matrix(self.C))
        object.__setattr__(self, "D", _as_matrix(self.D, n))
        object.__setattr__(self, "Q", _as_matrix(self.Q))
        object.__setattr__(self, "P", _as_matrix(self.P, n))
        object.__setattr__(self, "nonholonomic", dict(self.nonholonomic))
        object.__setattr__(self, "holonomic", dict(self.holonomic))
        object.__setattr__(self, "outputs", dict(self.outputs))
        object.__setattr__(self, "monitors", dict(self.monitors))
        object.__setattr__(self, "u_independent", tuple(self.u_independent))
        object.__setattr__(self, "q_dependent", tuple(self.q_dependent))
        self.validate()

    # ------------------------------------------------------------------ checks
    def validate(self) -> None:
        """Check the symbols, shapes, partition and the symbols of every expression (run on creation).

        Raises
        ------
        InputError
            Naming the model's field (``q``, ``P[1]``, ``energy``, ``nonholonomic['speed']``),
            the offending value and what is allowed.
        """
        self._check_symbols()
        n = len(self.q)
        if len(self.u) != n:
            raise InputError(
                self._where("u"), self._names(self.u), f"one speed per coordinate ({n})", f"{len(self.u)} speeds"
            )
        for label, mat, shape in (
            ("C", self.C, (n, n)),
            ("D", self.D, (n, 1)),
            ("Q", self.Q, (n, n)),
            ("P", self.P, (n, 1)),
        ):
            if mat.shape != shape:
                raise InputError(self._where(label), mat.shape, f"shape {shape}", "wrong shape")
        m = self.m
        p = len(self.u_independent)
        # p = 0: the library picks the partition; p + m > n: redundant equations (the rank,
        # n − p, is checked numerically at the default state: see docs/closed-loops.md)
        if m and p and (p >= n or p + m < n):
            raise InputError(
                self._where("u_independent"),
                self._names(self.u_independent),
                f"at least one dependent speed and at most m = {m} (n − p ≤ m; more constraints than "
                "dependent speeds means redundant ones), or u_independent left out",
                f"{m} constraints and {p} independent speeds for {n} speeds",
            )
        for label, syms, among, what in (
            ("u_independent", self.u_independent, self.u, "speeds"),
            ("q_dependent", self.q_dependent, self.q, "coordinates"),
        ):
            names = self._names(syms)
            if len(set(names)) != len(names):
                twice = sorted({s for s in names if names.count(s) > 1})
                raise InputError(self._where(label), names, f"{what} of the model, each once", f"{twice} repeated")
            unknown = [s for s in syms if s not in among]
            if unknown:
                raise InputError(
                    self._where(label),
                    self._names(unknown),
                    f"{what} of the model: {', '.join(self._names(among))}",
                    f"not {what} of the model",
                )
        dup = set(self.nonholonomic) & set(self.holonomic)
        if dup:
            raise InputError(
                self._where("holonomic"), sorted(dup), "names not used by a nonholonomic constraint", "names used twice"
            )
        self._check_expressions()

    def _where(self, label: str) -> str:
        """The field path of an error: ``model 'nonlinear': P[1]`` (``model: P[1]`` unnamed)."""
        return f"model {self.name!r}: {label}" if self.name else f"model: {label}"

    @staticmethod
    def _names(syms: Iterable) -> list[str]:
        return [str(s) for s in syms]

    def _check_symbols(self) -> None:
        """q, u and params are sympy Symbols, t a Symbol, and every name appears once among them."""
        hint = "plain sympy symbols (plain_symbols(...)); a model of dynamicsymbols: MechanicalModel.from_mechanics"
        for label, syms in (("q", self.q), ("u", self.u), ("params", self.params), ("t", (self.t,))):
            for s in syms:
                if not isinstance(s, sp.Symbol):
                    raise InputError(self._where(label), str(s), hint, "not a symbol")
        owner: dict[str, str] = {}
        role = {"q": "a coordinate", "u": "a speed", "params": "a parameter", "t": "the time symbol"}
        for label, syms in (("q", self.q), ("u", self.u), ("params", self.params), ("t", (self.t,))):
            names = self._names(syms)
            counts = Counter(names)
            for s in syms:
                first = owner.setdefault(s.name, label)
                if first == label and counts[s.name] == 1:
                    continue
                if first == label:
                    why = f"{s.name} appears {counts[s.name]} times in {label}"
                else:
                    why = f"{s.name} is {role[label]} and already {role[first]} ({first})"
                value = names if label != "t" else s.name
                raise InputError(
                    self._where(label),
                    value,
                    "distinct symbols: each coordinate, speed and parameter named once, none of them "
                    f"named like the time symbol {self.t}",
                    why,
                )

    def _expressions(self) -> Iterator[tuple[str, sp.Expr, bool]]:
        """Every expression of the model: (its field, itself, whether speeds may appear in it)."""
        for label, mat in (("C", self.C), ("D", self.D), ("Q", self.Q), ("P", self.P)):
            rows, cols = mat.shape
            for i in range(rows):
                for j in range(cols):
                    yield (f"{label}[{i}]" if cols == 1 else f"{label}[{i}, {j}]"), mat[i, j], True
        for name, e in self.nonholonomic.items():
            yield f"nonholonomic[{name!r}]", e, True
        for name, e in self.holonomic.items():
            yield f"holonomic[{name!r}]", e, False  # ψ(q, t)
        if self.energy is not None:
            yield "energy", self.energy, True
        for name, e in self.outputs.items():
            yield f"outputs[{name!r}]", e, True
        for name, e in self.monitors.items():
            yield f"monitors[{name!r}]", e, True

    def _check_expressions(self) -> None:
        """Every expression uses q, u (not in ψ), params and t only: no other symbol, no function
        of time (a ``dynamicsymbol`` left in) and no derivative — the generated code knows
        nothing else (another name would fail there with a ``NameError``, at the first run)."""
        q, params = ", ".join(self._names(self.q)), ", ".join(self._names(self.params)) or "none"
        speeds = f"the speeds ({', '.join(self._names(self.u))}), "
        by_name = {s.name: s for s in (*self.q, *self.u, *self.params, self.t)}
        allowed_q = set(self.q) | set(self.params) | {self.t}
        allowed_qu = allowed_q | set(self.u)
        for label, expr, with_u in self._expressions():
            try:
                e = sp.sympify(expr)
            except (sp.SympifyError, TypeError):
                raise InputError(self._where(label), expr, "a sympy expression", "not an expression") from None
            if not isinstance(e, sp.Basic):
                raise InputError(self._where(label), expr, "a sympy expression", "not an expression")
            allowed = (
                f"expressions of the coordinates ({q}), {speeds if with_u else ''}the time {self.t} and the "
                f"parameters ({params}); a symbol that stands for a number belongs in params"
            )
            funcs = sorted(map(str, e.atoms(AppliedUndef, sp.Derivative)))
            if funcs:
                raise InputError(
                    self._where(label),
                    funcs,
                    allowed + " (a model of dynamicsymbols: MechanicalModel.from_mechanics converts them)",
                    "a function of time or a derivative, which the generated code cannot evaluate",
                )
            extra = e.free_symbols - (allowed_qu if with_u else allowed_q)
            if not extra:
                continue
            names = sorted(s.name for s in extra)
            in_psi = sorted(s.name for s in extra & set(self.u))
            unknown = sorted(s.name for s in extra - set(self.u))
            whys = [f"ψ(q, t) may not depend on the speeds {', '.join(in_psi)}"] if in_psi else []
            if unknown:
                whys.append(f"unknown symbol{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}")
            twins = [s for s in unknown if s in by_name]
            if twins:
                whys.append(
                    f"{', '.join(twins)}: named like a symbol of the model but with other assumptions "
                    "(make every symbol with plain_symbols, or with the same assumptions)"
                )
            raise InputError(self._where(label), names, allowed, "; ".join(whys))

    # ------------------------------------------------------------- properties
    @property
    def n(self) -> int:
        """Number of coordinates (and of speeds)."""
        return len(self.q)

    @property
    def m(self) -> int:
        """Number of constraints, nonholonomic plus holonomic."""
        return len(self.nonholonomic) + len(self.holonomic)

    @property
    def u_dependent(self) -> tuple[sp.Symbol, ...]:
        """u_D of (16): the speeds not in u_I, in the order of ``u``."""
        if not self.m:
            return ()
        return tuple(s for s in self.u if s not in self.u_independent)

    @property
    def constraint_names(self) -> tuple[str, ...]:
        """The constraints' names, nonholonomic first, then holonomic (the rows of φ)."""
        return tuple(self.nonholonomic) + tuple(self.holonomic)

    @property
    def state_names(self) -> tuple[str, ...]:
        """The names of q then u: the state names of runs (``run.state[name]``)."""
        return tuple(str(s) for s in self.q + self.u)

    # ------------------------------------------------------------ from mechanics
    @classmethod
    def from_mechanics(
        cls,
        name: str = "",
        *,
        q,
        u,
        kd_eqs,
        bodies,
        loads,
        frame,
        params,
        nonholonomic: Mapping[str, sp.Expr] | None = None,
        holonomic: Mapping[str, sp.Expr] | None = None,
        u_independent: Iterable = (),
        energy=None,
        outputs: Mapping[str, sp.Expr] | None = None,
        q_dependent: Iterable = (),
        monitors: Mapping[str, sp.Expr] | None = None,
        singular_positions: bool = False,
        description: str = "",
        rotations: Iterable = (),
    ) -> MechanicalModel:
        """Build a model from sympy.physics.mechanics bodies, particles and loads.

        ``KanesMethod`` is run on the *unconstrained* system, so its ``mass_matrix`` is the
        holonomic Q and its ``forcing`` the holonomic P of (42); the constraints are then
        attached exactly as for an explicit model.  Constraint and energy expressions may
        use the dynamicsymbols; they are converted to plain symbols.

        Parameters
        ----------
        name : str, optional
            As for the model.
        q, u : sequence of sympy.Function
            The coordinates and speeds as ``dynamicsymbols``.
        kd_eqs : sequence of sympy.Expr
            The kinematical differential equations (``q' - u`` ...), solved for q̇ = C u + D (1).
        bodies : sequence
            ``RigidBody`` and ``Particle`` objects.
        loads : sequence
            ``(point or frame, vector)`` forces and torques.
        frame : sympy.physics.vector.ReferenceFrame
            The inertial frame.
        params : sequence of sympy.Symbol
            The parameter symbols.
        nonholonomic, holonomic, u_independent, energy, outputs, q_dependent, monitors, singular_positions, description
            As for the model (see the class's parameters).
        rotations : sequence, optional
            Frames oriented by a unit quaternion (``nmkane_core.declare.rotation.quaternion_frame``
            returns one with its frame): the rotation's kinematical equations and norm constraint
            are given as ``kd_eqs`` and ``holonomic`` like any others; here its norm rate s, which
            moves no mass (a zero row and column of Q), gets a fictitious inertia — the mean of Q's
            diagonal over the rotation's body rates — which keeps Q positive definite and does not
            change the motion (the norm constraint alone fixes s).

        Returns
        -------
        MechanicalModel
            The model, in plain symbols.
        """
        from sympy.physics.mechanics import KanesMethod

        q, u = list(q), list(u)
        kane = KanesMethod(frame, q_ind=q, u_ind=u, kd_eqs=list(kd_eqs))
        kane.kanes_equations(list(bodies), list(loads))
        C, D, plain, (qs, us, ts) = _kinematics_in_plain_symbols(q, u, list(kd_eqs))
        Q = kane.mass_matrix.applyfunc(plain)
        _norm_rate_inertia(Q, u, rotations)

        def named(mapping):
            return {k: plain(v) for k, v in dict(mapping or {}).items()}

        return cls(
            name=name,
            q=qs,
            u=us,
            params=tuple(params),
            C=C.applyfunc(plain),
            D=D.applyfunc(plain),
            Q=Q,
            P=kane.forcing.applyfunc(plain),
            nonholonomic=named(nonholonomic),
            holonomic=named(holonomic),
            u_independent=tuple(plain(s) for s in u_independent),
            energy=None if energy is None else plain(energy),
            outputs=named(outputs),
            q_dependent=tuple(plain(s) for s in q_dependent),
            monitors=named(monitors),
            singular_positions=singular_positions,
            t=ts,
            description=description,
        )


def _kinematics_in_plain_symbols(q, u, kd_eqs):
    """(C, D of q̇ = C u + D (1) solved from the kinematical equations, a converter of
    expressions in dynamicsymbols to plain symbols — q̇ replaced by C u + D —, and the plain
    (q, u, t)) for :meth:`MechanicalModel.from_mechanics`."""
    from sympy.physics.mechanics import dynamicsymbols

    t = dynamicsymbols._t
    qd = [qi.diff(t) for qi in q]
    sol = sp.solve(kd_eqs, qd, dict=True)[0]
    qdot = sp.Matrix([sol[v] for v in qd])
    C = qdot.jacobian(u)
    D = sp.expand(qdot - C * sp.Matrix(u))
    qs = plain_symbols([str(s).replace("(t)", "") for s in q])
    us = plain_symbols([str(s).replace("(t)", "") for s in u])
    ts = sp.Symbol("t", real=True)
    # xreplace, not subs: an exact swap of nodes, linear in the size of the expression
    # (subs took minutes on the mass matrix of a model with 8 coordinates)
    to_qdot = dict(zip(qd, qdot, strict=True))
    to_plain = {**dict(zip(q, qs, strict=True)), **dict(zip(u, us, strict=True)), t: ts}

    def plain(e):
        return sp.sympify(e).xreplace(to_qdot).xreplace(to_plain)

    return C, D, plain, (qs, us, ts)


def _norm_rate_inertia(Q: sp.Matrix, u: list, rotations) -> None:
    """A quaternion's norm rate moves no mass: give it, in place, the mean of Q's diagonal over
    the rotation's body rates (see ``rotations`` of :meth:`MechanicalModel.from_mechanics`)."""
    for rot in rotations:
        s, rates = u.index(rot.norm_rate), [u.index(w) for w in rot.rates]
        Q[s, s] = sum((Q[i, i] for i in rates), sp.S.Zero) / len(rates)
