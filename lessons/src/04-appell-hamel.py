# %% [markdown]
# # Lesson 4 — The Appell–Hamel mechanism: a constraint nonlinear in the speeds
#
# The paper's Example 1 (Bajodah, Hodges & Chen 2005, Fig. 1). A frame slides on the plane
# and carries a wheel W (radius a) that rolls without slipping, and two pulleys ρ apart. A
# thread wound on the wheel's drum (radius b) runs over the pulleys to a load P that hangs on
# the frame's vertical bar. The load falls, pulls the thread and spins the wheel up, and the
# wheel drives the frame over the plane. Coordinates q = (θ, φ, x, y, z): the frame's heading,
# the wheel's angle and the load's position; speeds u1..u5 = (θ̇, φ̇, ẋ, ẏ, ż).
#
# Rolling can be written in two ways. With v_o the velocity of the wheel's centre:
#
# * **nonlinear** (the paper's (57)–(58)): the centre moves as fast as the rim turns and not
#   sideways, $|v_o|^2 - a^2\dot\varphi^2 = 0$ and $v_o \cdot \hat y_H = 0$ — the first is
#   *quadratic* in the speeds;
# * **linear** ((101)–(102)): the centre's velocity is $a\dot\varphi$ along the heading,
#   component by component.
#
# Both describe the same motion, and the thread (59), z + bφ = z0, is holonomic in both. The
# nonminimal equations need J2 = ∂φ/∂u_D, the constraints' Jacobian in the dependent speeds,
# to be invertible. The gradient of the quadratic one is 2 v_o, whose length is 2a|φ̇|: **when
# the wheel stops rolling, J2 of the nonlinear model is singular**. This lesson compares the
# two models, adds Baumgarte's Γ, and follows the nonlinear model through a wheel that stops
# and turns back.

# %%
import matplotlib.pyplot as plt
import numpy as np

from nmkane_core import InconsistentStateError, get_system, resolve, simulate

system = get_system("appell-hamel")
print(system.title)
print("models:", list(system.variants))
print(system.description)

# %% [markdown]
# ## The two models, side by side
#
# The paper's defaults: 20 s, Kutta–Merson with Δt = 0.01 s, the load 30 m up, u1 = θ̇ = 1 and
# u2 = φ̇ = 1 rad/s (the dependent speeds u3, u4, u5 are completed from the constraints).
# `"model"` picks the variant.

# %%
BASE = {"system": "appell-hamel", "t_final": 20.0}
runs = {m: simulate({**BASE, "model": m}) for m in ("nonlinear", "linear")}
for m, r in runs.items():
    print(
        f"{m:9s} {r.status}: max |ΔE| = {r.summary['max_abs_energy_drift']:.2e} J, violations",
        {k: f"{v:.1e}" for k, v in r.summary["max_abs_violation"].items()},
    )
nl, lin = runs["nonlinear"], runs["linear"]
t = np.asarray(nl.t)
gap = {k: np.abs(np.asarray(nl.state[k]) - np.asarray(lin.state[k])).max() for k in nl.state}
print(f"largest difference between the models over 20 s: {max(gap.values()):.1e} ({max(gap, key=gap.get)})")

# %% [markdown]
# The two models follow the same motion to the integrator's accuracy; what differs is the
# error each one makes. The paper's Fig. 9: with the same step, the nonlinear model's energy
# error is the smaller.

# %%
E = {m: np.asarray(r.energy) for m, r in runs.items()}
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
ax1.plot(nl.state["x"], nl.state["y"], label="nonlinear")
ax1.plot(lin.state["x"], lin.state["y"], "--", label="linear")
ax1.set_aspect("equal")
ax1.set_xlabel("x [m]")
ax1.set_ylabel("y [m]")
ax1.set_title("the load's point on the plane (Fig. 7)")
ax1.legend()
for m in runs:
    ax2.plot(t, E[m] - E[m][0], label=m)
ax2.set_xlabel("t [s]")
ax2.set_ylabel("E − E(0) [J]")
ax2.set_title("energy error, Δt = 0.01 s (Fig. 9)")
ax2.legend()
plt.tight_layout()
plt.show()

# %% [markdown]
# The frame turns less and less (u1 = θ̇ → 0) while the wheel spins up, so the path
# straightens. The wheel's and the thread's forces are reported too (`point_forces`): the
# thread tension is m (g + z̈), below m g while the load speeds up.

# %%
tension = np.asarray(nl.point_forces["thread.tension"])
u1, u2 = nl.state["u1"], nl.state["u2"]
print(f"θ̇: {u1[0]} → {u1[-1]:.1e} rad/s;  φ̇: {u2[0]} → {u2[-1]:.3f} rad/s")
P = system.resolve_params({})  # the default parameter values
mg = P["m"] * P["g"]
print(f"thread tension {tension.min():.3f} … {tension.max():.3f} N (m g = {mg:.2f} N)")

