"""Physics execution (openup_ompl.physics): the MuJoCo world, the rollout and its verdict."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as ou
from openup_ompl.exceptions import ConfigError
from openup_ompl.physics import (
    PhysicsOptions,
    Rollout,
    build_world,
    execute_plan,
    read_execution,
    rollout,
)
from openup_ompl.physics.record import check_execution
from openup_ompl.physics.trajectory import time_path

mujoco = pytest.importorskip("mujoco")

SCENES = Path(__file__).resolve().parents[1] / "scenes"
#: Largest arm tracking error [rad] along a plan at the default gains (measured 3-11 mrad
#: on the three shipped robots' demo plans).
ARM_TRACKING_BOUND = 0.02
#: Largest hand tracking error [rad or m] before any contact (the Allegro's law jumps at
#: mga, ~0.05 rad measured).
HAND_TRACKING_BOUND = 0.1


def _plan_dict(scene: Path) -> dict:
    """A plan file's contents for a scene with a one-row path at the start: enough to
    build its world."""
    problem = ou.load_scene(scene)
    robot = problem.robot
    q = robot.full_q(problem.start, problem.hand_law.c[: robot.n_driven])
    return {
        "format": "openup-plan/1",
        "robot": {
            "name": robot.name,
            "urdf": str(robot.urdf),
            "package_dirs": list(robot.package_dirs),
            "palm_frame": robot.spec.palm_frame,
            "joint_names": robot.joint_names,
            "arm_joints": list(robot.spec.arm_joints),
            "hand_joints": list(robot.hand_joints),
        },
        "scene": {
            "object": problem.object.raw if problem.object else None,
            "obstacles": [shape.raw for shape in problem.obstacles],
        },
        "hand_law": {**problem.hand_law.to_dict(), "start_palm_distance": 0.3},
        "grasp_pose": problem.grasp_pose.tolist(),
        "path": [q.tolist()],
    }


@pytest.fixture(scope="module")
def panda_plan(tmp_path_factory) -> Path:
    """The Panda demo scene planned once (seed 1), as a plan file."""
    setup = ou.GraspPlanningSetup(ou.load_scene(SCENES / "panda_can.toml"))
    plan = setup.solve(time_limit=5.0, planner="ikbirrt", seed=1)
    return plan.save(tmp_path_factory.mktemp("physics") / "plan.json")


@pytest.fixture(scope="module")
def nominal(panda_plan):
    """The Panda demo plan executed at the nominal object pose."""
    return execute_plan(panda_plan)


@pytest.mark.parametrize("scene", ["panda_can", "lwa3_sdh_can", "ur5_allegro_can"])
def test_mujoco_palm_pose_is_pinocchio_forward_kinematics(scene):
    """MuJoCo's palm link pose equals Pinocchio's FK at random configurations."""
    problem = ou.load_scene(SCENES / f"{scene}.toml")
    robot = problem.robot
    world = build_world(_plan_dict(SCENES / f"{scene}.toml"))
    data = mujoco.MjData(world.model)
    pdata = robot.model.createData()
    rng = np.random.default_rng(3)
    low, high = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    for _ in range(20):
        q = rng.uniform(np.maximum(low, -3.0), np.minimum(high, 3.0))
        data.qpos[world.qpos] = q[[robot.model.joints[robot.model.getJointId(n)].idx_q
                                   for n in world.joint_names]]  # fmt: skip
        mujoco.mj_kinematics(world.model, data)
        expected = robot.palm_placement(pdata, q)
        rotation = data.xmat[world.palm_body].reshape(3, 3)
        assert np.linalg.norm(data.xpos[world.palm_body] - expected.translation) <= 5e-4
        assert np.linalg.norm(pin.log3(expected.rotation.T @ rotation)) <= 1e-3


def test_tracking_error_stays_under_the_bound(nominal):
    """Along the Panda plan the arm tracks within ARM_TRACKING_BOUND, the hand within
    HAND_TRACKING_BOUND, the lift within ARM_TRACKING_BOUND."""
    assert nominal.tracking["reach_arm"] <= ARM_TRACKING_BOUND
    assert nominal.tracking["reach_hand"] <= HAND_TRACKING_BOUND
    assert nominal.tracking["lift_arm"] <= ARM_TRACKING_BOUND


def test_nominal_panda_plan_lifts_its_can(nominal):
    """At the nominal pose the can rises with the hand and stays put in it."""
    assert nominal.success, nominal.verdict
    assert nominal.cause is None
    assert nominal.lift["object_mm"] >= 90
    assert {c["with"] for c in nominal.final_contacts} == {"can"}
    assert not nominal.obstacle_contacts
    # Stiff contacts: the squeezing fingers sink less than 2 mm into the can.
    assert nominal.penetration["robot_object_mm"] < 2.0


def test_object_15_cm_away_is_not_lifted(panda_plan):
    """With the can 15 cm away the hand closes on nothing and the trial fails."""
    record = execute_plan(panda_plan, (0.15, 0.0, 0.0), frames=False)
    assert not record.success
    assert record.cause == "no contact"
    assert record.lift["object_mm"] < 5
    assert record.first_contact is None


def test_a_can_lifted_then_lost_was_dropped_not_untouched(panda_plan):
    """A can too heavy for the Panda's grip (2.46 kg) rises with the hand, slides out and
    falls back onto the table: at the end nothing touches it and it is no higher than it
    sat, but it was ``dropped`` (its highest rise over the lift is recorded), not ``no
    contact``."""
    from openup_ompl.physics.rollout import DROPPED_RISE

    record = execute_plan(panda_plan, options=PhysicsOptions(object_mass=2.46), frames=False)
    assert record.cause == "dropped", record.verdict
    assert record.lift["object_peak_mm"] > DROPPED_RISE * 1e3 > record.lift["object_mm"]


def test_same_inputs_give_the_same_execution_file(panda_plan, tmp_path):
    """Two runs of one plan, offset and seed write identical execution.json files."""
    texts = []
    for name in ("a", "b"):
        result = _cli("execute", str(panda_plan), "--object-offset", "0", "0.01", "0.1",
                      "--seed", "4", "--out", str(tmp_path / name))  # fmt: skip
        assert result.returncode in (0, 1), result.stderr
        texts.append((tmp_path / name / "execution.json").read_bytes())
    assert texts[0] == texts[1]
    data = read_execution(tmp_path / "a" / "execution.json")
    assert data["offset"] == {"dx": 0.0, "dy": 0.01, "yaw": 0.1}
    assert data["seed"] == 4


def test_execute_cli_exit_status_and_verdict(panda_plan, tmp_path):
    """``execute`` prints one verdict line and exits 0 on a held grasp."""
    result = _cli("execute", str(panda_plan), "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("held:")
    assert len(result.stdout.splitlines()) == 1
    assert json.loads((tmp_path / "execution.json").read_text())["success"] is True


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openup_ompl", *args], capture_output=True, text=True, timeout=120
    )


def _bad_plans(panda_plan: Path, tmp: Path) -> dict[str, tuple[list[str], str]]:
    data = json.loads(panda_plan.read_text())
    no_urdf = tmp / "no_urdf.json"
    no_urdf.write_text(json.dumps({**data, "robot": {**data["robot"], "urdf": "/no/such.urdf"}}))
    old = tmp / "old.json"
    old.write_text(json.dumps({**data, "format": "openup-plan/0"}))
    return {
        "missing URDF": ([str(no_urdf)], "/no/such.urdf"),
        "not openup-plan/1": ([str(old)], "openup-plan/0"),
        "NaN offset": ([str(panda_plan), "--object-offset", "nan", "0", "0"], "nan"),
        "missing plan": ([str(tmp / "none.json")], "none.json"),
    }


@pytest.mark.parametrize(
    "case", ["missing URDF", "not openup-plan/1", "NaN offset", "missing plan"]
)
def test_bad_input_exits_2_with_one_line_naming_it(panda_plan, tmp_path, case):
    """Every bad input ends with exit status 2 and one stderr line naming the value."""
    args, named = _bad_plans(panda_plan, tmp_path)[case]
    result = _cli("execute", *args, "--out", str(tmp_path / "out"))
    assert result.returncode == 2, result.stdout
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert named in lines[0]
    assert not (tmp_path / "out" / "execution.json").exists()


def test_bad_offset_and_options_raise_config_errors(panda_plan):
    """A non-finite offset, one beyond OFFSET_MAX or a negative gain is a ConfigError
    naming it."""
    with pytest.raises(ConfigError, match="yaw"):
        execute_plan(panda_plan, (0.0, 0.0, math.inf))
    with pytest.raises(ConfigError, match="dx"):
        execute_plan(panda_plan, (1e10, 0.0, 0.0))
    with pytest.raises(ConfigError, match="arm_kp"):
        PhysicsOptions(arm_kp=-1.0)
    with pytest.raises(ConfigError, match="speed"):
        PhysicsOptions(speed=2.0)
    # A bool or a string is not a displacement (True was taken as 1 m).
    for offset in ((True, 0.0, 0.0), ("0.01", 0.0, 0.0)):
        with pytest.raises(ConfigError, match="object offset"):
            execute_plan(panda_plan, offset)
    # MuJoCo refuses a lighter body while compiling, and blamed the URDF.
    with pytest.raises(ConfigError, match="object_mass"):
        PhysicsOptions(object_mass=1e-12)
    for solimp in ((0.95, 0.99, 0.001, -0.5, 2.0), (0.95, 0.99, 0.001, 0.5, -2.0)):
        with pytest.raises(ConfigError, match="contact_solimp"):
            PhysicsOptions(contact_solimp=solimp)


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"hold": 1e9}, "hold"),
        ({"hold": True}, "hold"),
        ({"lift_height": 1e9}, "lift_height"),
        ({"lift_speed": 1e-9}, "lift_speed"),
        ({"object_jitter": 1e300}, "object_jitter"),
        ({"speed": 1e-300}, "speed"),
        ({"close_speed": 1e-9, "finger_close_speed": 1e-9}, "close_speed"),
    ],
)
def test_options_that_would_run_for_hours_are_refused(panda_plan, changes, named):
    """Every phase of a rollout is bounded (PHASE_MAX of simulated time): an option that
    would make one longer is a ConfigError naming it, raised before any simulation (these
    ran past a minute each)."""
    with pytest.raises(ConfigError, match=named):
        execute_plan(panda_plan, options=PhysicsOptions(**changes), frames=False)


def test_a_state_mujoco_resets_gives_no_verdict(panda_plan, monkeypatch):
    """An object placed where MuJoCo finds its position huge is reset by MuJoCo (which
    once read "held"): the rollout raises SimulationDiverged instead of a verdict."""
    monkeypatch.setattr(rollout, "check_offset", lambda offset: tuple(map(float, offset)))
    with pytest.raises(ou.SimulationDiverged, match="huge or non-finite position"):
        execute_plan(panda_plan, (1e10, 0.0, 0.0), frames=False)


def test_a_path_of_two_rows_is_timed_from_rest_to_rest():
    """Two rows (a plan of one straight motion) take about what a rest-to-rest motion
    under the limits takes (they once took 1e12 s: the execution never ended)."""
    rows = np.array([[0.0, 0.0], [0.4, -0.1]])
    limits = np.array([1.0, 1.0])
    timed = time_path(rows, limits, speed=0.5, acceleration=2.0)
    # At least the time at the velocity limit, at most twice accelerating then braking
    # over the whole distance.
    assert 0.4 / 0.5 <= timed.duration <= 2.0 * (0.4 / 0.5 + 2.0 * math.sqrt(0.4 / 2.0))
    times = np.linspace(0.0, timed.duration, 200)
    q = np.array([timed.at(t) for t in times])
    assert np.allclose(q[0], rows[0]) and np.allclose(q[-1], rows[-1])
    assert np.all(np.abs(np.diff(q, axis=0)) / np.diff(times)[:, None] <= 0.5 * limits * 1.001)


def test_timing_respects_the_velocity_limits():
    """The timed path never moves a joint faster than speed x its limit, starts and ends
    at the path's ends."""
    rows = np.linspace([0.0, 0.0], [1.0, -0.5], 50)
    limits = np.array([2.0, 0.5])
    rows[20:] += np.linspace([0.0, 0.0], [0.3, 0.3], 30)  # a turn at row 20
    timed = time_path(rows, limits, speed=0.5, acceleration=2.0)
    times = np.linspace(0.0, timed.duration, 400)
    q = np.array([timed.at(t) for t in times])
    velocity = np.abs(np.diff(q, axis=0)) / np.diff(times)[:, None]
    assert np.all(velocity <= 0.5 * limits * 1.001)
    assert np.allclose(q[0], rows[0]) and np.allclose(q[-1], rows[-1])


