"""The Python package against the command line and an independent numpy model (issue 42).

Run after ``pip install ./python pytest pandas`` with the ``calib`` binary of the same checkout built
(``cargo build --release``; ``CALIB_BIN`` names another).
"""

import json
import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

import calib

ROOT = pathlib.Path(__file__).resolve().parents[2]
UR10 = ROOT / "host-tools/robots/ur10.toml"
SERIES_B = ROOT / "host-tools/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
PROFILE = ROOT / "host-tools/profiles/ipa-ur10-lasertracker.toml"
CALIB = os.environ.get("CALIB_BIN", str(ROOT / "target/release/calib"))


def run_calib(*args):
    return subprocess.run([CALIB, *map(str, args)], capture_output=True, text=True)


# A 6-joint arm with a twist (beta), base and tool frames: the file and, below, the same model
# written out in numpy from docs/ARCHITECTURE.md (A_i = Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)).
ARM = [  # a_mm, alpha_deg, theta_offset_deg, d_mm, beta_deg
    (150.0, -90.0, 0.0, 450.0, 0.0),
    (600.0, 0.0, -90.0, 0.0, 0.2),
    (120.0, -90.0, 0.0, 0.0, 0.0),
    (0.0, 90.0, 0.0, 640.0, 0.0),
    (0.0, -90.0, 0.0, 0.0, 0.0),
    (0.0, 0.0, 0.0, 100.0, 0.0),
]
BASE = ([10.0, -20.0, 30.0], [1.0, -2.0, 30.0])
TOOL = ([0.5, 1.0, 93.0], [0.0, 0.0, -90.0])


def arm_toml():
    joints = "".join(
        f"[[joint]]\na_mm = {a}\nalpha_deg = {al}\ntheta_offset_deg = {th}\nd_mm = {d}\nbeta_deg = {b}\n"
        "limits_deg = [-360.0, 360.0]\n\n"
        for a, al, th, d, b in ARM
    )
    frame = lambda name, f: f"[{name}]\nxyz_mm = {f[0]}\nrpy_deg = {f[1]}\n\n"
    return 'name = "test arm"\n\n' + joints + frame("base", BASE) + frame("tool", TOOL)


def rot(axis, angle):
    c, s = math.cos(angle), math.sin(angle)
    m = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]], "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]], "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
    t = np.eye(4)
    t[:3, :3] = m
    return t


def trans(x, y, z):
    t = np.eye(4)
    t[:3, 3] = [x, y, z]
    return t


def frame(xyz, rpy_deg):
    r, p, y = np.radians(rpy_deg)
    return trans(*xyz) @ rot("z", y) @ rot("y", p) @ rot("x", r)


def numpy_fk(q):
    t = frame(*BASE)
    for qi, (a, al, th, d, b) in zip(q, ARM):
        t = t @ rot("z", qi + math.radians(th)) @ trans(0, 0, d) @ trans(a, 0, 0) @ rot("x", math.radians(al)) @ rot("y", math.radians(b))
    return t @ frame(*TOOL)


def test_forward_kinematics_equals_an_independent_numpy_model():
    robot = calib.Robot.from_toml(arm_toml())
    assert (robot.name, robot.joints) == ("test arm", 6)
    q = np.random.default_rng(1).uniform(-3.0, 3.0, (200, 6))
    poses = robot.fk(q)
    assert poses.shape == (200, 4, 4)
    for qi, pose in zip(q, poses):
        assert np.abs(pose - numpy_fk(qi)).max() < 1e-9
    assert robot.fk(q[0]).shape == (4, 4)
    # The same arm from arrays (mm, rad).
    arrays = calib.Robot.from_dh(
        "test arm", a_mm=[j[0] for j in ARM], alpha_rad=[math.radians(j[1]) for j in ARM],
        theta_offset_rad=[math.radians(j[2]) for j in ARM], d_mm=[j[3] for j in ARM],
        beta_rad=[math.radians(j[4]) for j in ARM], limits_rad=[[-2 * math.pi, 2 * math.pi]] * 6,
        base_xyz_mm=BASE[0], base_rpy_rad=np.radians(BASE[1]), tool_xyz_mm=TOOL[0],
        tool_rpy_rad=np.radians(TOOL[1]))
    assert np.abs(arrays.fk(q) - poses).max() < 1e-9
    with pytest.raises(calib.InputError, match="every parameter needs 6 values"):
        calib.Robot.from_dh("bad", [0.0] * 6, [0.0] * 6, [0.0] * 6, [0.0] * 5)
    with pytest.raises(calib.InputError, match=r"from_dh: d_mm\[2\] = NaN is not a finite number"):
        calib.Robot.from_dh("bad", [0.0] * 6, [0.0] * 6, [0.0] * 6, [0.0, 0.0, math.nan, 0.0, 0.0, 0.0])
    with pytest.raises(calib.InputError, match=r"from_dh: limits_rad\[1\]\[0\] = -inf is not a finite number"):
        calib.Robot.from_dh("bad", [0.0] * 6, [0.0] * 6, [0.0] * 6, [0.0] * 6,
                            limits_rad=[[-1.0, 1.0], [-math.inf, 1.0]] + [[-1.0, 1.0]] * 4)
    # A robot file is checked whole when it is read, in the command's words, as an InputError.
    text = arm_toml().replace("a_mm = 150.0", "a_mm = inf")
    with pytest.raises(calib.InputError, match="joint 1: a_mm = inf is not a finite number"):
        calib.Robot.from_toml(text)
    # As `calib fk` prints it.
    out = run_calib("fk", "--robot", UR10, "--joints-deg", "10,-20,30,-40,50,-60", "--json")
    printed = json.loads(out.stdout)["position_mm"]
    pose = calib.Robot.from_file(UR10).fk(np.radians([10, -20, 30, -40, 50, -60]))
    assert np.abs(pose[:3, 3] - printed).max() < 1e-9


def test_calibrate_from_files_equals_the_command_line(tmp_path):
    report = tmp_path / "r.json"
    out = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE,
                    "--validate", "0.9666", "--accept", "95% <= 1 mm", "--report", report)
    assert out.returncode == 0, out.stderr
    cli = json.loads(report.read_text())
    robot = calib.Robot.from_file(UR10)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE)  # checked against the robot it is used with
    assert len(data) == 1495
    result = calib.calibrate(robot, data, validate=0.9666, accept=["95% <= 1 mm"])
    py = result.report()
    assert set(py) == set(cli)
    assert result.accepted is True
    assert list(py["parameters"]) == list(cli["parameters"]) == result.parameter_names
    for name, value, se in zip(result.parameter_names, result.parameter_values, result.standard_errors):
        assert abs(value - cli["parameters"][name]["value"]) < 1e-9
        assert abs(se - cli["parameters"][name]["std_error"]) < 1e-9
    for key in ("p50_mm", "p95_mm", "max_mm"):
        assert abs(py["held_out"]["after"]["position"][key] - cli["held_out"]["after"]["position"][key]) < 1e-9
    # The identified robot: the same geometry as the command's file.
    identified = result.robot
    q = data.joints_rad[:5]
    out_file = tmp_path / "identified.toml"
    identified.to_file(out_file)
    assert np.abs(calib.Robot.from_file(out_file).fk(q) - identified.fk(q)).max() == 0.0
    assert "<!DOCTYPE html>" in result.html()


