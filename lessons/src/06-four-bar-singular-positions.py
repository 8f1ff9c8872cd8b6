# %% [markdown]
# # Lesson 6 — A closed-loop linkage: singular positions
#
# IFToMM benchmark A02, the **N-four-bar mechanism**: N + 1 cranks pinned to the ground one
# metre apart, their tips joined by N couplers, every rod 1 m long and 1 kg, under gravity.
# Each window is a parallelogram. With N = 2 there are five rods, five angles (cranks θ0, θ1,
# θ2, couplers φ1, φ2) and four loop-closure equations — coupler k's end must meet crank k's
# tip, in x and in y — so one degree of freedom: all the cranks turn together and the couplers
# stay horizontal. The closures are holonomic, used as ψ̇ = 0 and stabilized with Γ1, Γ2
# (lesson 3).
#
# When the cranks lie **horizontal**, the x rows of the closure Jacobian ∂ψ/∂q vanish: its
# rank drops from 4 to 2, and for an instant the linkage has three degrees of freedom (each
# window could fold either way). The paper's equations need J2 — the Jacobian in the
# dependent speeds — invertible; at that position no choice of the dependent speeds makes it
# so. This lesson meets the singular position with the paper's solve and with the library's
# rank-robust one (`"solve"`: `auto` | `paper` | `robust`, see the closed-loops page).
#
# The A02 system is not in the built-in catalogue here: it is declared in
# `nmkane_core.systems.iftomm_a02`, and `register` makes it available to `simulate` by name.

# %%
import matplotlib.pyplot as plt
import numpy as np
from scipy.integrate import quad, solve_ivp

from nmkane_core import register, simulate
from nmkane_core.systems import iftomm_a02

N = 2
system = register(iftomm_a02.iftomm_a02(N))  # the first call derives and compiles its kernels
print(system.name, "—", system.title)
print(system.description)
QN, UN = iftomm_a02.names(N)
print("coordinates:", QN, " speeds:", UN)
print("the benchmark's start:", system.default_initial)

# %% [markdown]
# ## The rank of the closures
#
# The closures written out (not taken from the library): crank k is pinned at (k L, 0), its
# tip at (k L + L cos θk, L sin θk), and coupler k runs from crank k−1's tip at angle φk.

# %%
L = 1.0


def closures(q):
    th, ph = q[: N + 1], q[N + 1 :]
    out = []
    for k in range(1, N + 1):
        out.append((k - 1) * L + L * np.cos(th[k - 1]) + L * np.cos(ph[k - 1]) - (k * L + L * np.cos(th[k])))
        out.append(L * np.sin(th[k - 1]) + L * np.sin(ph[k - 1]) - L * np.sin(th[k]))
    return np.array(out)


def jacobian(q, h=1e-6):
    cols = []
    for j in range(len(q)):
        e = np.zeros(len(q))
        e[j] = h
        cols.append((closures(q + e) - closures(q - e)) / (2 * h))
    return np.column_stack(cols)


def branch(theta):
    """The parallelogram position: every crank at θ, the couplers horizontal."""
    return np.array([theta] * (N + 1) + [0.0] * N)


for theta in (np.pi / 2, np.pi / 4, 0.1, 0.0):
    J = jacobian(branch(theta))
    sv = np.linalg.svd(J, compute_uv=False)
    print(f"θ = {theta:.3f}: rank {np.linalg.matrix_rank(J, tol=1e-8)}, singular values {np.round(sv, 4)}")

# %% [markdown]
# Two singular values are proportional to |sin θ| and vanish at the horizontal position.
#
# ## The exact motion
#
# On the parallelogram branch the whole linkage is one pendulum: each crank (m L²/3 about its
# pivot, its centre at L/2) turns by θ, and each coupler translates with the cranks' tips
# (m L², its centre at height L sin θ). So I θ̈ = −K cos θ with
# I = (N+1) m L²/3 + N m L² and K = (N+1) m g L/2 + N m g L. The benchmark starts with the cranks
# vertical, θ = π/2, and the point B0 (crank 0's tip) moving at 1 m/s along x: θ̇ = −1 rad/s.
# Energy gives θ̇² = θ̇0² + (2K/I)(1 − sin θ), so the time to the first horizontal position is
# the quadrature
#
# $$t_h = \int_0^{\pi/2} \frac{d\theta}{\sqrt{\dot\theta_0^2 + (2K/I)(1 - \sin\theta)}} .$$

# %%
m, g = 1.0, 9.81
I = (N + 1) * m * L**2 / 3 + N * m * L**2
K = (N + 1) * m * g * L / 2 + N * m * g * L
assert np.allclose((I, K), iftomm_a02.pendulum_constants(N))  # the module's oracle agrees
w0 = system.default_initial["dth0"]
t_h = quad(lambda th: 1.0 / np.sqrt(w0**2 + 2 * K / I * (1 - np.sin(th))), 0.0, np.pi / 2)[0]
print(f"I = {I:.4f} kg·m², K = {K:.4f} N·m: the first horizontal position at t_h = {t_h:.6f} s")


