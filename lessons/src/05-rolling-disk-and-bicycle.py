# %% [markdown]
# # Lesson 5 — The rolling disk and the bicycle: stability against speed
#
# A coin rolled upright falls over when it is slow and stays up when it is fast; a bicycle
# without a rider's help does the same, but only in a window of speeds. Both are rolling
# without slipping — nonholonomic constraints, as in lesson 1 — and both questions are
# answered by **linearizing** the equations of motion about straight upright rolling and
# looking at the eigenvalues against the speed:
#
# * an eigenvalue with a positive real part is a motion that grows: unstable;
# * a pair ±iω (zero real part) is an oscillation that neither grows nor decays;
# * negative real parts decay.
#
# `nmkane_core.linearize` gives the state matrix of the independent coordinates and speeds
# about a state (perturbing the independent values only, the dependent ones completed from
# the constraints, so the linearization stays on the constraint manifold). A system may also
# declare a sweep over a value (`System.stability`): the bicycle declares its forward speed,
# and `nmkane_core.analysis.eigensweep` sweeps it and finds where an eigenvalue crosses zero.

# %%
import matplotlib.pyplot as plt
import numpy as np

from nmkane_core import get_system, linearize, simulate
from nmkane_core.analysis import eigensweep

disk = get_system("rolling-disk")
print(disk.description)
P = disk.resolve_params({})
print("parameters:", P)

# %% [markdown]
# ## The rolling disk
#
# A uniform thin disk of radius r (moments of inertia m r²/4 about a diameter, m r²/2 about
# the axle). Coordinates: the contact point (x, y), yaw ψ, lean θ (0 upright) and spin φ;
# speeds u1..u5 = (ẋ, ẏ, ψ̇, θ̇, φ̇), of which ψ̇, θ̇, φ̇ are independent. Rolling straight
# and upright at spin s: θ = 0, ψ̇ = θ̇ = 0, φ̇ = s, and the contact point moves at ẋ = r s.
#
# We linearize in the lean θ, the yaw rate u3 and the lean rate u4 (the position, the heading
# and the spin angle do not change the motion, and the spin rate stays s to first order).

# %%
r, g = P["r"], P["g"]
KEEP = ("theta", "u3", "u4")


def upright(s, radius=r):
    """Straight upright rolling at spin s: a full consistent state."""
    return dict(x=0.0, y=0.0, psi=0.0, theta=0.0, phi=0.0, u1=radius * s, u2=0.0, u3=0.0, u4=0.0, u5=s)


lin = linearize("rolling-disk", upright(6.0), keep=KEEP)
print(lin.names)
print(np.round(lin.A, 6))
print("eigenvalues at s = 6 rad/s:", np.round(lin.eigenvalues, 6))

# %% [markdown]
# One eigenvalue is zero (a lean-free change of the yaw rate: the disk rolls on a slightly
# different straight line) and two carry the lean. Sweep the spin:

# %%
spins = np.linspace(0.0, 8.0, 81)
eig = np.array(
    [sorted(linearize("rolling-disk", upright(s), keep=KEEP).eigenvalues, key=lambda z: z.real) for s in spins]
)
largest = eig.real.max(axis=1)
print(f"largest real part: {largest[0]:.3f} s⁻¹ at s = 0 … {largest[-1]:.1e} s⁻¹ at s = {spins[-1]} rad/s")

# %% [markdown]
# Below a critical spin the lean has a positive real eigenvalue: the disk falls over, like an
# inverted pendulum. Above it the pair is ±iω: the disk wobbles without falling. It never
# *decays* — the disk conserves energy and nothing damps the wobble — so upright rolling of
# the coin is stable only in this neutral sense.
#
# The closed form (Neimark & Fufaev): the lean obeys
# $(I_1 + m r^2)\,\ddot\theta + \left[(I_3 + m r^2) I_3 s^2/I_1 - m g r\right]\theta = 0$,
# which for the thin disk is $\lambda^2 = 4(g - 3 r s^2)/(5 r)$: stable for $s^2 > g/(3r)$, a
# forward speed $v = r s > \sqrt{g r/3}$.

# %%
s_closed = np.sqrt(g / (3 * r))
lam_closed = np.sqrt((4 * (g - 3 * r * spins**2) / (5 * r)).astype(complex))
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4), sharex=True)
for k in range(eig.shape[1]):
    ax1.plot(r * spins, eig[:, k].real, "o", ms=3, color="C0")
    ax2.plot(r * spins, np.abs(eig[:, k].imag), "o", ms=3, color="C1")
ax1.plot(r * spins, lam_closed.real, "k-", lw=0.8, label="closed form")
ax2.plot(r * spins, lam_closed.imag, "k-", lw=0.8, label="closed form")
for ax, what in ((ax1, "real part [1/s]"), (ax2, "|imaginary part| [rad/s]")):
    ax.axvline(r * s_closed, color="k", ls=":", label=f"v = √(g r/3) = {r * s_closed:.3f} m/s")
    ax.set_xlabel("forward speed v = r s [m/s]")
    ax.set_ylabel(what)
    ax.legend()