def test_a_dataset_from_arrays_calibrates_as_its_file():
    robot = calib.Robot.from_file(UR10)
    files = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    arrays = calib.Dataset.from_arrays(joints_rad=files.joints_rad, positions_mm=files.positions_mm,
                                       rotations=files.rotations, frame="tracker")
    a = calib.calibrate(robot, files, method="lm")
    b = calib.calibrate(robot, arrays, method="lm")
    assert a.parameter_names == b.parameter_names
    assert np.abs(a.parameter_values - b.parameter_values).max() < 1e-9
    # Quaternions give the same poses.
    rotations = files.rotations
    quaternions = np.array([_quaternion(m) for m in rotations])
    c = calib.calibrate(robot, calib.Dataset.from_arrays(files.joints_rad, files.positions_mm, robot=robot,
                                                         quaternions_wxyz=quaternions, frame="tracker"), method="lm")
    assert np.abs(a.parameter_values - c.parameter_values).max() < 1e-6


def _quaternion(m):
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2.0
    x = math.copysign(math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2.0, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2.0, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2.0, m[1, 0] - m[0, 1])
    return [w, x, y, z]


def test_bad_inputs_raise_the_documented_exceptions():
    robot = calib.Robot.from_file(UR10)
    with pytest.raises(calib.InputError, match=r"joints_rad: shape \[3, 5\]: the robot Universal Robots UR10 has 6 joints"):
        calib.Dataset.from_arrays(np.zeros((3, 5)), np.zeros((3, 3)), robot=robot)
    # Without a robot, the joint count is checked against the robot the data are used with.
    with pytest.raises(calib.InvalidInputError, match="has 5 joint columns, the robot Universal Robots UR10 has 6 joints") as bad:
        calib.calibrate(robot, calib.Dataset.from_arrays(np.zeros((3, 5)), np.zeros((3, 3))))
    # Issue 53, item 4: the refusal's kind is its class, with its data as attributes.
    assert bad.value.input == "<memory>"
    with pytest.raises(calib.InputError, match=r"positions_mm: shape \[3, 2\], expected \(3, 3\)"):
        calib.Dataset.from_arrays(np.zeros((3, 6)), np.zeros((3, 2)), robot=robot)
    q = np.zeros((3, 6))
    q[1, 2] = np.nan
    with pytest.raises(calib.InputError, match="row 1: NaN is not a finite number"):
        calib.Dataset.from_arrays(q, np.zeros((3, 3)), robot=robot)
    with pytest.raises(calib.InputError, match="not a unit quaternion"):
        calib.Dataset.from_arrays(np.zeros((3, 6)), np.zeros((3, 3)), quaternions_wxyz=np.ones((3, 4)))
    with pytest.raises(calib.InputError, match="beyond ten turns"):
        robot.fk(np.full(6, 100.0))
    with pytest.raises(calib.InputError, match="frame"):
        calib.Dataset.from_arrays(np.zeros((3, 6)), np.zeros((3, 3)), frame="world")
    with pytest.raises(calib.CalibError):
        calib.Robot.from_file(ROOT / "no-such-robot.toml")
    # A file the data reader refuses (a robot file given as data): InputError with the reason.
    out = run_calib("check", "--robot", UR10, "--data", UR10)
    with pytest.raises(calib.InputError) as refused:
        calib.Dataset.from_file(UR10)
    assert str(refused.value).splitlines()[0] == out.stderr.splitlines()[0].removeprefix("Error: ")
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    # What the command writes is returned, not an option: a TypeError, as any keyword no option
    # has (issue 53: typed keyword arguments; issue 52 had clap's text).
    with pytest.raises(TypeError, match="unexpected keyword argument 'report'"):
        calib.calibrate(robot, data, report="r.json")
    with pytest.raises(TypeError, match="unexpected keyword argument 'no_such_option'"):
        calib.calibrate(robot, data, no_such_option=1)
    # The same refusal, in the same words, as the command line.
    out = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE, "--accept", "95% <= 1 mm")
    first = out.stderr.splitlines()[0].removeprefix("Error: ")
    with pytest.raises(calib.InputError) as refused:
        calib.calibrate(robot, data, accept=["95% <= 1 mm"])
    assert str(refused.value).splitlines()[0] == first


def test_export_gives_the_bytes_calib_export_writes(tmp_path):
    robot = calib.Robot.from_file(UR10)
    for fmt, extra in (("block", []), ("toml", []), ("urdf", []), ("ur-kinematics-yaml", []), ("block", ["--scalar", "f64"])):
        out = tmp_path / f"ur10-{len(extra)}.{fmt}"
        done = run_calib("export", "--params", UR10, "--format", fmt, "--out", out, *extra)
        assert done.returncode == 0, done.stderr
        kwargs = {"scalar": "f64"} if extra else {}
        assert robot.export(fmt, **kwargs) == out.read_bytes(), fmt
    # Two joint names for six joints: refused in the command's words.
    done = run_calib("export", "--params", UR10, "--format", "urdf", "--joint-names", "a,b", "--out", tmp_path / "x.urdf")
    with pytest.raises(calib.OptionError) as refused:
        robot.export("urdf", joint_names=["a", "b"])
    assert refused.value.option == "--joint-names"
    assert str(refused.value).splitlines()[0] == done.stderr.splitlines()[0].removeprefix("Error: ")
    with pytest.raises(calib.InputError, match="invalid value 'pdf'"):
        robot.export("pdf")
    # Issue 53: typed keyword arguments calling the library's export request; an option of
    # another format is refused as the command refuses it, by type.
    urdf = tmp_path / "named.urdf"
    done = run_calib("export", "--params", UR10, "--format", "urdf", "--joint-names", "a,b,c,d,e,f",
                     "--base-link", "world", "--joints-only", "--out", urdf)
    assert done.returncode == 0, done.stderr
    assert robot.export("urdf", joint_names=list("abcdef"), base_link="world", joints_only=True) == urdf.read_bytes()
    done = run_calib("export", "--params", UR10, "--format", "block", "--joints-only", "--out", tmp_path / "x.bin")
    with pytest.raises(calib.OptionConflictError) as conflict:
        robot.export("block", joints_only=True)
    assert conflict.value.options == ["--joints-only", "--format"]
    assert str(conflict.value).splitlines()[0] == done.stderr.splitlines()[0].removeprefix("Error: ")
    with pytest.raises(TypeError, match="unexpected keyword argument 'scaler'"):
        robot.export("block", scaler="f64")  # type: ignore[call-arg]