def test_the_record_names_the_jitter_drawn_on_top_of_the_offset(panda_plan):
    """With ``object_jitter`` the object starts at offset + jitter: the record keeps the
    offset asked for and the shift drawn (it once said only the offset, and a jittered
    trial read as one at the asked pose)."""
    plan = ou.read_plan(panda_plan)
    plain = Rollout(plan).run((0.0, 0.01, 0.0), seed=3, frames=True)
    shaken = Rollout(plan, PhysicsOptions(object_jitter=0.005)).run((0.0, 0.01, 0.0), seed=3)
    assert plain.jitter == {"dx": 0.0, "dy": 0.0}
    assert shaken.offset == plain.offset == {"dx": 0.0, "dy": 0.01, "yaw": 0.0}
    shift = np.array([shaken.jitter["dx"], shaken.jitter["dy"]])
    assert 0.0 < np.linalg.norm(shift) < 0.05
    assert plain.frames is not None and shaken.frames is not None
    start = np.array(shaken.frames["object"][0][:2]) - np.array(plain.frames["object"][0][:2])
    assert np.allclose(start, shift, atol=1e-4)
    data = shaken.to_dict(frames=False)
    check_execution(data)
    assert data["jitter"] == pytest.approx(shaken.jitter, abs=1e-9)


