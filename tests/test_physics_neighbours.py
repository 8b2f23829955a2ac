"""Movable obstacles in physics: free bodies whose disturbance the rollout reports."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("mujoco")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import physics_regression as regression  # noqa: E402

from openup_ompl.physics import Rollout, build_world, read_execution, write_execution  # noqa: E402
from openup_ompl.physics.sweep import physics_trial  # noqa: E402
from openup_ompl.physics.world import NEIGHBOUR  # noqa: E402

#: A thin 50 g block standing where the Panda's right finger comes down beside the can.
IN_PATH = {"name": "block", "shape": "box", "size": [0.03, 0.02, 0.12], "movable": True,
           "mass": 0.05, "pose": [0.6, 0.06, 0.06, 0.0, 0.0, 0.0, 1.0]}  # fmt: skip
#: A jar 40 cm to the side, out of every link's way.
FAR = {"name": "jar", "shape": "cylinder", "radius": 0.03, "length": 0.1, "movable": True,
       "mass": 0.2, "friction": 0.5, "pose": [0.6, -0.4, 0.05, 0.0, 0.0, 0.0, 1.0]}  # fmt: skip


@pytest.fixture(scope="module")
def contents() -> dict:
    """The stored Panda plan with the two neighbours added to its scene."""
    data = regression.plan_contents(regression.load()[0])
    data["scene"]["obstacles"] += [IN_PATH, FAR]
    return data


@pytest.fixture(scope="module")
def record(contents):
    """That plan executed at the nominal pose."""
    return Rollout(contents).run()


def test_movable_obstacles_are_free_bodies_with_their_mass_and_friction(contents):
    """Each movable obstacle is a body with a free joint, its mass and its friction;
    the fixed ones stay static geoms of the world body."""
    import mujoco

    world = build_world(contents)
    model = world.model
    assert [s.name for s in world.neighbours] == ["block", "jar"]
    for shape, body in zip(world.neighbours, world.neighbour_body, strict=True):
        assert model.body_jntnum[body] == 1
        assert model.jnt_type[model.body_jntadr[body]] == mujoco.mjtJoint.mjJNT_FREE
        assert model.body_mass[body] == pytest.approx(shape.mass)
        geom = model.geom(shape.name)
        assert world.geom_kind[geom.id] == NEIGHBOUR
    assert model.geom("jar").friction[0] == pytest.approx(0.5)
    assert model.geom_bodyid[model.geom("table").id] == 0


def test_a_neighbour_in_the_hands_path_is_pushed_and_reported(record):
    """The finger coming down knocks the block over (moved, tipped, touched in the reach);
    the far jar is neither moved nor touched; touching a neighbour is no obstacle contact."""
    block, jar = record.neighbours
    assert block["name"] == "block" and jar["name"] == "jar"
    assert block["moved"] and block["moved_mm"] > 20.0
    assert block["tipped"] and block["tilt_deg"] > 45.0
    assert block["touched"] is not None and block["touched"]["phase"] == "reach"
    assert not jar["moved"] and jar["moved_mm"] < 1.0
    assert not jar["tipped"] and jar["touched"] is None
    assert record.neighbour_moved and record.neighbour_tipped and record.neighbour_touched
    assert all(c["obstacle"] not in ("block", "jar") for c in record.obstacle_contacts)


def test_the_disturbance_is_in_the_file_the_frames_and_the_sweep_trial(record, tmp_path):
    """execution.json keeps the neighbours' fields and per-frame poses; a sweep trial
    carries neighbour_moved and neighbour_tipped."""
    data = read_execution(write_execution(record, tmp_path))
    assert data["neighbour_moved"] is True and data["neighbour_tipped"] is True
    assert [n["name"] for n in data["neighbours"]] == ["block", "jar"]
    poses = data["frames"]["neighbours"]["block"]
    assert len(poses) == len(data["frames"]["q"])
    assert poses[-1][2] < poses[0][2]  # the block's centre came down as it fell over
    trial = physics_trial(record.to_dict(frames=False))
    assert trial["neighbour_moved"] and trial["neighbour_tipped"]
    json.dumps(trial, allow_nan=False)


def test_a_scene_without_movable_obstacles_reports_no_disturbance():
    """No neighbours: an empty list and every summary field False."""
    case = regression.load()[0]
    record = Rollout(regression.plan_contents(case)).run(frames=False)
    assert record.neighbours == []
    assert not (record.neighbour_moved or record.neighbour_tipped or record.neighbour_touched)


def test_a_world_is_compiled_once_and_its_copy_takes_new_poses(contents, monkeypatch):
    """Two rollouts of one scene compile once (the second gets a copy of the model: a
    change to one does not reach the other); moving the far jar in the second plan's
    scene puts it at its new pose from the start."""
    import copy

    from openup_ompl.physics import reuse

    reuse.clear_cache()
    compiled = []
    make = reuse.make_world
    monkeypatch.setattr(reuse, "make_world", lambda *a: compiled.append(1) or make(*a))
    first = Rollout(contents)
    moved = copy.deepcopy(contents)
    moved["scene"]["obstacles"][-1]["pose"] = [0.5, -0.35, 0.05, 0.0, 0.0, 0.0, 1.0]
    second = Rollout(moved)
    assert len(compiled) == 1
    assert first.world.model is not second.world.model
    first.world.model.opt.timestep = 0.004
    assert second.world.model.opt.timestep == pytest.approx(0.002)
    record = second.run(frames=True)
    assert record.frames["neighbours"]["jar"][0][:3] == pytest.approx([0.5, -0.35, 0.05], abs=1e-3)


def test_the_watch_sensors_say_what_the_contact_list_holds(contents, monkeypatch):
    """At every step of a rollout whose hand pushes the block and squeezes the can, the
    watch's sensors give the contact list's counts and least distances: the object on
    the obstacles, the robot's moving links on the object, and on obstacles and
    neighbours; their robot parts are the robot's moving geoms."""
    import mujoco

    from openup_ompl.physics import monitor as monitor_module
    from openup_ompl.physics.world import OBJECT, OBSTACLE, ROBOT

    step, seen = monitor_module.Monitor.step, {"gripped": 0, "touching": 0}

    def checked(self, targets=None):
        step(self, targets)
        sim, kinds, watch = self.sim, self.world.geom_kind, self.world.watch
        pairs = [sorted((int(kinds[a]), int(kinds[b]))) for a, b in sim.contact.geom[: sim.ncon]]
        dist = sim.contact.dist[: sim.ncon]
        s = sim.sensordata
        for kind, at in (((OBSTACLE, OBJECT), watch.pressed), ((ROBOT, OBJECT), watch.gripped[0])):
            mine = [d for p, d in zip(pairs, dist, strict=True) if p == sorted(kind)]
            assert s[at] == len(mine)
            assert not mine or s[at + 1] == min(mine)
        touching = sum(p in ([ROBOT, OBSTACLE], [ROBOT, NEIGHBOUR]) for p in pairs)
        assert sum(s[i] for i in watch.touching) == touching
        seen["gripped"] += bool(s[watch.gripped[0]])
        seen["touching"] += bool(touching)

    monkeypatch.setattr(monitor_module.Monitor, "step", checked)
    Rollout(contents).run(frames=True)  # the block in the way; frames: every step single
    without_block = {**contents, "scene": {**contents["scene"], "obstacles": [
        o for o in contents["scene"]["obstacles"] if o["name"] != "block"]}}  # fmt: skip
    Rollout(without_block).run(frames=True)  # the can held
    assert seen["gripped"] > 1000 and seen["touching"] > 100, seen
    world = build_world(contents)
    model, kinds = world.model, world.geom_kind
    subtree = mujoco.mjtObj.mjOBJ_XBODY
    roots = {int(model.sensor_objid[i]) for i in range(model.nsensor)
             if model.sensor_objtype[i] == subtree}  # fmt: skip

    def under_a_root(body):
        while body and body not in roots:
            body = int(model.body_parentid[body])
        return body in roots

    assert [under_a_root(int(b)) for b in model.geom_bodyid] == list(kinds == ROBOT)


@pytest.mark.parametrize("early_end", [False, True])
def test_steps_run_inside_mujoco_give_the_single_steps_record(contents, early_end):
    """A rollout whose steps run in stretches inside MuJoCo (no frames kept) gives the
    record of the same rollout stepped one step at a time (frames kept), to the last bit:
    the block pushed, the can held, the can missed."""
    from openup_ompl.physics import PhysicsOptions

    without_block = {**contents, "scene": {**contents["scene"], "obstacles": [
        o for o in contents["scene"]["obstacles"] if o["name"] != "block"]}}  # fmt: skip
    for data, offset in ((contents, (0.0, 0.0, 0.0)), (without_block, (0.0, 0.0, 0.0)),
                         (without_block, (0.0, 0.03, 0.0))):  # fmt: skip
        rollout = Rollout(data, PhysicsOptions(early_end=early_end))
        assert rollout.run(offset, frames=False).to_dict(frames=False) == rollout.run(
            offset, frames=True
        ).to_dict(frames=False)