def test_ctrl_c_stops_a_long_calibration():
    import signal

    # A test runner started in the background by a non-interactive shell inherits SIGINT
    # ignored, and Python then never sees Ctrl-C: install Python's own handler for this test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _interrupt_a_long_calibration()
    finally:
        signal.signal(signal.SIGINT, previous)


def _interrupt_a_long_calibration():
    import signal
    import threading
    import time

    robot = calib.Robot.from_file(UR10)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        # About two minutes of swarm without the interrupt.
        calib.calibrate(robot, data, method="ipso", generations=200000)
    assert time.perf_counter() - start < 3.0


def test_evaluate_equals_calib_evaluate(tmp_path):
    identified = tmp_path / "b.toml"
    done = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE,
                     "--validate", "0.9666", "--method", "lm", "--out", identified)
    assert done.returncode == 0, done.stderr
    out = run_calib("evaluate", "--robot", identified, "--data", SERIES_B, "--profile", PROFILE,
                    "--fit-frames", "base", "--json")
    cli = json.loads(out.stdout)
    robot = calib.Robot.from_file(identified)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    py = calib.evaluate(robot, data, fit_frames="base")
    assert py == cli
    # Data read for the nominal robot, or given as arrays, are checked against the robot given:
    # the same statistics.
    nominal = calib.Robot.from_file(UR10)
    assert calib.evaluate(robot, calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=nominal), fit_frames="base") == cli
    arrays = calib.Dataset.from_arrays(data.joints_rad, data.positions_mm, rotations=data.rotations,
                                       frame="tracker")
    assert calib.evaluate(robot, arrays, fit_frames="base") == cli
    # A robot whose limits the data leave: the command's refusal.
    narrow = calib.Robot.from_toml(UR10.read_text().replace("limits_deg = [-360.0, 360.0]", "limits_deg = [-10.0, 10.0]", 1),
                                   name="narrow")
    with pytest.raises(calib.InputError, match="outside the joint limits"):
        calib.evaluate(narrow, data)
    # Issue 53: typed keyword arguments calling the library; the stored registration and frames
    # fitted on 30 poses as the command gives them.
    for words, kwargs in ((["--stored-registration"], {"stored_registration": True}),
                          (["--fit-poses", "30", "--seed", "2"], {"fit_poses": 30, "seed": 2})):
        out = run_calib("evaluate", "--robot", identified, "--data", SERIES_B, "--profile", PROFILE, *words, "--json")
        assert out.returncode == 0, out.stderr
        assert calib.evaluate(robot, data, **kwargs) == json.loads(out.stdout), words
    with pytest.raises(TypeError, match="unexpected keyword argument 'fit_frame'"):
        calib.evaluate(robot, data, fit_frame="base")  # type: ignore[call-arg]
    with pytest.raises(calib.OptionConflictError) as refused:
        calib.evaluate(robot, data, seed=3)
    assert refused.value.options == ["--seed", "--fit-poses"]
    with pytest.raises(calib.InputError, match="fit_frames: invalid value 'all': choose 'none', 'base', 'base\\+tool'"):
        calib.evaluate(robot, data, fit_frames="all")


def test_plan_equals_calib_plan(tmp_path):
    out, report = tmp_path / "plan.csv", tmp_path / "plan.json"
    done = run_calib("plan", "--robot", UR10, "--candidates", SERIES_B, "--profile", PROFILE, "--poses", "30",
                     "--measure", "position", "--noise-mm", "0.05", "--out", out, "--report", report)
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.read_text())
    robot = calib.Robot.from_file(UR10)
    p = calib.plan(robot, candidates=SERIES_B, profile=PROFILE, poses=30, measure="position", noise_mm=0.05)
    assert p.report() == cli
    assert len(p) == len(cli["poses"]) and p.roles == [q["role"] for q in cli["poses"]]
    assert np.abs(p.joints_rad - np.array([q["q"] for q in cli["poses"]])).max() == 0.0
    with pytest.raises(TypeError, match="poses"):
        calib.plan(robot)
    with pytest.raises(TypeError, match="noise"):
        calib.plan(robot, generate=300, poses=20, measure="pose", noise=0.05)
    with pytest.raises(calib.InputError, match="give the candidates"):
        calib.plan(robot, poses=20, measure="pose", noise_mm=0.05)
    with pytest.raises(calib.OptionConflictError) as refused:
        calib.plan(robot, generate=300, poses=20, measure="position", noise_mm=0.05, noise_deg=0.01)
    assert refused.value.options == ["--noise-deg", "--measure"]
    with pytest.raises(calib.InputError, match="measure: invalid value 'laser': choose 'position', 'pose'"):
        calib.plan(robot, generate=300, poses=20, measure="laser", noise_mm=0.05)


def test_compensate_equals_calib_compensate(tmp_path):
    identified = tmp_path / "b.toml"
    done = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE,
                     "--validate", "0.9666", "--method", "lm", "--out", identified)
    assert done.returncode == 0, done.stderr
    robot = calib.Robot.from_file(UR10)
    q = np.degrees(calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot).joints_rad[:12])
    targets = tmp_path / "targets.csv"
    targets.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n" + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in q))
    out = tmp_path / "c.csv"
    done = run_calib("compensate", "--robot", UR10, "--params", identified, "--targets", targets,
                     "--joint-targets", "--max-correction-mm", "15", "--out", out)
    assert done.returncode == 0, done.stderr
    import csv
    rows = list(csv.reader(line for line in out.read_text().splitlines() if not line.startswith("#")))
    py = calib.compensate(robot, calib.Robot.from_file(identified), targets, joint_targets=True, max_correction_mm=15)
    assert list(py) == rows[0]
    for i, name in enumerate(rows[0]):
        for cell, value in zip((r[i] for r in rows[1:]), py[name]):
            try:
                assert value == float(cell)
            except ValueError:
                assert value == (cell or None)
    assert len(py["status"]) == 12 and py["status"].count("ok") >= 10, py["status"]
    # The identified robot straight from a calibration in Python, never written to a file: the
    # same table.
    result = calib.calibrate(robot, calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot),
                             validate=0.9666, method="lm")
    assert calib.compensate(robot, result.robot, targets, joint_targets=True, max_correction_mm=15) == py
    # Typed keyword arguments (issue 53): a misspelt one is Python's TypeError, contradicting ones
    # an OptionConflictError naming the flags, a bad choice or bound an InputError.
    identified_robot = calib.Robot.from_file(identified)
    with pytest.raises(TypeError, match="max_correction"):
        calib.compensate(robot, identified_robot, targets, joint_targets=True, max_correction=15)
    with pytest.raises(calib.OptionConflictError) as refused:
        calib.compensate(robot, identified_robot, targets, near_deg=[0, -90, 90, 0, 90, 0], branch=2)
    assert refused.value.options == ["--near-deg", "--branch"]
    with pytest.raises(calib.OptionConflictError) as refused:
        calib.compensate(robot, identified_robot, targets, joint_targets=True, targets_frame="tracker")
    assert refused.value.options == ["--joint-targets", "--targets-frame"]
    with pytest.raises(calib.InputError, match="targets_frame: invalid value 'world': choose 'base', 'tracker', 'ur-base'"):
        calib.compensate(robot, identified_robot, targets, targets_frame="world")
    with pytest.raises(calib.InputError, match="--near-within-deg 400: give 0 to 360 deg"):
        calib.compensate(robot, identified_robot, targets, joint_targets=True, near_within_deg=400)


