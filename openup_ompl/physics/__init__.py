"""Physics execution of plans in MuJoCo (optional: ``pip install mujoco``)."""
