# %% [markdown]
# # Lesson 2 — The Chaplygin sleigh: energy conserved, the motion straightens
#
# The sleigh is the knife edge of lesson 1 with its mass centre a distance `a` **ahead of the
# blade**. The constraint is the same (the blade does not slip sideways, u2 = 0), but now the
# blade force has a lever arm about the mass centre. With the forward speed v = u1 and the
# turning rate ω = u3 the equations are
#
# $$\dot v = a\,\omega^2, \qquad \dot\omega = -\frac{m a}{J}\, v\,\omega, \qquad J = I + m a^2 .$$
#
# The constraint force does no work, so the energy E = (m v² + J ω²)/2 is conserved; yet the
# spin dies away and the sleigh ends sliding straight ahead at V = √(2E/m). Energy is not
# lost — it is moved from spin into forward motion.

# %%
import matplotlib.pyplot as plt
import numpy as np

from nmkane_core import get_system, simulate

print(get_system("chaplygin-sleigh").description)

# %% [markdown]
# ## A spinning start
#
# The defaults: u1 = 0.1 m/s forward, u3 = 2 rad/s spin; m = 1 kg, I = 0.1 kg·m², a = 0.5 m.

# %%
run = simulate({"system": "chaplygin-sleigh", "t_final": 20.0})
t = np.asarray(run.t)
s = {k: np.asarray(v) for k, v in run.state.items()}
E = np.asarray(run.energy)
print(run.status, "—", run.summary["message"])
print(f"energy {E[0]:.6f} J, max |ΔE| = {np.abs(E - E[0]).max():.1e} J")
print(f"max |φ| = {np.abs(np.asarray(run.violation['no_side_slip'])).max():.1e}")
print(f"spin u3: {s['u3'][0]} → {s['u3'][-1]:.2e} rad/s;  forward u1: {s['u1'][0]} → {s['u1'][-1]:.6f} m/s")

# %% [markdown]
# ## Against the closed form
#
# With V = √(2E/m) and s(t) = (m a V/J) t + artanh(v0/V) the solution is v = V tanh s and
# ω = √(m/J) V sech s. The run follows it to the integrator's accuracy.

# %%
m, I, a = 1.0, 0.1, 0.5
J = I + m * a**2
V = np.sqrt(2 * E[0] / m)
arg = m * a * V / J * t + np.arctanh(s["u1"][0] / V)
v_exact, w_exact = V * np.tanh(arg), np.sqrt(m / J) * V / np.cosh(arg)
print(f"V = {V:.6f} m/s")
print(f"max |u1 − v| = {np.abs(s['u1'] - v_exact).max():.1e},  max |u3 − ω| = {np.abs(s['u3'] - w_exact).max():.1e}")

# %%
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
ax1.plot(s["x"], s["y"])
ax1.set_aspect("equal")
ax1.set_xlabel("x [m]")
ax1.set_ylabel("y [m]")
ax1.set_title("the blade's path: a few turns, then straight")
ax2.plot(t, s["u1"], label="u1 (forward)")
ax2.plot(t, s["u3"], label="u3 (spin)")
ax2.plot(t, E, "k--", label="E")
ax2.set_xlabel("t [s]")
ax2.legend()
plt.show()

# %% [markdown]
# ## Exercises
#
# 1. Start with u1 = 0.5 m/s and u3 = 1 rad/s. Predict the final forward speed from the energy,
#    then check it with a run.
# 2. Put the mass centre behind the blade, a = −0.5 m (parameters go in `"params"`). Which way
#    does the sleigh end up sliding?
# 3. With a = 0 the sleigh is a knife edge. Does the spin die away?
# 4. Doubling the inertia I: does the spin die away faster or slower? (Compare the time at
#    which u3 falls below 1 % of its start.)
#
# The next cell computes the answers and checks them.

# %%
def settle_time(r, fraction=0.01):
    u3 = np.abs(np.asarray(r.state["u3"]))
    return float(np.asarray(r.t)[np.argmax(u3 < fraction * u3[0])])


init = {"u1": 0.5, "u3": 1.0}
predicted = np.sqrt((m * 0.5**2 + J * 1.0**2) / m)
ex1 = simulate({"system": "chaplygin-sleigh", "t_final": 30.0, "initial": init})
assert abs(ex1.state["u1"][-1] - predicted) < 1e-6, (ex1.state["u1"][-1], predicted)

ex2 = simulate({"system": "chaplygin-sleigh", "t_final": 30.0, "params": {"a": -0.5}})
assert ex2.state["u1"][-1] < 0 and abs(ex2.state["u3"][-1]) < 1e-3  # backwards, straight

ex3 = simulate({"system": "chaplygin-sleigh", "t_final": 20.0, "params": {"a": 0.0}})
assert np.allclose(ex3.state["u3"], 2.0)  # spins for ever

heavy = simulate({"system": "chaplygin-sleigh", "t_final": 40.0, "params": {"I": 0.2}})
assert settle_time(heavy) > settle_time(run)  # more inertia: slower
print(f"1: {predicted:.6f} m/s   2: backwards at {ex2.state['u1'][-1]:.4f} m/s   3: no   4: slower "
      f"({settle_time(run):.2f} s → {settle_time(heavy):.2f} s)")