def test_a_pandas_frame_of_the_tracker_file_calibrates_as_the_file():
    """Series B read with pandas, its orientations turned into matrices here (intrinsic XYZ Euler
    angles in degrees, R = Rx Ry Rz, as the data profile states): the parameters of the file."""
    import pandas as pd
    frame = pd.read_csv(SERIES_B, sep=";", decimal=",")
    joints = frame[["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                    "wrist_2_joint", "wrist_3_joint"]]
    angles = np.radians(frame[["measurement_rx", "measurement_ry", "measurement_rz"]].to_numpy())
    rotations = np.array([(rot("x", a) @ rot("y", b) @ rot("z", c))[:3, :3] for a, b, c in angles])
    positions = frame[["measurement_x", "measurement_y", "measurement_z"]]
    robot = calib.Robot.from_file(UR10)
    files = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    # The file's rotations with the frame's joints and positions: the same parameters to 1e-9.
    arrays = calib.Dataset.from_arrays(joints, positions, rotations=files.rotations, frame="tracker")
    assert len(arrays) == len(files) == 1495
    assert np.array_equal(arrays.joints_rad, files.joints_rad) and np.array_equal(arrays.positions_mm, files.positions_mm)
    a = calib.calibrate(robot, files, method="lm", validate=0.9666)
    b = calib.calibrate(robot, arrays, method="lm", validate=0.9666)
    assert a.parameter_names == b.parameter_names
    assert np.abs(a.parameter_values - b.parameter_values).max() < 1e-9
    # The rotations made here differ from the profile's in the last bit (1e-16); the 50 fitted
    # poses amplify that to under 1e-6 (mm, rad), far below the standard errors.
    assert np.abs(rotations - files.rotations).max() < 1e-12
    c = calib.calibrate(robot, calib.Dataset.from_arrays(joints, positions, rotations=rotations, frame="tracker"),
                        method="lm", validate=0.9666)
    assert np.abs(a.parameter_values - c.parameter_values).max() < 1e-6
    assert np.all(np.abs(a.parameter_values - c.parameter_values) < 1e-4 * a.standard_errors)
    assert np.abs(robot.fk(joints) - robot.fk(files.joints_rad)).max() == 0.0
    text = pd.DataFrame([["0.1", "zero", "0"]])
    with pytest.raises(calib.InputError, match="joints_rad: not an array of numbers .*zero"):
        robot.fk(pd.concat([text, text], axis=1))
    with pytest.raises(calib.InputError, match="positions_mm: not an array of numbers with 2 axes"):
        calib.Dataset.from_arrays(joints[:1], text)


def test_joint_maps_and_a_re_registration_equal_the_command_line(tmp_path):
    """The paper's richest model (joint maps and gravity compliance) and then a re-registration of
    the tracker on the identified file (--identify frames): parameters equal to 1e-9."""
    maps, report = tmp_path / "maps.toml", tmp_path / "maps.json"
    options = ["--model", "joint-maps+compliance", "--validate", "0.8", "--method", "lm"]
    done = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE, *options,
                     "--out", maps, "--report", report)
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.read_text())
    robot = calib.Robot.from_file(UR10)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    result = calib.calibrate(robot, data, model="joint-maps+compliance", validate=0.8, method="lm")
    assert result.parameter_names == list(cli["parameters"])
    for name, value in zip(result.parameter_names, result.parameter_values):
        assert abs(value - cli["parameters"][name]["value"]) < 1e-9, name
    # Re-registration: the geometry, maps and compliance of the file kept, the frames fitted.
    again = tmp_path / "again.json"
    done = run_calib("calibrate", "--robot", maps, "--data", SERIES_B, "--profile", PROFILE,
                     "--identify", "frames", "--method", "lm", "--validate", "0.8", "--report", again)
    assert done.returncode == 0, done.stderr
    cli = json.loads(again.read_text())
    identified = calib.Robot.from_file(maps)
    # The whole model (geometry, maps, compliance) is evaluated by one code path: `calib fk` prints
    # the position Robot.fk computes, to the bit.
    q = [10.0, -20.0, 30.0, -40.0, 50.0, -60.0]
    out = run_calib("fk", "--robot", maps, "--joints-deg", ",".join(map(str, q)), "--json")
    assert out.returncode == 0, out.stderr
    assert identified.fk(np.radians(q))[:3, 3].tolist() == json.loads(out.stdout)["position_mm"]
    frames = calib.calibrate(identified, data, identify="frames", method="lm", validate=0.8)
    assert frames.parameter_names == list(cli["parameters"]) and len(frames.parameter_names) > 0
    for name, value in zip(frames.parameter_names, frames.parameter_values):
        assert abs(value - cli["parameters"][name]["value"]) < 1e-9, name
    py = frames.report()["held_out"]["after"]["position"]
    assert abs(py["p95_mm"] - cli["held_out"]["after"]["position"]["p95_mm"]) < 1e-9



def test_huge_arrays_raise_instead_of_ending_the_interpreter():
    # Issue 52 (V5): a broadcast array of a billion rows (48 GB as a copy) is a MemoryError and
    # a dataset of 3e8 poses an InputError; both aborted the interpreter ("memory allocation of
    # 48000000000 bytes failed").
    robot = calib.Robot.from_file(UR10)
    with pytest.raises(MemoryError, match="joints_rad"):
        robot.fk(np.broadcast_to(np.zeros(6), (1_000_000_000, 6)))
    with pytest.raises(calib.InputError, match="at most 10000000 poses"):
        calib.Dataset.from_arrays(
            np.broadcast_to(np.zeros(6), (300_000_000, 6)),
            np.broadcast_to(np.zeros(3), (300_000_000, 3)),
        )
    # The interpreter goes on: a normal call still works.
    assert robot.fk(np.zeros(6)).shape == (4, 4)


def test_options_are_keyword_arguments_and_results_say_what_they_are():
    # Issue 52: a typo in an option is a TypeError, as Python says it; results and plans print
    # what they hold; each parameter value states its unit.
    robot = calib.Robot.from_file(UR10)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    with pytest.raises(TypeError, match="unexpected keyword argument 'validat'"):
        calib.calibrate(robot, data, method="lm", validat=0.9)
    result = calib.calibrate(robot, data, method="lm", validate=0.9666)
    text = repr(result)
    assert text.startswith("CalibrationResult(robot=") and "held-out mean" in text, text
    assert "object at 0x" not in text
    units = result.parameter_units
    assert len(units) == len(result.parameter_names)
    for name, unit in zip(result.parameter_names, units):
        # Lengths (da, dd, frame translations) in mm, angles in rad.
        angle = name.startswith(("dalpha", "dtheta", "dbeta")) or name.endswith(("_rx", "_ry", "_rz"))
        assert unit == ("rad" if angle else "mm"), (name, unit)
    plan = calib.plan(robot, generate=300, poses=20, measure="pose", noise_mm=0.05)
    assert repr(plan).startswith("Plan(poses=35: core"), repr(plan)


