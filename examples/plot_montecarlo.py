"""
Monte Carlo: are the standard errors honest?
============================================

Fit the six-derivative model to 24 seeded noisy simulations of the same manoeuvre and
compare, per parameter, the scatter of the estimates with the mean standard error the fits
report (efficiency = scatter / CRB; near 1 means the bounds are honest). The study is
deliberately small so the example runs in seconds; ``fdml montecarlo -n 1000`` is the real
thing.
"""

import matplotlib.pyplot as plt

import fdml
from fdml.montecarlo import monte_carlo

model = fdml.make_model("derivatives", "navion")
mc = monte_carlo(model, n=24, duration=10.0, noise=0.03, seed=0, engine="serial")
print(mc.table())

# %%
# Efficiency (scatter / mean reported standard error) per parameter. With n runs the
# scatter itself is uncertain by about 1/sqrt(2 (n - 1)), here about 15 %: values between
# 0.85 and 1.15 are consistent with honest standard errors.
fig, ax = plt.subplots(figsize=(6, 3.2))
ax.bar(range(len(mc.names)), mc.efficiency)
ax.axhline(1.0, color="k", lw=0.8)
ax.set_xticks(range(len(mc.names)), mc.names, rotation=45)
ax.set_ylabel("scatter / mean s.e.")
ax.set_title(f"{mc.n_used} Monte Carlo fits")
fig.tight_layout()
