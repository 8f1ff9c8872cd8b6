# %% [markdown]
# # Lesson 1 — The knife edge: what a nonholonomic constraint is
#
# A skate on ice: a blade at the point (x, y) with heading θ. It can roll forward and turn,
# but **it cannot slip sideways**. In the body's speeds u1 (forward), u2 (sideways) and
# u3 = θ̇ (turning rate) the constraint is simply
#
# $$\varphi = u_2 = 0 .$$
#
# It restricts the *velocity*, not the position: written in the coordinates it reads
# −ẋ sin θ + ẏ cos θ = 0, and no function f(x, y, θ) = 0 integrates it. Every place and every
# heading can still be reached (think of parallel parking); only the way there is restricted.
# Such a constraint is called **nonholonomic**.
#
# nmkane's nonminimal Kane equations (Bajodah, Hodges & Chen 2005) keep all three speeds and
# enforce φ = 0 through the equations of motion. This lesson runs the system and checks that
# the constraint holds to round-off.

# %%
import matplotlib.pyplot as plt
import numpy as np

from nmkane_core import get_system, simulate

system = get_system("knife-edge")
print(system.title)
print(system.description)

# %% [markdown]
# ## A run
#
# The defaults: forward speed u1 = 1 m/s, turning rate u3 = 0.5 rad/s, for 20 s.
# `simulate` takes the run settings as a dictionary and returns the run: times `t`, the state
# by name, the energy and each constraint's violation.

# %%
run = simulate({"system": "knife-edge", "t_final": 20.0})
t = np.asarray(run.t)
s = {k: np.asarray(v) for k, v in run.state.items()}
phi = np.asarray(run.violation["no_side_slip"])
print(run.status, "—", run.summary["message"])
print("state names:", list(s))
print(f"max |φ| = {np.abs(phi).max():.1e}, max |ΔE| = {run.summary['max_abs_energy_drift']:.1e}")

# %% [markdown]
# The violation is zero to round-off: the constraint is linear in the speeds and the method
# solves for the dependent speed u2 from it at every step, so nothing drifts.
#
# We can also check it *from the path alone*, without trusting u2: the sideways velocity
# −ẋ sin θ + ẏ cos θ, with ẋ, ẏ by central differences of the computed positions, vanishes
# too (on a circle a central difference points along the tangent, so only round-off is left).

# %%
xdot = np.gradient(s["x"], t)
ydot = np.gradient(s["y"], t)
sideways = -xdot * np.sin(s["theta"]) + ydot * np.cos(s["theta"])
forward = xdot * np.cos(s["theta"]) + ydot * np.sin(s["theta"])
print(f"sideways velocity from the path: max {np.abs(sideways[1:-1]).max():.1e} m/s")
print(f"forward velocity from the path:  mean {forward.mean():.4f} m/s (u1 = {s['u1'][0]})")

# %% [markdown]
# ## The path
#
# With no forces the forward speed and the turning rate stay constant and the blade runs on a
# circle of radius u1/u3.

# %%
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
ax1.plot(s["x"], s["y"])
ax1.set_aspect("equal")
ax1.set_xlabel("x [m]")
ax1.set_ylabel("y [m]")
ax1.set_title("the contact point's path")
ax2.semilogy(t, np.abs(phi) + 1e-17, label="|φ| (the run's)")
ax2.semilogy(t[1:-1], np.abs(sideways[1:-1]), label="|sideways velocity| from the path")
ax2.set_xlabel("t [s]")
ax2.legend()
plt.show()

# %% [markdown]
# ## The blade force
#
# What keeps the blade from slipping is a sideways force at the contact point. The run reports
# it (`point_forces`, here `blade.lateral`): it is the centripetal force m u1 u3.

# %%
lateral = np.asarray(run.point_forces["blade.lateral"])
print(f"blade force: {lateral.min():.4f} … {lateral.max():.4f} N")

# %% [markdown]
# ## Exercises
#
# 1. Run with u1 = 2 m/s and u3 = 0.5 rad/s. What is the radius of the circle? Measure it from
#    the path (half the width of the x range).
# 2. How long does one lap take? (Find the time at which θ has grown by 2π.)
# 3. Set u3 = 0: how far sideways (in y, starting with θ = 0) does the skate go in 10 s?
# 4. What is the blade force for u1 = 2, u3 = 0.5 (mass 1 kg)?
#
# The next cell computes the answers and checks them.

# %%
ex1 = simulate({"system": "knife-edge", "t_final": 20.0, "initial": {"u1": 2.0, "u3": 0.5}})
x1 = np.asarray(ex1.state["x"])
radius = (x1.max() - x1.min()) / 2
assert abs(radius - 2.0 / 0.5) < 1e-3, radius

theta1 = np.asarray(ex1.state["theta"])
lap = np.interp(theta1[0] + 2 * np.pi, theta1, np.asarray(ex1.t))
assert abs(lap - 2 * np.pi / 0.5) < 1e-6, lap

ex3 = simulate({"system": "knife-edge", "t_final": 10.0, "initial": {"u3": 0.0}})
assert np.abs(np.asarray(ex3.state["y"])).max() < 1e-12  # straight ahead: no sideways motion

force = np.asarray(ex1.point_forces["blade.lateral"])
assert np.allclose(np.abs(force), 1.0 * 2.0 * 0.5), force[:3]
print(f"1: radius {radius:.4f} m   2: lap {lap:.4f} s   3: straight   4: |force| {abs(force[0]):.3f} N")