def test_compensate_takes_targets_as_arrays(tmp_path):
    """The targets of a file given as columns in memory (a dict of numpy arrays, a pandas
    DataFrame): the table of the file, value for value."""
    import pandas as pd
    robot = calib.Robot.from_file(UR10)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    identified = calib.calibrate(robot, data, validate=0.9666, method="lm").robot
    q = np.degrees(data.joints_rad[:12])
    names = [f"q{j + 1}_deg" for j in range(6)]
    joints = {name: q[:, j] for j, name in enumerate(names)}
    path = tmp_path / "joints.csv"
    pd.DataFrame(joints).to_csv(path, index=False, float_format="%.17g")
    from_file = calib.compensate(robot, identified, path, joint_targets=True, max_correction_mm=15)
    assert from_file["status"].count("ok") >= 10, from_file["status"]
    assert calib.compensate(robot, identified, joints, joint_targets=True, max_correction_mm=15) == from_file
    # Pose targets (the nominal poses of those joints, with ids and the controller's joints as
    # starts), as a DataFrame and as the file pandas writes of it.
    poses = robot.fk(data.joints_rad[:12])
    w = np.sqrt(1.0 + np.trace(poses[:, :3, :3], axis1=1, axis2=2)) / 2.0
    frame = pd.DataFrame({
        "id": [f"T{i}" for i in range(12)],
        "x_mm": poses[:, 0, 3], "y_mm": poses[:, 1, 3], "z_mm": poses[:, 2, 3],
        "qw": w,
        "qx": (poses[:, 2, 1] - poses[:, 1, 2]) / (4.0 * w),
        "qy": (poses[:, 0, 2] - poses[:, 2, 0]) / (4.0 * w),
        "qz": (poses[:, 1, 0] - poses[:, 0, 1]) / (4.0 * w),
        **joints,
    })
    path = tmp_path / "poses.csv"
    frame.to_csv(path, index=False, float_format="%.17g")
    from_file = calib.compensate(robot, identified, path, max_correction_mm=15)
    assert from_file["id"] == [f"T{i}" for i in range(12)]
    assert calib.compensate(robot, identified, frame, max_correction_mm=15) == from_file
    with pytest.raises(calib.InputError, match=r"lengths differ \(q1_deg 12, q2_deg 3"):
        calib.compensate(robot, identified, {**joints, "q2_deg": q[:3, 1]}, joint_targets=True)
    with pytest.raises(calib.InputError, match=r"targets\['q3_deg'\]\[0\] = 'x' is not a number"):
        calib.compensate(robot, identified, {**joints, "q3_deg": ["x"] * 12}, joint_targets=True)
    with pytest.raises(TypeError, match="a file path or a mapping"):
        calib.compensate(robot, identified, q, joint_targets=True)


def test_from_craig_is_the_published_table():
    """The Panda from Franka's published table (Craig's modified DH, the flange 107 mm along z):
    the forward kinematics of that convention written out here in numpy, and of the robot file
    that writes the same table as [[craig_joint]] rows."""
    alpha = np.radians([0.0, -90.0, 90.0, 90.0, -90.0, 90.0, 90.0])
    a = [0.0, 0.0, 0.0, 82.5, -82.5, 0.0, 88.0]
    d = [333.0, 0.0, 316.0, 0.0, 384.0, 0.0, 0.0]
    limits = np.radians([[-166.0031, 166.0031], [-101.001, 101.001], [-166.0031, 166.0031],
                         [-176.0012, -3.9992], [-166.0031, 166.0031], [-1.0027, 215.0024],
                         [-166.0031, 166.0031]])
    panda = calib.Robot.from_craig("Panda", alpha, a, d, [0.0] * 7, limits_rad=limits, flange_d_mm=107.0)

    def rx(t):
        c, s = math.cos(t), math.sin(t)
        return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])

    def rz(t):
        c, s = math.cos(t), math.sin(t)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    def tx(v):
        m = np.eye(4)
        m[0, 3] = v
        return m

    def tz(v):
        m = np.eye(4)
        m[2, 3] = v
        return m

    file = calib.Robot.from_file(ROOT / "host-tools/robots/franka-panda.toml")
    rng = np.random.default_rng(7)
    for q in rng.uniform(limits[:, 0], limits[:, 1], size=(20, 7)):
        chain = np.eye(4)
        for i in range(7):
            chain = chain @ rx(alpha[i]) @ tx(a[i]) @ rz(q[i]) @ tz(d[i])
        chain = chain @ tz(107.0)
        assert np.abs(panda.fk(q) - chain).max() < 1e-9
        assert np.abs(file.fk(q) - chain).max() < 1e-9
    # Read as Hayati rows, the same numbers are another robot.
    other = calib.Robot.from_dh("not the Panda", a, alpha, [0.0] * 7, d)
    home = np.radians([0.0, 0.0, 0.0, -90.0, 0.0, 90.0, 0.0])
    assert np.abs(other.fk(home) - panda.fk(home)).max() > 100.0
    with pytest.raises(calib.InputError, match="outside the joint limits"):
        panda.fk(np.zeros(7))
    with pytest.raises(calib.InputError, match=r"from_craig: every parameter needs 7 values"):
        calib.Robot.from_craig("bad", alpha, a, d[:6], [0.0] * 7)
    with pytest.raises(calib.InputError, match=r"from_craig: flange_d_mm\[0\] = inf is not a finite number"):
        calib.Robot.from_craig("bad", alpha, a, d, [0.0] * 7, flange_d_mm=math.inf)


