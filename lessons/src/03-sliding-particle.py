# %% [markdown]
# # Lesson 3 — The paper's sliding particle: drift and Baumgarte stabilization
#
# Example 2 of Bajodah, Hodges & Chen (2005): a particle slides without friction on the
# parabola
#
# $$\psi = y + \frac{x^2}{l_0} - l_0 = 0$$
#
# under gravity (y points down: the parabola is a bowl). This constraint restricts the
# *position* — it is **holonomic** — but the nonminimal equations use it in acceleration form,
# ψ̈ = 0. Nothing then holds ψ itself at zero: the integrator's small errors in ψ and ψ̇ are
# never corrected and ψ **drifts**.
#
# Baumgarte's remedy (the paper's (112)–(113)) asks instead for
#
# $$\ddot\psi = \Gamma_1 \dot\psi + \Gamma_2 \psi ,$$
#
# a damped oscillator for the error: with negative gains any drift decays.

# %%
import matplotlib.pyplot as plt
import numpy as np

from nmkane_core import simulate

BASE = {"system": "sliding-particle", "dt": 0.05, "t_final": 300.0}


def violation(**settings):
    run = simulate({**BASE, **settings})
    return np.asarray(run.t), np.abs(np.asarray(run.violation["surface"]))


# %% [markdown]
# ## Γ = 0: the drift
#
# A coarse step (Δt = 0.05 s) over 300 s, as in the paper's Fig. 16, with no stabilization.

# %%
t, phi0 = violation()
print(f"Γ = 0: |ψ| at the end {phi0[-1]:.2e} m (the bowl's depth is l0 = 1 m)")
t_half, phi_half = violation(dt=0.025)
print(f"Γ = 0, Δt halved: {phi_half[-1]:.2e} m — the drift is the integrator's error, it shrinks with Δt")

# %% [markdown]
# ## Γ1 = −20, Γ2 = −100: the drift is damped
#
# The paper's gains. The error obeys ψ̈ + 20 ψ̇ + 100 ψ = 0, whose characteristic roots are
# both −10 s⁻¹: critically damped.

# %%
t, phi_d = violation(gamma1=-20.0, gamma2=-100.0)
print(f"Γ1 = −20, Γ2 = −100: |ψ| at the end {phi_d[-1]:.2e} m, max {phi_d.max():.2e} m")
print(f"reduction at the end: {phi0[-1] / phi_d[-1]:.1e}×")
print("roots of λ² − Γ1 λ − Γ2:", np.roots([1.0, 20.0, 100.0]))

# %%
fig, ax = plt.subplots(figsize=(8, 4))
ax.semilogy(t, phi0 + 1e-16, label="Γ = 0")
ax.semilogy(t_half, phi_half + 1e-16, label="Γ = 0, Δt/2")
ax.semilogy(t, phi_d + 1e-16, label="Γ1 = −20, Γ2 = −100")
ax.set_xlabel("t [s]")
ax.set_ylabel("|ψ| [m]")
ax.legend()
plt.show()

# %% [markdown]
# ## Tuning Γ
#
# Stiffer is not always better. With a fixed step the integrator must also follow the error's
# own motion, whose rates grow with the gains: when |λ| Δt is no longer small the
# stabilization itself adds error.

# %%
GAINS = [(-2.0, -1.0), (-5.0, -10.0), (-20.0, -100.0), (-40.0, -400.0), (-100.0, -2500.0)]
final = {}
for g1, g2 in GAINS:
    final[g1, g2] = violation(gamma1=g1, gamma2=g2)[1][-1]
    print(f"Γ1 = {g1:6.0f}, Γ2 = {g2:6.0f}:  |ψ(300 s)| = {final[g1, g2]:.1e} m")
best = min(final, key=final.get)
print("best of these:", best)

# %% [markdown]
# ## Exercises
#
# 1. By how many orders of magnitude do the paper's gains reduce the final violation at
#    Δt = 0.05 s?
# 2. Halving Δt without stabilization: by what factor does the drift fall? What does that say
#    about the integrator's order (Kutta–Merson is fourth order)?
# 3. Positive gains (Γ1 = +1, Γ2 = 0, 100 s): what happens to the violation?
# 4. Which pair Γ1, Γ2 makes the error equation critically damped with both roots at −5 s⁻¹?
#    Run it and check it also beats Γ = 0 by orders.
# 5. The minimal formulation (`"formulation": "minimal"`, Kane's equation in x alone): what is
#    its violation?
#
# The next cell computes the answers and checks them.

# %%
orders = np.log10(phi0[-1] / phi_d[-1])
assert orders > 4, orders

factor = phi0[-1] / phi_half[-1]
assert 16 < factor < 128, factor  # about 2^4 … 2^6: the error of a method of order four or more

_, grow = violation(gamma1=1.0, gamma2=0.0, t_final=100.0)
assert grow[-1] > 1e6 * phi0[-1], grow[-1]  # positive gains: the error grows exponentially

g1, g2 = -2 * 5.0, -(5.0**2)  # (λ + 5)² = λ² + 10 λ + 25 = λ² − Γ1 λ − Γ2
assert np.allclose(np.roots([1.0, -g1, -g2]), -5.0)
_, phi5 = violation(gamma1=g1, gamma2=g2)
assert phi5[-1] < 1e-3 * phi0[-1], phi5[-1]

_, minimal = violation(formulation="minimal")
assert minimal.max() == 0.0  # on the parabola by construction

print(f"1: {orders:.1f} orders   2: {factor:.0f}× (~2^{np.log2(factor):.1f})   3: grows to {grow[-1]:.0e} m   "
      f"4: Γ1 = {g1}, Γ2 = {g2}   5: {minimal.max()}")