# %% [markdown]
# ## Two branches
#
# A constraint quadratic in the speeds has two roots: |v_o| = a|φ̇| is also satisfied by a
# centre moving *backwards*, v_o = −aφ̇ along the heading, which is not rolling. When the
# dependent speeds are completed, the value you give (or the default) is the starting guess
# that picks the branch; a full state on the spurious branch is refused.

# %%
start = {k: nl.state[k][0] for k in nl.state}  # the completed default start: θ = 0, u3 = ẋ = 1
rho, a = P["rho"], P["a"]
v_o = np.array([start["u3"] + rho * start["u1"] * np.sin(start["theta"]), start["u4"] - rho * start["u1"]])
print("physical branch: v_o =", v_o, " |v_o|² − a²φ̇² =", v_o @ v_o - (a * start["u2"]) ** 2)
spurious = {**start, "u3": -start["u3"]}  # v_o = (−1, 0): |v_o| = aφ̇ holds too, but backwards
try:
    resolve({"system": "appell-hamel", "model": "nonlinear", "initial": spurious})
except InconsistentStateError as err:
    print("refused:", err.reason)

# %% [markdown]
# ## Baumgarte's Γ
#
# The constraints are used in differentiated form, so their violation is not held at zero by
# the equations; with φ̇ = Γφ (the paper's (104)) and Γ < 0 it decays instead. A coarse step,
# Δt = 0.05 s, over 100 s, with and without Γ = −1 s⁻¹ on the two rolling constraints:

# %%
COARSE = {**BASE, "dt": 0.05, "t_final": 100.0}
stab = {}
for m in ("nonlinear", "linear"):
    for gamma in (None, -1.0):
        r = simulate({**COARSE, "model": m, **({"gamma": gamma} if gamma else {})})
        rolling = [k for k in r.violation if k != "thread"]
        stab[m, gamma] = r
        end = max(abs(r.violation[k][-1]) for k in rolling)
        print(
            f"{m:9s} Γ = {gamma or 0:4}: rolling violation at the end {end:.1e}, "
            f"max |ΔE| = {r.summary['max_abs_energy_drift']:.1e} J"
        )

# %%
fig, ax = plt.subplots(figsize=(8, 4))
for (m, gamma), r in stab.items():
    Em = np.asarray(r.energy)
    ax.semilogy(r.t, np.abs(Em - Em[0]) + 1e-16, label=f"{m}, Γ = {gamma or 0}")
ax.set_xlabel("t [s]")
ax.set_ylabel("|E − E(0)| [J]")
ax.set_ylim(1e-10, None)
ax.set_title("energy error, Δt = 0.05 s")
ax.legend()
plt.show()

# %% [markdown]
# Without Γ the energy error of the linear model keeps growing; with Γ = −1 both stay
# bounded and the final violations of the rolling constraints are four to five orders
# smaller.
#
# ## When the wheel stops rolling
#
# Start with the wheel turning backwards (φ̇ = −0.4 rad/s, a weak gravity g = 1 m/s² so the
# reversal is slow). The falling load brakes the wheel, φ̇ passes through zero and the wheel
# rolls forwards. At φ̇ = 0 the nonlinear model's J2 is singular.
#
# The library watches J2's reciprocal condition. The system declares the linear model as
# equivalent, so when the estimate drops to `rcond_switch` (default 1e−2) the run **switches**
# to it and back (with a hysteresis of ×10) once φ̇ has grown again; `summary["switches"]`
# lists when. With `"switching": False` the run keeps the nonlinear model and ends with
# status `singular` if the estimate falls below `rcond_min` (1e−10) — but fixed steps seldom
# land that close to φ̇ = 0: this run steps over it (exercise 4 raises `rcond_min`).

# %%
REVERSAL = {
    "system": "appell-hamel",
    "initial": {"u2": -0.4, "u1": 0.3},
    "params": {"g": 1.0},
    "dt": 0.01,
    "t_final": 15.0,
}
switched = simulate({**REVERSAL, "model": "nonlinear"})
linear = simulate({**REVERSAL, "model": "linear"})
for sw in switched.summary["switches"]:
    print(f"t = {sw['t']:.2f} s: {sw['from']} → {sw['to']} (J2 estimate {sw['rcond']:.1e})")
print(
    "status",
    switched.status,
    "— the violations reported are the nonlinear model's:",
    {k: f"{v:.1e}" for k, v in switched.summary["max_abs_violation"].items()},
)

# %%
tl, u2l = np.asarray(linear.t), np.asarray(linear.state["u2"])
k = int(np.argmax(u2l > 0))
t_stop = float(np.interp(0.0, u2l[k - 1 : k + 1], tl[k - 1 : k + 1]))  # the linear model has no singularity
t_in, t_out = (sw["t"] for sw in switched.summary["switches"])