def test_refusals_are_exception_classes_with_their_data():
    # Issue 53: the library's typed refusals reach Python by type, with their data, and in the
    # command line's words.
    robot = calib.Robot.from_file(UR10)
    data = calib.Dataset.from_file(SERIES_B, profile=PROFILE, robot=robot)
    out = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE, "--accept", "95% <= 1 mm")
    with pytest.raises(calib.NoHeldOutError) as refused:
        calib.calibrate(robot, data, accept=["95% <= 1 mm"])
    assert str(refused.value).splitlines()[0] == out.stderr.splitlines()[0].removeprefix("Error: ")
    assert isinstance(refused.value, calib.InputError)
    out = run_calib("calibrate", "--robot", UR10, "--data", SERIES_B, "--profile", PROFILE, "--loss-scale-mm", "0.5")
    with pytest.raises(calib.OptionConflictError) as refused:
        calib.calibrate(robot, data, loss_scale_mm=0.5)
    assert refused.value.options == ["--loss-scale-mm", "--loss"]
    assert str(refused.value).splitlines()[0] == out.stderr.splitlines()[0].removeprefix("Error: ")
    with pytest.raises(calib.OptionConflictError) as refused:
        calib.calibrate(robot, data, method="lm", c1=2.5)
    assert refused.value.options == ["--c1", "--method"]
    with pytest.raises(calib.InputError, match="method: invalid value 'gauss': choose 'ipso', 'lm', 'ipso\\+lm'"):
        calib.calibrate(robot, data, method="gauss")
    with pytest.raises(TypeError):
        calib.calibrate(robot, data, validate="most")  # type: ignore[arg-type]
    # Base-frame data of 20 poses that move joints 1 and 2 only: the wrist's parameters are
    # undetermined, named with the rank the command prints.
    q = np.zeros((20, 6))
    q[:, 0] = np.linspace(-1.0, 1.0, 20)
    q[:, 1] = np.linspace(-1.5, -0.5, 20) ** 2
    poses = robot.fk(q)
    flat = calib.Dataset.from_arrays(q, poses[:, :3, 3], rotations=poses[:, :3, :3], frame="base", robot=robot)
    with pytest.raises(calib.UnidentifiableError) as refused:
        calib.calibrate(robot, flat, method="lm")
    e = refused.value
    assert 0 < e.rank < e.parameters and len(e.undetermined) == e.parameters - e.rank, (e.rank, e.parameters, e.undetermined)
    assert f"rank {e.rank} of {e.parameters}" in str(e)
    # Poses of a UR10 whose upper arm is 12 mm longer than its file says: beyond the file's
    # max_length_error_mm = 5, refused with the values kept on the exception.
    text = UR10.read_text()
    longer = calib.Robot.from_toml(text.replace("a_mm = -612.0", "a_mm = -624.0"), "longer")
    q = np.radians(np.random.default_rng(1).uniform(-170, 170, (40, 6)))
    poses = longer.fk(q)
    real = calib.Dataset.from_arrays(q, poses[:, :3, 3], rotations=poses[:, :3, :3], frame="base")
    with pytest.raises(calib.ImplausibleError) as refused:
        calib.calibrate(robot, real, method="lm")
    e = refused.value
    assert any(p.startswith("da2 = -12.0000 mm is beyond the plausible 5") for p in e.problems), e.problems
    assert abs(e.parameters["da2"] + 12.0) < 1e-6


def _touches_of(folder):
    """The touches of a MUKCa folder read with numpy (independently of the toolkit's reader):
    each socket file's rows, and per row its placement's name and its socket."""
    rows, names, sockets = [], [], []
    for placement in sorted(p.name for p in folder.iterdir() if p.is_dir()):
        for socket in (0, 1):
            q = np.loadtxt(folder / placement / f"hole_{socket}.csv", delimiter=",", ndmin=2)
            rows.append(q)
            names += [placement] * len(q)
            sockets += [socket] * len(q)
    return rows, names, sockets


def test_touches_from_numpy_equal_calib_sockets(tmp_path):
    """Issue 54: the panda_3 touches given as numpy arrays (read here with numpy, independently
    of the toolkit's reader) calibrate as ``calib sockets`` on the folder does: the same report."""
    panda = ROOT / "host-tools/robots/franka-panda.toml"
    folder = ROOT / "host-tools/data/mukca-sockets/panda_3"
    ball = (0.025171, -0.084766, 133.528298)
    report = tmp_path / "sockets.json"
    done = run_calib("sockets", "--robot", panda, "--data", folder, "--ball-mm", ",".join(map(str, ball)),
                     "--train", "frontcenter", "--distance", "50", "--report", report)
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.read_text())
    rows, names, sockets = _touches_of(folder)
    joints = np.vstack(rows)
    robot, py, text = calib.calibrate_touches(calib.Robot.from_file(panda), joints, names, sockets,
                                              ball_mm=ball, train=["frontcenter"], distance=50.0)
    assert py["parameters"] == cli["parameters"]
    assert py["held_out"] == cli["held_out"]
    held = [f["identified"]["authors_mean_mm"] for f in py["held_out"]]
    assert abs(sum(held) / len(held) - 0.2190) < 5e-5
    assert "not absolute accuracy" in text
    assert "dalpha2" in robot.to_toml()
    with pytest.raises(calib.InputError, match="placements \\(3\\) and sockets"):
        calib.calibrate_touches(calib.Robot.from_file(panda), joints, names[:3], sockets, ball_mm=ball)
    with pytest.raises(calib.InputError, match="feature \"hole\""):
        calib.calibrate_touches(calib.Robot.from_file(panda), joints, names, sockets, ball_mm=ball,
                                feature="hole")
    # Leave one placement out from Python equals the command's.
    done = run_calib("sockets", "--robot", panda, "--data", folder, "--ball-mm", ",".join(map(str, ball)),
                     "--distance", "50", "--leave-one-out", "--report", report.with_suffix(".lopo.json"))
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.with_suffix(".lopo.json").read_text())
    _, py, text = calib.calibrate_touches(calib.Robot.from_file(panda), joints, names, sockets,
                                          ball_mm=ball, distance=50.0, leave_one_out=True)
    assert py["leave_one_out"] == cli["leave_one_out"]
    left_out = [f["identified"]["authors_mean_mm"] for f in py["leave_one_out"]]
    assert len(left_out) == 6 and abs(sum(left_out) / 6 - 0.1943) < 5e-5
    assert "leave one placement out" in text


def test_torsion_from_numpy_equals_calib_sockets_compliance(tmp_path):
    """Issue 54: the joints' torsion under gravity from Python (``compliance=True``) equals
    ``calib sockets --compliance`` on the same panda_3 touches: the same gains, the same held-out
    figures, the identified robot carrying the torsions in its ``[compliance]``."""
    panda = ROOT / "host-tools/robots/franka-panda.toml"
    folder = ROOT / "host-tools/data/mukca-sockets/panda_3"
    ball = (0.025171, -0.084766, 133.528298)
    report = tmp_path / "torsion.json"
    done = run_calib("sockets", "--robot", panda, "--data", folder, "--ball-mm", ",".join(map(str, ball)),
                     "--train", "frontcenter", "--distance", "50", "--compliance", "--report", report)
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.read_text())
    rows, names, sockets = _touches_of(folder)
    robot, py, text = calib.calibrate_touches(calib.Robot.from_file(panda), np.vstack(rows), names, sockets,
                                              ball_mm=ball, train=["frontcenter"], distance=50.0,
                                              compliance=True)
    assert py["torsion"] == cli["torsion"]
    assert py["held_out"] == cli["held_out"]
    assert py["torsion"]["kept"] and py["torsion"]["joints"] == [2, 3, 4, 5]
    assert all(g >= 0.0 for g in py["torsion"]["gains_urad_per_nm"])
    held = [f["identified"]["authors_mean_mm"] for f in py["held_out"]]
    assert sum(held) / len(held) < 0.221  # the authors' calibrated model on the same split
    assert "[compliance]" in robot.to_toml() and "joints' torsion under gravity (kept)" in text