def exact(t, theta0=np.pi / 2, omega0=w0):
    """θ(t), θ̇(t) of the pendulum, integrated to 1e-12."""
    t = np.asarray(t, float)
    sol = solve_ivp(
        lambda _, y: [y[1], -K / I * np.cos(y[0])],
        (0.0, t[-1]),
        [theta0, omega0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t,
    )
    return sol.y[0], sol.y[1]


def b0_error(run):
    """The benchmark's quantity: B0's position error against the exact motion, m (over the run)."""
    t, th = np.asarray(run.t), np.asarray(run.state["th0"])
    th_x, _ = exact(t, th[0], run.state["dth0"][0])
    return np.hypot(L * (np.cos(th) - np.cos(th_x)), L * (np.sin(th) - np.sin(th_x)))


# %% [markdown]
# ## The paper's solve at the horizontal position
#
# The paper's partition here is u_I = θ̇0: the other four speeds are dependent and J2 is the
# 4×4 block of the closures' velocity Jacobian in them. `"solve": "paper"` uses only that;
# a J2 whose reciprocal condition estimate falls below `rcond_min` (1e−10) ends the run with
# status `singular`. With a fixed step the stages seldom come that close to the singular
# instant; the adaptive Kutta–Merson, whose step control shrinks the step there, lands on it.
# (`"projection": "none"` turns off the system's default post-step projection, for now; the
# paper's solve has no other.)

# %%
BASE = {"system": system.name, "integrator": "kutta-merson-adaptive", "t_final": 3.0}
paper = simulate({**BASE, "solve": "paper", "projection": "none"}, progress=False)
print(paper.status, "—", paper.summary["message"])
print(f"stopped at t = {paper.summary['t_end']:.6f} s; the exact motion is horizontal at {t_h:.6f} s")
tp, thp, wp = (np.asarray(x) for x in (paper.t, paper.state["th0"], paper.state["dth0"]))
print("    t [s]        θ0 [rad]   θ̇0 [rad/s]")
rows = [int(np.argmax(thp < level)) for level in (1e-3, 1e-5, 1e-7, 1e-8, 5e-9, 3.3e-9)]
for k in [*rows, len(tp) - 1]:  # the first rows below each of these angles, and the last
    print(f"{tp[k]:.8f}  {thp[k]:10.3e}  {wp[k]:9.4f}")

# %% [markdown]
# The end of the run is worse than a stop: as θ0 nears zero the equations, solved with the
# failing J2, brake the crank from −4.9 rad/s to rest within a fraction of a microsecond, a
# few nanoradians above the horizontal; the steps then grow again over a linkage standing
# still, until J2's estimate crosses `rcond_min`. The crank *stalls* where the real one
# passes at full speed. (Stopping at a small `rcond_min` protects the numbers from overflow,
# not the motion from being wrong just before.)

# %% [markdown]
# ## The rank-robust solve
#
# `"solve": "robust"` solves the acceleration constraints J u̇ = c by Gauss's principle in the
# mass metric — u̇ the acceleration closest to the unconstrained one, measured by the mass
# matrix, among those satisfying the constraints — with a pivoted QR factorization that
# drops the equations that have become dependent. Where J2 is invertible it gives the paper's
# u̇; at the singular position it is still defined. `auto` (the default) uses the paper's solve
# where J2 is well-conditioned and this one elsewhere.
#
# The run below keeps the system's default projection (`yoon`: after each step the state is
# moved back onto the closures in the mass metric).

# %%
robust = simulate({**BASE, "solve": "robust"}, progress=False)
err = b0_error(robust)
print(robust.status, "—", robust.summary["message"])
drift = robust.summary["max_abs_energy_drift"]
print(f"B0 within {err.max():.1e} m of the exact motion over 3 s; max |ΔE| = {drift:.1e} J")
print("robust solve:", robust.summary["robust_solve"])

# %%
t_dense = np.linspace(0.0, 3.0, 601)
th_exact, _ = exact(t_dense)
passages = t_dense[1:][np.diff(np.sign(np.sin(th_exact))) != 0]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
ax1.plot(t_dense, th_exact, "k-", lw=3, alpha=0.3, label="exact")
ax1.plot(robust.t, robust.state["th0"], label="robust solve")
ax1.plot(paper.t, paper.state["th0"], "--", label="paper's solve (stops)")
for t_pass in passages:
    ax1.axvline(t_pass, color="0.6", ls=":")
ax1.set_xlabel("t [s]")
ax1.set_ylabel("crank angle θ0 [rad]")
ax1.set_title("dotted: the horizontal positions")
ax1.legend()
ax2.semilogy(robust.t, err + 1e-17, label="robust solve")
ax2.semilogy(paper.t, b0_error(paper) + 1e-17, label="paper's solve")
ax2.set_xlabel("t [s]")
ax2.set_ylabel("B0's position error [m]")
ax2.set_ylim(1e-14, 1)
ax2.legend()
plt.tight_layout()
plt.show()

# %% [markdown]
# Did the robust solve do the work? Not alone: with the projection, this run's adaptive steps
# stay large and no evaluation comes near the singular instant, and the paper's solve passes
# too (try it). The sure test is a start **on** the singular position — cranks horizontal,
# θ̇ = −1 rad/s, couplers at rest: a full, consistent state.

# %%
flat = {**dict.fromkeys(QN, 0.0), **{u: (w0 if u.startswith("dth") else 0.0) for u in UN}}
on_paper = simulate({**BASE, "solve": "paper", "initial": flat}, progress=False)
on_robust = simulate({**BASE, "solve": "robust", "initial": flat}, progress=False)
print("paper: ", on_paper.status, "—", on_paper.summary["message"][:110])
print("robust:", on_robust.status, f"— B0 within {b0_error(on_robust).max():.1e} m of the exact motion")

# %% [markdown]
# ## Why the projection
#
# Near a horizontal position the linkage can fold either way; the equations amplify any
# departure from the parallelogram by about 1/|sin θ| at each passage. The integrator's small
# errors are such departures. The post-step projection removes them. A run without one still
# projects the few steps that come near a singular position (`singular_projection`, on by
# default: the summary's `robust_solve` counts them); with that turned off too, the robust
# solve gets through the first passage but not the next ones:

# %%
loose = simulate({**BASE, "solve": "robust", "projection": "none", "singular_projection": False}, progress=False)
print(loose.status, f"at t = {loose.summary['t_end']:.4f} s —", loose.summary["message"][:100], "…")
print(f"B0 error: {b0_error(loose).max():.1e} m (with the projection {err.max():.1e} m)")

# %% [markdown]
# ## Exercises
#
# 1. When does the linkage first reach the horizontal position? When did the paper's run
#    stall there (its crank speed collapse), and when did it end?
# 2. What is the rank of the closure Jacobian at θ = π/4 and at θ = 0, and how many degrees of
#    freedom does that leave?
# 3. How far is the robust run from the exact motion over 3 s, and did it pass as many
#    horizontal positions as the exact motion?
# 4. Started on the horizontal position: what does the paper's solve do, and the robust one?
# 5. Without the projection, does the robust run stay on the parallelogram?
#
# The next cell computes the answers and checks them.

# %%
fastest = int(np.argmax(np.abs(wp)))
t_stall = float(tp[fastest + np.argmax(np.abs(wp[fastest:]) < 2.0)])  # the crank speed collapses
gap = abs(t_stall - t_h)
assert paper.status == "singular" and gap < 1e-5, (paper.status, t_stall, t_h)
assert paper.summary["t_end"] - t_stall < 1e-3 and np.abs(thp[-1]) < 1e-6  # stuck at the horizontal

ranks = {th: np.linalg.matrix_rank(jacobian(branch(th)), tol=1e-8) for th in (np.pi / 4, 0.0)}
assert ranks == {np.pi / 4: 4, 0.0: 2}, ranks
dof = {th: len(QN) - rank for th, rank in ranks.items()}

assert robust.status == "ok" and err.max() < 1e-6, err.max()
crossed = np.count_nonzero(np.diff(np.sign(np.sin(robust.state["th0"]))) != 0)
assert crossed == len(passages) >= 3, (crossed, len(passages))

# it cannot take a first step (the run keeps its start: one row, or sometimes the same row twice)
assert on_paper.status == "singular" and on_paper.summary["steps"] == 0 and max(on_paper.t) == 0.0
assert on_robust.status == "ok" and b0_error(on_robust).max() < 1e-6

assert loose.status != "ok" or b0_error(loose).max() > 1e-3, loose.status

print(
    f"1: t_h = {t_h:.7f} s; the paper's run stalled at {t_stall:.7f} s ({gap:.0e} s off) and ended at "
    f"{paper.summary['t_end']:.6f} s"
)
print(f"2: rank {ranks[np.pi / 4]} → {dof[np.pi / 4]} degree of freedom; rank {ranks[0.0]} → {dof[0.0]} at θ = 0")
print(f"3: B0 within {err.max():.1e} m; {crossed} horizontal passages, as the exact motion")
print(f"4: paper {on_paper.status} at t = 0; robust {on_robust.status}, within {b0_error(on_robust).max():.1e} m")
print(f"5: no — {loose.status} at t = {loose.summary['t_end']:.3f} s, B0 off by {b0_error(loose).max():.1e} m")
