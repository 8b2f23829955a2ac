"""Minimal MuJoCo reproduction: two box finger pads pinching a cylinder off their centre.

Two boxes the size of the Panda's finger pads (half sides 11 x 7.5 x 10 mm, as its URDF's
collision boxes) close along y on a free cylinder of radius 30 mm (the demo can, 0.1 kg,
friction 0.6), their centres ``offset`` behind its axis along x, with the physics world's
settings (implicitfast, 2 ms, elliptic cones, impratio 10, 20 N per finger). When the
pads do not reach the axis (offset > 11 mm) their vertical edges touch the can where its
surface is inclined by asin((offset - 11 mm) / 30 mm) (8 deg at 15 mm, 17 deg at 20 mm):
Coulomb friction of 0.6 would hold it (tan 31 deg), yet MuJoCo squeezes the can out along
x: the contact normal it computes for the edge turns to the pad's side face (90 deg).
This is what fails the Panda's physics trials with errors of 1.5 cm and more across the
fingers (README, Physics execution).

Run (a second)::

    python benchmarks/physics_edge_contact.py
    python benchmarks/physics_edge_contact.py --json edge.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

XML = """<mujoco>
<option timestep="0.002" integrator="implicitfast" cone="elliptic" impratio="10"/>
<worldbody>
  <geom type="plane" size="1 1 .1"/>
  <body name="can" pos="0 0 0.06"><freejoint/>
    <geom type="cylinder" size="0.03 0.06" mass="0.1" friction="0.6 0.005 0.0001"
          condim="4" priority="1"/></body>
  <body pos="{x} -0.045 0.06"><joint name="left" type="slide" axis="0 1 0" armature="0.01"/>
    <geom type="box" size="0.011 0.0075 0.01"/></body>
  <body pos="{x} 0.045 0.06"><joint name="right" type="slide" axis="0 -1 0" armature="0.01"/>
    <geom type="box" size="0.011 0.0075 0.01"/></body>
</worldbody>
<actuator>
  <position joint="left" kp="2000" kv="40" forcerange="-20 20" forcelimited="true"/>
  <position joint="right" kp="2000" kv="40" forcerange="-20 20" forcelimited="true"/>
</actuator>
</mujoco>"""


def squeeze(offset: float) -> tuple[float, float]:
    """The can's x [m] after 3 s of closing, and the largest angle from y [deg] of a
    pad-can contact normal while closing (MuJoCo's)."""
    model = mujoco.MjModel.from_xml_string(XML.format(x=-offset))
    data = mujoco.MjData(model)
    angle = 0.0
    for k in range(1500):
        data.ctrl[:] = min(0.04, 0.05 * k * model.opt.timestep)
        mujoco.mj_step(model, data)
        for i in range(data.ncon):
            if 0 not in data.contact.geom[i]:
                normal = data.contact.frame[i][:3]
                angle = max(angle, float(np.degrees(np.arccos(min(1.0, abs(normal[1]))))))
    return float(data.qpos[0]), angle


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=None, help="also write the rows as JSON here")
    args = parser.parse_args()
    rows = []
    for offset in (0.0, 0.005, 0.01, 0.012, 0.015, 0.02):
        x, angle = squeeze(offset)
        true = float(np.degrees(np.arcsin(max(0.0, offset - 0.011) / 0.03)))
        rows.append({"offset_m": offset, "incline_deg": true, "normal_deg": angle, "can_x_m": x})
    print(
        _common.markdown_table(
            [
                "pads behind the axis [mm]",
                "edge's true incline [deg]",
                "MuJoCo normal's largest angle from y [deg]",
                "can x after closing [mm]",
            ],
            [
                [
                    f"{r['offset_m'] * 1e3:.0f}",
                    f"{r['incline_deg']:.0f}",
                    f"{r['normal_deg']:.0f}",
                    f"{r['can_x_m'] * 1e3:.1f}",
                ]
                for r in rows
            ],
            left=0,
        )
    )
    _common.write_json(args.json, {"machine": _common.machine_info(), "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