def test_rollout_frames_follow_the_phases(panda_plan):
    """The kept frames cover every phase in order, with the object's pose per frame."""
    record = Rollout(ou.read_plan(panda_plan)).run(frames=True)
    assert record.frames is not None
    phases = list(dict.fromkeys(record.frames["phase"]))
    assert phases == ["settle", "reach", "close", "squeeze", "lift", "hold"]
    assert len(record.frames["object"]) == len(record.frames["q"])


def test_physics_sweep_adds_touched_and_moved_mm(tmp_path):
    """``robustness --execute physics`` writes the kinematic columns plus touched and
    moved_mm, and keeps each trial's execution record; a kinematic run's grasps.png left
    in the directory (it would describe other trials) is removed."""
    (tmp_path / "grasps.png").write_bytes(b"a kinematic run's figure")
    result = _cli("robustness", "--execute", "physics", "--scene", str(SCENES / "panda_can.toml"),
                  "--u", "0.3", "--delta", "0", "0.02", "--seeds", "1", "--workers", "1",
                  "--quiet", "--out", str(tmp_path))  # fmt: skip
    assert result.returncode == 0, result.stderr
    with (tmp_path / "robustness.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 5
    assert list(rows[0])[:7] == ["u", "dx", "dy", "yaw", "trials", "successes", "success_rate"]
    assert {"touched", "moved_mm"} <= set(rows[0])
    trials = json.loads((tmp_path / "trials.json").read_text())[0]["trials"]
    assert all("verdict" in t and "first_contact" in t for t in trials)
    assert not (tmp_path / "grasps.png").exists()


@pytest.mark.parametrize("jacobian", ["mjJAC_DENSE", "mjJAC_SPARSE"])
def test_accelerations_solve_the_dynamics_in_a_grasp(panda_plan, jacobian):
    """MuJoCo issue 3767 (wrong accelerations from the sparse path): at the held grasp
    (contacts, the mimic constraint) MuJoCo's qacc solves M qacc = qfrc_smooth +
    qfrc_constraint, with the dense Jacobian we use and with the sparse one."""
    rollout = Rollout(ou.read_plan(panda_plan))
    rollout.run(frames=False)
    model, data = rollout.world.model, rollout.sim
    assert data.ncon > 0
    model.opt.jacobian = getattr(mujoco.mjtJacobian, jacobian)
    mujoco.mj_forward(model, data)
    inertia = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, inertia)
    expected = np.linalg.solve(inertia, data.qfrc_smooth + data.qfrc_constraint)
    assert np.abs(data.qacc - expected).max() <= 1e-6 * max(1.0, np.abs(expected).max())