def test_tracker_positions_with_touches_equal_calib_sockets(tmp_path):
    """Issue 54, item 5: twelve tracker positions of the ball (the touches' own calibration's
    geometry and ball, computed here with numpy from ``Robot.fk``, moved 2 m and turned 90 degrees) fitted with
    the panda_3 touches from numpy equal ``calib sockets --tracker`` on the same files."""
    panda = ROOT / "host-tools/robots/franka-panda.toml"
    folder = ROOT / "host-tools/data/mukca-sockets/panda_3"
    ball = (0.025171, -0.084766, 133.528298)
    rows, names, sockets = _touches_of(folder)
    joints = np.vstack(rows)
    identified, first, _ = calib.calibrate_touches(calib.Robot.from_file(panda), joints, names, sockets,
                                                   ball_mm=ball, train=["frontcenter"], distance=50.0)
    q_tracker = np.vstack([r[0] for r in rows])
    flange = identified.fk(q_tracker)
    balls = flange[:, :3, :3] @ np.array(first["ball_mm"]) + flange[:, :3, 3]
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    measured = balls @ turn.T + np.array([2000.0, -500.0, 100.0])
    header = ",".join([f"q{j}_rad" for j in range(1, 8)] + ["x_mm", "y_mm", "z_mm"])
    tracker = tmp_path / "tracker.csv"
    np.savetxt(tracker, np.hstack([q_tracker, measured]), delimiter=",", header=header, comments="",
               fmt="%.12f")
    report = tmp_path / "mixed.json"
    done = run_calib("sockets", "--robot", panda, "--data", folder, "--ball-mm", ",".join(map(str, ball)),
                     "--train", "frontcenter", "--distance", "50", "--tracker", tracker, "--report", report)
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.read_text())
    # The values the command read: the file's decimals, parsed by numpy.
    written = np.loadtxt(tracker, delimiter=",", skiprows=1)
    _, py, text = calib.calibrate_touches(calib.Robot.from_file(panda), joints, names, sockets,
                                          ball_mm=ball, train=["frontcenter"], distance=50.0,
                                          tracker_joints_rad=written[:, :7], tracker_xyz_mm=written[:, 7:])
    assert py["parameters"] == cli["parameters"]
    assert py["tracker"] == cli["tracker"]
    assert py["tracker"]["positions"] == 12 and py["tracker"]["rms_mm"] < 0.1
    assert np.allclose(py["tracker"]["registration_xyz_mm"], [2000.0, -500.0, 100.0], atol=0.05)
    assert "tracker positions of the ball: 12" in text
    with pytest.raises(calib.InputError, match="give both"):
        calib.calibrate_touches(calib.Robot.from_file(panda), joints, names, sockets, ball_mm=ball,
                                tracker_joints_rad=q_tracker)


def test_datum_planes_from_numpy_equal_calib_sockets(tmp_path):
    """Issue 54, item 1: contacts given as planes (panda_3's ``frontcenter`` touches, each socket
    a plane's contacts), plane 0 a datum (horizontal, 18.1 mm above the base): ``calib sockets
    --datum-plane`` on a CSV and ``calibrate_touches(datum_planes=...)`` on the same rows give the
    same report, and the datum's contacts are judged against it."""
    panda = ROOT / "host-tools/robots/franka-panda.toml"
    folder = ROOT / "host-tools/data/mukca-sockets/panda_3"
    ball = (0.025171, -0.084766, 133.528298)
    rows = [np.loadtxt(folder / "frontcenter" / f"hole_{s}.csv", delimiter=",", ndmin=2) for s in (0, 1)]
    joints = np.vstack(rows)
    planes = [0] * len(rows[0]) + [1] * len(rows[1])
    data = tmp_path / "planes.csv"
    header = ",".join(["placement", "plane"] + [f"q{j}_rad" for j in range(1, 8)])
    lines = [header] + [",".join(["frontcenter", str(p)] + [repr(float(v)) for v in q]) for p, q in zip(planes, joints)]
    data.write_text("\n".join(lines) + "\n")
    report = tmp_path / "datum.json"
    done = run_calib("sockets", "--robot", panda, "--data", data, "--ball-mm", ",".join(map(str, ball)),
                     "--datum-plane", "0:0,0,1,18.1", "--report", report)
    assert done.returncode == 0, done.stderr
    cli = json.loads(report.read_text())
    _, py, text = calib.calibrate_touches(calib.Robot.from_file(panda), joints, ["frontcenter"] * len(planes),
                                          planes, ball_mm=ball, feature="plane",
                                          datum_planes=[(0, (0.0, 0.0, 1.0), 18.1)])
    assert py["parameters"] == cli["parameters"]
    assert py["fitted"] == cli["fitted"]
    assert py["datums"] == [{"plane": 0, "normal": [0.0, 0.0, 1.0], "offset_mm": 18.1}]
    known = py["fitted"][0]["identified"]["known_planes"]
    assert len(known) == 1 and known[0]["contacts"] == len(rows[0])
    assert "datum planes" in text
    with pytest.raises(calib.InputError, match="non-zero vector"):
        calib.calibrate_touches(calib.Robot.from_file(panda), joints, ["frontcenter"] * len(planes), planes,
                                ball_mm=ball, feature="plane", datum_planes=[(0, (0.0, 0.0, 0.0), 1.0)])


def test_registry_from_python_equals_calib_registry(tmp_path):
    """Issue 55, item 8: a calibration registered from Python is the record ``calib registry``
    lists and shows; the report's SHA-256 is the file's; a foreign file is refused as from the
    command line."""
    import hashlib
    panda = ROOT / "host-tools/robots/franka-panda.toml"
    folder = ROOT / "host-tools/data/mukca-sockets/panda_3"
    report, identified, db = tmp_path / "touches.json", tmp_path / "panda-3.toml", tmp_path / "fleet.db"
    done = run_calib("sockets", "--robot", panda, "--data", folder, "--ball-mm", "0.025171,-0.084766,133.528298",
                     "--train", "frontcenter", "--distance", "50", "--report", report, "--out", identified)
    assert done.returncode == 0, done.stderr
    assert calib.registry_add(report, db=db, serial="PANDA-3", identified=identified) == 1
    done = run_calib("registry", "list", "--json", "--db", db)
    assert done.returncode == 0, done.stderr
    assert calib.registry_list(db) == json.loads(done.stdout)
    record = calib.registry_show(1, db=db)
    assert record["report_sha256"] == hashlib.sha256(report.read_bytes()).hexdigest()
    assert record["identified_toml"] == identified.read_text()
    assert record["report"] == json.loads(report.read_text())
    import pandas
    frame = pandas.DataFrame(calib.registry_list(db, serial="PANDA-3"))
    assert list(frame["id"]) == [1] and frame["kind"][0] == "touches"
    with pytest.raises(calib.InputError, match="already registered for robot PANDA-3 as record 1"):
        calib.registry_add(report, db=db, serial="PANDA-3")
    foreign = tmp_path / "notes.db"
    foreign.write_text("not a database\n" * 100)
    with pytest.raises(calib.InputError, match="not a calib registry"):
        calib.registry_list(foreign)