ax1.set_title("rolling disk: eigenvalues of the lean")
plt.tight_layout()
plt.show()

# %% [markdown]
# ### A run on either side
#
# A small lean rate (u4 = 0.05 rad/s) at v = 0.6 m/s (below √(g r/3) ≈ 0.99 m/s) and at
# v = 1.2 m/s (above):

# %%
fig, ax = plt.subplots(figsize=(8, 3.5))
disk_runs = {}
for s in (2.0, 4.0):
    run = simulate(
        {"system": "rolling-disk", "t_final": 10.0, "initial": {"theta": 0.0, "u3": 0.0, "u4": 0.05, "u5": s}}
    )
    disk_runs[s] = run
    ax.plot(
        run.t, run.state["theta"], label=f"v = {r * s:.1f} m/s: max |θ| = {np.abs(run.state['theta']).max():.3f} rad"
    )
ax.set_xlabel("t [s]")
ax.set_ylabel("lean θ [rad]")
ax.set_ylim(-1.1, 1.7)
ax.legend(loc="upper right")
plt.show()

# %% [markdown]
# Below the critical speed the small lean grows exponentially, as the positive eigenvalue
# says, until the lean is large (about 1 rad) and the linearization no longer holds: the
# turning it causes lifts the coin again, and it swings from side to side in a large wobble.
# Above it the lean stays at the size of the push.
#
# ## The bicycle
#
# The Carvallo–Whipple bicycle with the benchmark parameters of Meijaard, Papadopoulos, Ruina
# & Schwab (2007): rear wheel, rear frame with a rigid rider, front frame, front wheel; four
# rolling constraints and the front wheel's ground contact (holonomic). Its independent speeds
# are the roll rate u4, the rear wheel's rate u6 (forward speed v = −rR u6) and the steer rate
# u7. The system declares its stability sweep over the forward speed, linearized in roll q4,
# steer q7 and their rates: `eigensweep.sweep` gives the eigenvalues at each speed and
# `eigensweep.crossings` the speeds where a real part changes sign.

# %%
bike = get_system("whipple-bicycle")
print(bike.description)
rows = eigensweep.sweep("whipple-bicycle", np.linspace(0.0, 10.0, 101))
speeds = np.array([row["value"] for row in rows])
ev = np.array([[complex(a, b) for a, b in row["eigenvalues"]] for row in rows])
found = eigensweep.crossings("whipple-bicycle", rows)
for c in found:
    print(f"{c['name']:8s} ({c['kind']} crossing): {c['value']:.10f} m/s   Meijaard 2007: {c['reference']:.10f} m/s")

# %%
weave, capsize = (next(c["value"] for c in found if c["name"] == n) for n in ("weave", "capsize"))
fig, ax = plt.subplots(figsize=(8, 5))
ax.axvspan(weave, capsize, color="0.9", label="self-stable")
ax.plot(speeds, ev.real, "o", ms=2.5, color="C0")
ax.plot(speeds, np.abs(ev.imag), "o", ms=2.5, color="C1")
ax.plot([], [], "o", color="C0", label="real parts")
ax.plot([], [], "o", color="C1", label="|imaginary parts|")
ax.axhline(0.0, color="k", lw=0.6)
ax.set_ylim(-10, 10)
ax.set_xlabel("forward speed v [m/s]")
ax.set_ylabel("eigenvalues [1/s]")
ax.set_title("Whipple bicycle, benchmark parameters (Meijaard et al. 2007, Fig. 3)")
ax.legend(loc="lower right")
plt.show()

# %% [markdown]
# Below the **weave speed** (≈ 4.29 m/s) an oscillating mode — the weave, roll and steer
# swinging against each other — grows. Above the **capsize speed** (≈ 6.02 m/s) a real mode —
# a slow fall to the side, steering too little — grows, slowly. In between every real part is
# negative: the bicycle is **self-stable** and a push dies out by itself. Unlike the coin's,
# these eigenvalues do have negative real parts, though the bicycle conserves energy: a
# nonholonomic system is not Hamiltonian, and energy can move from the wobble into the forward
# motion (as the spin of lesson 2's sleigh went into its forward speed).
#
# ### Three runs
#
# The same push, a roll rate u4 = 0.5 rad/s, at 3, 5 and 7.5 m/s (u6 = −v/rR). The bicycle
# declares an event, the handlebar touching the ground: a run where it falls ends there with
# status `event`.

# %%
rR = bike.resolve_params({})["rR"]


def ride(v, t_final=5.0):
    return simulate({"system": "whipple-bicycle", "t_final": t_final, "initial": {"u6": -v / rR, "u4": 0.5}})


rides = {v: ride(v) for v in (3.0, 5.0, 7.5)}
fig, ax = plt.subplots(figsize=(8, 3.5))
for v, run in rides.items():
    ax.plot(run.t, run.state["q4"], label=f"{v} m/s: {run.status}")
    print(f"{v} m/s: {run.status} — {run.summary['message'][:90]}")
