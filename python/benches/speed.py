"""Benchmark (issue 42): the paper's swarm on the bundled UR10 Series B from Python against the
`calib` process, runs alternating, and forward kinematics of 1,000,000 configurations.

    python python/benches/speed.py [ROUNDS]

Prints the median wall time of each; it asserts nothing (speed goals are measured, not tested).
"""

import os
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np

import calib

root = pathlib.Path(__file__).resolve().parents[2]
ur10 = root / "host-tools/robots/ur10.toml"
data = root / "host-tools/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
profile = root / "host-tools/profiles/ipa-ur10-lasertracker.toml"
binary = os.environ.get("CALIB_BIN", str(root / "target/release/calib"))
rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
options = ["--method", "ipso", "--validate", "0.9666"]

process, python = [], []
for _ in range(rounds):
    start = time.perf_counter()
    subprocess.run([binary, "calibrate", "--robot", ur10, "--data", data, "--profile", profile, *options],
                   check=True, capture_output=True)
    process.append(time.perf_counter() - start)
    start = time.perf_counter()
    robot = calib.Robot.from_file(ur10)
    result = calib.calibrate(robot, calib.Dataset.from_file(data, profile=profile, robot=robot),
                             method="ipso", validate=0.9666)
    python.append(time.perf_counter() - start)
p, q = statistics.median(process), statistics.median(python)
print(f"paper's swarm, Series B (50 poses fitted, 1445 held out), median of {rounds}: "
      f"calib process {p:.3f} s, Python {q:.3f} s ({100 * (q / p - 1):+.1f} %)")

joints = np.random.default_rng(0).uniform(-3.0, 3.0, (1_000_000, 6))
times = []
for _ in range(rounds):
    start = time.perf_counter()
    robot.fk(joints)
    times.append(time.perf_counter() - start)
print(f"forward kinematics of 1,000,000 configurations (UR10), median of {rounds}: "
      f"{statistics.median(times):.3f} s")