def test_registry_compare_verify_and_shift_check_from_python(tmp_path):
    """Issue 55, items 2, 3, 5 and 8: two calibrations of the real UR10 (Series B, two draws of 50
    poses) compared, the controller's block verified and a later session (Series D) checked from
    Python: each the command line's JSON."""
    robot = ROOT / "host-tools/robots/ur10.toml"
    folder = ROOT / "host-tools/data/ipa-ur10-lasertracker"
    profile = ROOT / "host-tools/profiles/ipa-ur10-lasertracker.toml"
    db = tmp_path / "ur10.db"
    for name, seed in (("one", "1"), ("two", "2")):
        done = run_calib("calibrate", "--robot", robot, "--data", folder / "series-b-joint-configurations.csv",
                         "--profile", profile, "--validate", "0.9666", "--validate-seed", seed,
                         "--report", tmp_path / f"{name}.json", "--out", tmp_path / f"{name}.toml")
        assert done.returncode == 0, done.stderr
        calib.registry_add(tmp_path / f"{name}.json", db=db, serial="UR10-IPA", identified=tmp_path / f"{name}.toml")
    compared = calib.registry_compare(1, 2, db=db, poses=200)
    done = run_calib("registry", "compare", "1", "2", "--poses", "200", "--json", "--db", db)
    assert done.returncode == 0, done.stderr
    assert compared == json.loads(done.stdout)
    assert compared["same_robot"] and compared["joint_test"]["degrees_of_freedom"] > 0
    block = tmp_path / "two.block"
    done = run_calib("export", "--params", tmp_path / "two.toml", "--format", "block", "--out", block)
    assert done.returncode == 0, done.stderr
    verified = calib.registry_verify("UR10-IPA", block=block, db=db)
    assert verified["passed"] and verified["matched"]["id"] == 2
    older = calib.registry_verify("UR10-IPA", robot=tmp_path / "one.toml", db=db)
    assert not older["passed"] and older["matched"]["how"] == "identical file" and older["latest"] == 2
    checked = calib.check_shift("UR10-IPA", folder / "series-d-iso-cubes.csv", profile=profile,
                                register_tracker=True, checked_at="2021-08-02T08:00:00Z", db=db)
    assert checked["check"] == 1 and checked["result"]["drifted"]
    done = run_calib("registry", "checks", "--serial", "UR10-IPA", "--json", "--db", db)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["checks"][0]["mean_mm"] == checked["result"]["mean_mm"]
    import pandas
    import re
    checks = calib.registry_checks("UR10-IPA", db=db)
    assert checks == json.loads(done.stdout)
    assert pandas.DataFrame(checks["checks"])["mean_mm"].tolist() == [checked["result"]["mean_mm"]]
    # The fleet page: the robot, its shift check's drift, due a year after its last calibration
    # and overdue when judged in 2100; the command line's page but for the time it was generated.
    page = calib.registry_fleet(db=db, today="2100-01-01")
    done = run_calib("registry", "fleet", "--today", "2100-01-01", "--out", tmp_path / "fleet.html", "--db", db)
    assert done.returncode == 0, done.stderr
    generated = re.compile(r"Generated \S+")
    written = (tmp_path / "fleet.html").read_text()
    assert generated.sub("", page) == generated.sub("", written)
    assert "UR10-IPA" in page and "OVERDUE" in page and "DRIFT" in page
    with pytest.raises(calib.InputError, match="not a day of the calendar"):
        calib.registry_fleet(db=db, today="2100-13-01")
    # The defaults written out in the Python signatures are the command line's.
    import inspect
    assert f"[default: {inspect.signature(calib.registry_compare).parameters['poses'].default}]" in \
        run_calib("registry", "compare", "--help").stdout
    assert f"[default: {inspect.signature(calib.check_shift).parameters['k'].default:g}]" in \
        run_calib("check-shift", "--help").stdout


def test_an_iso9283_pose_test_evaluates_as_the_command_line(tmp_path):
    """``calib.iso9283_evaluate`` on a planned cube whose run is simulated on a robot with
    errors gives the command line's JSON, AP of each point in it."""
    robot = ROOT / "host-tools/robots/er10l-c10.toml"
    targets, run, measured = tmp_path / "targets.csv", tmp_path / "run.csv", tmp_path / "measured.csv"
    done = run_calib("iso9283", "plan", "--robot", robot, "--centre-mm", "1200,0,800", "--edge-mm", "400",
                     "--near-deg", "0,-30,30,0,60,0", "--cycles", "10", "--targets", targets, "--out", run)
    assert done.returncode == 0, done.stderr
    done = run_calib("simulate", "--robot", robot, "--errors", "random", "--seed", "5", "--joints-from", run,
                     "--position-only", "--position-sigma-mm", "0.01", "--out", measured,
                     "--truth-out", tmp_path / "truth.toml")
    assert done.returncode == 0, done.stderr
    tested = calib.iso9283_evaluate(targets, measured, robot)
    done = run_calib("iso9283", "evaluate", "--targets", targets, "--data", measured, "--robot", robot, "--json")
    assert done.returncode == 0, done.stderr
    assert tested == json.loads(done.stdout)
    points = tested["characteristics"]["points"]
    assert [p["point"] for p in points] == ["P1", "P2", "P3", "P4", "P5"]
    assert all(p["cycles"] == 10 and p["ap_mm"] > 0.1 for p in points)
    with pytest.raises(calib.CalibError, match="not been measured"):
        calib.iso9283_evaluate(targets, run, robot)
    # Recorded by the command line, read from Python: the list and the test whole.
    db = tmp_path / "cell.db"
    done = run_calib("iso9283", "evaluate", "--targets", targets, "--data", measured, "--robot", robot,
                     "--registry", db, "--serial", "ER-9", "--tested-at", "2026-11-29T10:00:00Z")
    assert done.returncode == 0, done.stderr
    listed = calib.registry_pose_tests("ER-9", db=db)
    done = run_calib("registry", "pose-tests", "--serial", "ER-9", "--json", "--db", db)
    assert listed == json.loads(done.stdout)
    assert [t["tested_at"] for t in listed] == ["2026-11-29T10:00:00Z"]
    whole = calib.registry_pose_test("ER-9", listed[0]["id"], db=db)
    assert [p["ap_mm"] for p in whole["characteristics"]["points"]] == [p["ap_mm"] for p in points]
    with pytest.raises(calib.CalibError, match="no pose test 99"):
        calib.registry_pose_test("ER-9", 99, db=db)