@pytest.mark.slow
def test_show_of_an_execution_writes_the_rollout_pictures(panda_plan, tmp_path):
    """``show EXECUTION.json`` writes the rollout's HTML (the object keyed per frame) and
    its storyboard; the page loads in headless Chromium without a script error."""
    pytest.importorskip("matplotlib")
    pytest.importorskip("meshcat")
    executed = _cli("execute", str(panda_plan), "--object-offset", "0", "0.02", "0",
                    "--out", str(tmp_path))  # fmt: skip
    assert executed.returncode in (0, 1), executed.stderr
    result = _cli("show", str(tmp_path / "execution.json"))
    assert result.returncode == 0, result.stderr
    page, board = tmp_path / "execution.html", tmp_path / "execution_storyboard.png"
    assert page.stat().st_size > 10_000 and board.stat().st_size > 10_000
    assert '"labels": ["settle' in page.read_text()
    from test_viz import _headless

    dom = _headless(page, tmp_path, "--dump-dom").stdout
    assert 'data-state="ready"' in dom
    assert "data-errors" not in dom


def test_show_of_an_execution_without_frames_names_the_fault(panda_plan, tmp_path):
    """An execution.json without its frames (a sweep's record) is refused in one line, also
    when re-saved compactly; one of another version is refused as an execution file, not
    as a plan."""
    record = execute_plan(panda_plan, frames=False).to_dict(frames=False)
    path = tmp_path / "execution.json"
    path.write_text(json.dumps(record, separators=(",", ":")))
    result = _cli("show", str(path))
    assert result.returncode == 2
    assert len(result.stderr.splitlines()) == 1 and "frames" in result.stderr
    path.write_text(json.dumps({**record, "format": "openup-execution/9"}))
    result = _cli("show", str(path))
    assert result.returncode == 2
    assert "openup-execution/9" in result.stderr and "openup-execution/1" in result.stderr


