"""
Export to python-control: a pitch-attitude loop on the identified model
=======================================================================

Fit the six-derivative model to a simulated record, export the identified short period to
python-control as a state space (:func:`fdml.export.to_control`), add the pitch attitude
(theta_dot = q) and close a proportional-integral pitch-attitude loop on it. The design is
checked on the identified model; the loop's margins say how much the identification's
uncertainty may cost.
"""

import control as ct
import matplotlib.pyplot as plt
import numpy as np

import fdml
from fdml.export import to_control
from fdml.simulate import simulate_maneuver

truth = fdml.make_model("derivatives", "navion")
rec = simulate_maneuver(truth, "3211", duration=12.0, dt=0.02, noise=0.02, seed=2)
res = fdml.fit(rec, truth)
exp = to_control(res, form="statespace")
G = exp.system
print(G)
print(f"outputs {G.output_labels}; delays: {exp.delays}")

# %%
# Pitch attitude: theta = q / s. The elevator is trailing edge down positive, so a
# nose-up command needs negative elevator: the controller carries the minus sign.
q_of_de = G[G.output_labels.index("q"), 0]
theta_of_de = ct.series(q_of_de, ct.tf([1], [1, 0]))
K = -ct.tf([1.5, 0.6], [1, 0])  # PI, de = -(1.5 + 0.6/s) (theta_ref - theta)
L = ct.series(K, theta_of_de)
T = ct.feedback(L, 1)
gm, pm, wcg, wcp = ct.margin(L)
print(
    f"gain margin {20 * np.log10(gm) if np.isfinite(gm) else np.inf:.1f} dB, "
    f"phase margin {pm:.1f} deg at {wcp:.2f} rad/s"
)
print("closed-loop poles:", np.round(ct.poles(T), 3))

# %%
t = np.linspace(0, 6, 601)
tt, y = ct.step_response(T, t)
fig, ax = plt.subplots(figsize=(6, 3.2))
ax.plot(tt, np.squeeze(y))
ax.set(xlabel="time (s)", ylabel=r"$\theta / \theta_{ref}$", title="pitch-attitude step on the identified model")
ax.grid(alpha=0.3)
fig.tight_layout()