ax.set_xlabel("t [s]")
ax.set_ylabel("roll q4 [rad]")
ax.set_ylim(-0.4, 0.4)
ax.legend()
plt.show()

# %% [markdown]
# ## Exercises
#
# 1. Find the disk's critical spin from the eigenvalues (bisection on the largest real part)
#    and compare it with √(g/(3r)). Do the same for a disk of radius 0.5 m. Check that the run
#    below the critical speed leans far and the one above does not.
# 2. Check the disk's lean eigenvalues against λ² = 4(g − 3 r s²)/(5 r) over the sweep.
# 3. What is the bicycle's self-stable speed range? Compare with Meijaard's 4.2923825363 and
#    6.0242620154 m/s.
# 4. At 5 m/s the push dies out: by how much has the roll wobble shrunk after 5 s? Measure the
#    wobble's period from the run (the zero crossings of the roll rate u4) and compare it with
#    2π / Im λ of the weave eigenvalue at 5 m/s. At 3 m/s: does it fall, and does the weave
#    eigenvalue there have a positive real part?
# 5. At 5 m/s the energy is conserved while the wobble dies. Where does it go?
#
# The next cell computes the answers and checks them.


# %%
def critical_spin(radius, lo=0.5, hi=10.0, tol=1e-10):
    """The spin above which the lean has no eigenvalue with a positive real part."""
    params = {"r": radius}

    def unstable(s):
        lam = linearize("rolling-disk", upright(s, radius), params=params, keep=KEEP).eigenvalues
        return lam.real.max() > 1e-6

    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if unstable(mid) else (lo, mid)
    return 0.5 * (lo + hi)


crit = {radius: critical_spin(radius) for radius in (r, 0.5)}
for radius, s_c in crit.items():
    assert abs(s_c - np.sqrt(g / (3 * radius))) < 1e-8, (radius, s_c)
    assert abs(radius * s_c - np.sqrt(g * radius / 3)) < 1e-8
assert np.abs(disk_runs[2.0].state["theta"]).max() > 0.5  # below: the lean grows large
assert np.abs(disk_runs[4.0].state["theta"]).max() < 0.05  # above: it stays small

lean = np.array([max(row, key=lambda z: abs(z)) for row in eig])  # the lean's ± pair (the other is 0)
closed = np.sqrt((4 * (g - 3 * r * spins**2) / (5 * r)).astype(complex))
assert np.allclose(np.abs(lean), np.abs(closed), atol=1e-6), np.abs(np.abs(lean) - np.abs(closed)).max()
assert np.allclose(np.abs(lean.real), closed.real, atol=1e-6)  # real where the closed form is real

assert abs(weave - 4.2923825363) < 1e-7 and abs(capsize - 6.0242620154) < 1e-7, (weave, capsize)

five = rides[5.0]
t5, q4, u4 = (np.asarray(x) for x in (five.t, five.state["q4"], five.state["u4"]))
shrink = np.abs(q4[t5 < 1]).max() / np.abs(q4[t5 > t5[-1] - 1]).max()
assert five.status == "ok" and shrink > 5, shrink
i = np.flatnonzero(np.diff(np.sign(u4)) != 0)[:4]
zeros = t5[i] - u4[i] * (t5[i + 1] - t5[i]) / (u4[i + 1] - u4[i])
period = 2 * (zeros[-1] - zeros[0]) / (len(zeros) - 1)
lam5 = eigensweep.eigenvalues_at("whipple-bicycle", 5.0)
weave5 = max(lam5, key=lambda z: z.imag)
assert abs(period - 2 * np.pi / weave5.imag) < 0.02 * period, (period, 2 * np.pi / weave5.imag)

three = rides[3.0]
assert three.status == "event" and three.summary["event"]["name"] == "handlebar_touches_ground"
assert max(z.real for z in eigensweep.eigenvalues_at("whipple-bicycle", 3.0) if abs(z.imag) > 1e-9) > 0

v_start, v_end = -rR * five.state["u6"][0], -rR * five.state["u6"][-1]
assert five.summary["max_abs_energy_drift"] < 1e-8 and v_end > v_start, (v_start, v_end)

print(
    f"1: s_c = {crit[r]:.6f} rad/s (√(g/3r) = {np.sqrt(g / (3 * r)):.6f}), v_c = {r * crit[r]:.4f} m/s; "
    f"r = 0.5 m: v_c = {0.5 * crit[0.5]:.4f} m/s"
)
print(f"2: largest gap to the closed form {np.abs(np.abs(lean) - np.abs(closed)).max():.1e}")
print(f"3: self-stable from {weave:.8f} to {capsize:.8f} m/s")
print(
    f"4: wobble ÷{shrink:.0f} in 5 s; period {period:.3f} s against 2π/Im λ = {2 * np.pi / weave5.imag:.3f} s; "
    f"3 m/s: falls at t = {three.summary['event']['t']:.3f} s"
)
print(f"5: |ΔE| ≤ {five.summary['max_abs_energy_drift']:.1e} J; the speed rises {v_start:.4f} → {v_end:.4f} m/s")