fig, ax = plt.subplots(figsize=(8, 4))
ax.axvspan(t_in, t_out, color="0.85", label="run on the linear model")
ax.plot(switched.t, switched.state["u2"], label=r"$\dot\varphi$, nonlinear model with switching")
ax.plot(tl, u2l, "--", label=r"$\dot\varphi$, linear model")
ax.axvline(t_stop, color="k", lw=0.8)
ax.axhline(0.0, color="k", lw=0.5)
ax.set_xlim(0, 8)
ax.set_xlabel("t [s]")
ax.set_ylim(-0.45, 0.6)
ax.set_ylabel(r"$\dot\varphi$ [rad/s]")
ax.legend()
plt.show()
print(f"the wheel stops at t = {t_stop:.4f} s")

# %% [markdown]
# ## Exercises
#
# 1. Over the paper's 20 s, how far apart are the nonlinear and the linear model's states?
#    Which one has the smaller energy error at Δt = 0.01 s?
# 2. At Δt = 0.05 s over 100 s, by how much does Γ = −1 reduce each model's energy error, and
#    the final violation of the rolling constraints?
# 3. In the reversal run, when does the wheel stop rolling? Check that the switched run spent
#    that instant on the linear model, and that it ends where the linear model ends.
# 4. Turn switching off. Does the run get through? How small did J2's estimate get
#    (`summary["min_rcond"]`)? Now ask for `"rcond_min": 1e-2`: when does the run stop, with
#    what status, and how fast is the wheel still turning there?
# 5. Start the paper's run with the wheel not rolling, u2 = 0. What happens with and without
#    switching?
#
# The next cell computes the answers and checks them.

# %%
KEYS = list(nl.state)


def final(r):
    return np.array([r.state[k][-1] for k in KEYS])


spread = max(gap.values())
assert spread < 1e-7, spread
assert nl.summary["max_abs_energy_drift"] < lin.summary["max_abs_energy_drift"]  # Fig. 9


def rolling_end(r):
    return max(abs(r.violation[k][-1]) for k in r.violation if k != "thread")


gains = {}
for m in ("nonlinear", "linear"):
    free, damped = stab[m, None], stab[m, -1.0]
    gains[m] = free.summary["max_abs_energy_drift"] / damped.summary["max_abs_energy_drift"]
    assert gains[m] > 5, (m, gains[m])
    assert rolling_end(damped) < 1e-3 * rolling_end(free), m

assert t_in < t_stop < t_out, (t_in, t_stop, t_out)
assert switched.status == "ok" and switched.summary["switches"][-1]["to"] == "nonlinear"
np.testing.assert_allclose(final(switched), final(linear), rtol=1e-8, atol=1e-8)

unswitched = simulate({**REVERSAL, "model": "nonlinear", "switching": False})
closest = unswitched.summary["min_rcond"]["J2"]
assert unswitched.status == "ok" and closest < 1e-2, (unswitched.status, closest)  # stepped over φ̇ = 0
stopped = simulate({**REVERSAL, "model": "nonlinear", "switching": False, "rcond_min": 1e-2})
assert stopped.status == "singular", stopped.status
t_end, u2_end = stopped.summary["t_end"], stopped.state["u2"][-1]
assert 0 < t_stop - t_end < 0.1 and abs(u2_end) < 0.02, (t_end, u2_end)

no_switch = simulate({**BASE, "initial": {"u2": 0.0}, "switching": False})
assert no_switch.status == "singular" and len(no_switch.t) == 1  # stops at once, at t = 0
from_rest = simulate({**BASE, "initial": {"u2": 0.0}})
first = from_rest.summary["switches"][0]
assert from_rest.status == "ok" and first["t"] == 0.0 and first["to"] == "linear"
np.testing.assert_allclose(
    final(from_rest), final(simulate({**BASE, "initial": {"u2": 0.0}, "model": "linear"})), rtol=1e-8, atol=1e-8
)

print(
    f"1: {spread:.1e} apart; nonlinear {nl.summary['max_abs_energy_drift']:.2e} J < linear "
    f"{lin.summary['max_abs_energy_drift']:.2e} J"
)
print(f"2: energy error ÷{gains['nonlinear']:.0f} (nonlinear), ÷{gains['linear']:.0f} (linear)")
print(f"3: φ̇ = 0 at t = {t_stop:.4f} s, on the linear model from {t_in} to {t_out} s")
print(
    f"4: without switching ok (J2 estimate down to {closest:.1e}); with rcond_min = 1e-2 singular at "
    f"t = {t_end} s, φ̇ = {u2_end:.4f} rad/s"
)
print(
    f"5: without switching singular at t = 0; with it on the linear model until t = "
    f"{from_rest.summary['switches'][-1]['t']} s"
)
