"""The README's real-data calibration from Python: the bundled UR10 Series B (IPA, MIT licence),
50 random poses calibrated and 1445 held out, the acceptance criterion judged, the identified
robot's forward kinematics at the held-out poses. Checks its own result; CI runs it.

    python python/examples/ur10_series_b.py
"""

import pathlib

import numpy as np

import calib

root = pathlib.Path(__file__).resolve().parents[2]
robot = calib.Robot.from_file(root / "host-tools/robots/ur10.toml")
data = calib.Dataset.from_file(
    root / "host-tools/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv",
    profile=root / "host-tools/profiles/ipa-ur10-lasertracker.toml",
)
result = calib.calibrate(robot, data, validate=0.9666, accept=["95% <= 1 mm"])
report = result.report()
held_out = report["held_out"]["after"]["position"]
print(f"{len(data)} poses; held out: 50 % {held_out['p50_mm']:.3f} mm, 95 % {held_out['p95_mm']:.3f} mm, "
      f"max {held_out['max_mm']:.3f} mm; accepted: {result.accepted}")
for name, value, se in zip(result.parameter_names[:4], result.parameter_values, result.standard_errors):
    print(f"  {name} = {value:+.4f} +- {se:.4f}")
identified = result.robot
poses = identified.fk(data.joints_rad)  # (1495, 4, 4), mm
print(f"forward kinematics of the identified robot: {poses.shape}")
assert result.accepted and held_out["p95_mm"] < 1.0 and poses.shape == (1495, 4, 4)
assert np.isfinite(result.parameter_values).all()
