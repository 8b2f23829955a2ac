"""The hand law (the paper's Algorithm 3) for a hand of your own.

A two-joint hand with its referential configurations: ``c`` the close preshape reached at
the grasp, ``b`` the base open configuration, ``w`` the widest opening (joint units, rad or
m), ``mga`` the normalised distance of maximum grip aperture and ``u`` in [0, 1] the
uncertainty. ``d`` is the palm's distance to the grasp divided by its value at the start
(1 at the start, 0 at the grasp). Writes ``hand_law.png`` when matplotlib is installed.
Run: ``python own_robot_hand_law.py``.
"""

import numpy as np

import openup_ompl as oo

c = np.array([0.20, 0.10])  # [rad] close preshape
b = np.array([0.60, 0.40])  # [rad] base opening
w = np.array([1.00, 0.80])  # [rad] widest opening
mga = 0.25

for u in (0.0, 0.3, 1.0):
    row = [oo.open_hand(d, c, b, w, u, mga) for d in (1.0, 0.5, mga, 0.1, 0.0)]
    print(f"u = {u}:", "  ".join(np.array2string(h, precision=2) for h in row))

# Algorithm 3 jumps by (b - c) u at d = mga; continuous=True meets the plateau instead.
below = oo.open_hand(mga - 1e-9, c, b, w, 0.3, mga)
above = oo.open_hand(mga + 1e-9, c, b, w, 0.3, mga)
print("jump at mga:", np.round(below - above, 3), "= (b - c) u:", (b - c) * 0.3)

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib missing: pip install 'openup-ompl[viz]' for the figure")
else:
    d = np.linspace(0.0, 1.0, 401)
    fig, ax = plt.subplots(figsize=(5, 3))
    for u in (0.0, 0.3, 1.0):
        ax.plot(d, [oo.open_hand(x, c, b, w, u, mga)[0] for x in d], label=f"u = {u}")
    ax.axvline(mga, color="grey", linestyle=":", label="mga")
    ax.set(xlabel="d (1 = start, 0 = grasp)", ylabel="joint 1 [rad]")
    ax.legend()
    fig.tight_layout()
    fig.savefig("hand_law.png", dpi=100)
    print("figure written to hand_law.png")