def test_physics_judge_executes_against_the_true_object():
    """The closed loop's physics judge holds the can where the plan expects it and fails
    when the truth is 15 cm away (the plan is the same; only the world's object moves)."""
    from openup_ompl.physics.sweep import physics_judge
    from openup_ompl.robustness import displaced

    problem = ou.load_scene(SCENES / "panda_can.toml")
    setup = ou.GraspPlanningSetup(problem)
    plan = setup.solve(time_limit=5.0, planner="ikbirrt", seed=1)
    held = physics_judge(setup, plan, problem)
    assert held["success"], held["verdict"]
    assert (held["dx"], held["dy"], held["yaw"]) == (0.0, 0.0, 0.0)
    missed = physics_judge(setup, plan, displaced(problem, 0.15, 0.0))
    assert not missed["success"]
    assert missed["cause"] == "no contact"
    # The trial reports the truth's offset from the plan's object (the world holds the
    # truth, so the rollout's own offset was 0).
    assert missed["dx"] == pytest.approx(0.15) and missed["dy"] == pytest.approx(0.0)


def test_physics_closed_loop_keeps_the_trials_seeds(tmp_path):
    """A physics closed loop records each trial's own seed and the truth's offset from the
    estimate, not the rollout's jitter seed and its zero offset."""
    from openup_ompl.perception.camera import camera_of_scene
    from openup_ompl.perception.closed_loop import ClosedLoopOptions, closed_loop
    from openup_ompl.physics.sweep import physics_judge

    problem = ou.load_scene(SCENES / "panda_can.toml")
    # The scene's camera (60 degrees up): from the default 40 the fit of the Panda's can
    # collapses onto one face, and no trial would be planned.
    options = ClosedLoopOptions(
        camera=camera_of_scene(problem),
        policies=("0",),
        noises=(1.0,),
        distances=(0.6,),
        trials=2,
        first_seed=5,
    )
    records = closed_loop(problem, options, judge=physics_judge)
    assert [r["seed"] for r in records] == [5, 6]
    planned = [r for r in records if r["planned"]]
    assert planned and all(abs(r["dx"]) + abs(r["dy"]) > 0.0 for r in planned)


def test_execute_plan_takes_a_plan_and_checks_seed_and_options():
    """A Plan from solve() is executed as its file would be (it was a TypeError); a seed
    that is not an integer in [0, 2^31) and options that are not PhysicsOptions are
    ConfigErrors before any simulation."""
    plan = ou.GraspPlanningSetup(ou.load_scene(ou.default_scene_path())).solve(seed=1)
    bad = (({"seed": "a"}, "seed"), ({"seed": -1}, "seed"), ({"options": "x"}, "options"))
    for kwargs, named in bad:
        with pytest.raises(ConfigError, match=named):
            execute_plan(plan, **kwargs)
    record = execute_plan(plan, (0.0, 0.0, 0.0), frames=False)
    assert record.success


def test_an_object_placed_inside_an_obstacle_is_not_blamed_on_the_hand(panda_plan):
    """An offset that puts the can 5 cm into the wall jams it during the settle, before the
    robot moves: the verdict says it lay there, not that the hand forced it (it did)."""
    record = execute_plan(panda_plan, (-0.15, 0.0, 0.0), frames=False)
    assert record.cause == "jammed"
    assert "before the robot moved" in record.verdict and "the hand forced" not in record.verdict
