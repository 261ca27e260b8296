"""Robot geometric calibration from laser-tracker data, from Python.

The host library of the calib toolkit (the same code as the ``calib`` command line): robots
(``Robot.from_file``), measured data (``Dataset.from_file``, ``Dataset.from_arrays``), the
calibration (``calibrate``, with the options of ``calib calibrate`` as keyword arguments and the
same defaults), its JSON report as a dict and its HTML certificate. Units are in the names: mm,
rad. Errors are ``CalibError`` (``InputError``: an input refused, with how to fix it;
``NumericalError``: a computation that cannot stand behind its result).
"""

import csv as _csv
import io as _io
import json as _json
import math as _math

from ._calib import (
    CalibError,
    CalibrationResult,
    Dataset,
    Plan,
    InputError,
    NumericalError,
    Robot,
    __version__,
)
from ._calib import calibrate as _calibrate
from ._calib import compensate_csv as _compensate_csv
from ._calib import evaluate_json as _evaluate_json
from ._calib import plan


def _report(self):
    """The JSON report as a dict: the keys of ``calib calibrate --report``."""
    return _json.loads(self.report_json())


CalibrationResult.report = _report
Plan.report = _report


def _from_dh(name, a_mm, alpha_rad, theta_offset_rad, d_mm, beta_rad=None, limits_rad=None,
             base_xyz_mm=None, base_rpy_rad=None, tool_xyz_mm=None, tool_rpy_rad=None):
    """A robot from arrays of its Hayati-modified DH parameters, one value per joint (docs/
    ARCHITECTURE.md: ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)``, ``theta_i = q_i +
    theta_offset_i``): lengths in mm, angles in rad; ``limits_rad`` (joints, 2); the base and tool
    frames as xyz (mm) and roll, pitch, yaw (rad, ``R = Rz(yaw) Ry(pitch) Rx(roll)``). The robot
    file it makes is checked as a file is."""
    columns = [list(map(float, c)) for c in (a_mm, alpha_rad, theta_offset_rad, d_mm)]
    joints = len(columns[0])
    beta = [0.0] * joints if beta_rad is None else list(map(float, beta_rad))
    if any(len(c) != joints for c in columns + [beta]):
        raise InputError(f"from_dh: every parameter needs {joints} values, one per joint")
    number = lambda v: repr(float(v))
    lines = [f"name = {_json.dumps(str(name))}", ""]
    for j in range(joints):
        lines += ["[[joint]]", f"a_mm = {number(columns[0][j])}",
                  f"alpha_deg = {number(_math.degrees(columns[1][j]))}",
                  f"theta_offset_deg = {number(_math.degrees(columns[2][j]))}",
                  f"d_mm = {number(columns[3][j])}", f"beta_deg = {number(_math.degrees(beta[j]))}"]
        if limits_rad is not None:
            low, high = limits_rad[j]
            lines.append(f"limits_deg = [{number(_math.degrees(low))}, {number(_math.degrees(high))}]")
        lines.append("")
    for section, xyz, rpy in (("base", base_xyz_mm, base_rpy_rad), ("tool", tool_xyz_mm, tool_rpy_rad)):
        if xyz is not None or rpy is not None:
            xyz = [0.0, 0.0, 0.0] if xyz is None else xyz
            rpy = [0.0, 0.0, 0.0] if rpy is None else rpy
            lines += [f"[{section}]", "xyz_mm = [" + ", ".join(number(v) for v in xyz) + "]",
                      "rpy_deg = [" + ", ".join(number(_math.degrees(v)) for v in rpy) + "]", ""]
    return Robot.from_toml("\n".join(lines), name=f"<{name}>")


Robot.from_dh = staticmethod(_from_dh)


def calibrate(robot, data, holdout=None, **options):
    """Calibrates ``robot`` (a Robot) on ``data`` (a Dataset).

    ``options`` are those of ``calib calibrate`` with underscores for dashes and the same
    defaults: ``method="ipso+lm"`` (or ``"lm"``, ``"ipso"``), ``frames``, ``model``,
    ``validate=FRACTION``, ``validate_seed``, ``loss``, ``seed``, ``accept=["95% <= 0.5 mm"]``, ...
    ``holdout`` is a Dataset held out for validation. Returns a CalibrationResult (``.report()``,
    ``.robot``, ``.parameter_names``, ``.parameter_values``, ``.standard_errors``, ``.html()``).
    The GIL is released while it runs.
    """
    return _calibrate(robot, data, holdout, **options)


def evaluate(robot, data, **options):
    """Table 3 statistics of ``robot`` (nominal or identified) on ``data`` as a dict, as
    ``calib evaluate --json`` prints them; its options as keyword arguments (``fit_frames``,
    ``fit_poses``, ``seed``, ``stored_registration``). Robot and data read from files."""
    return _json.loads(_evaluate_json(robot, data, **options))


def compensate(robot, params, targets, **options):
    """The joints that put the identified robot ``params`` on each target pose of the file
    ``targets`` (``calib compensate``), for a controller that plans with the nominal ``robot``;
    its options as keyword arguments (``targets_frame``, ``joint_targets``, ``max_correction_mm``,
    ``near_deg``, ``branch``, ...). Both robots read from files. Returns the output table as a
    dict: column name to list, one entry per target in file order (numbers as float, empty
    cells as None); rows whose ``status`` is not ``ok`` carry the reason."""
    text = _compensate_csv(robot, params, targets, **options)
    rows = list(_csv.reader(line for line in _io.StringIO(text) if not line.startswith("#")))
    header, body = rows[0], rows[1:]

    def value(cell):
        try:
            return float(cell)
        except ValueError:
            return cell if cell != "" else None

    return {name: [value(row[i]) if i < len(row) else None for row in body] for i, name in enumerate(header)}


__all__ = [
    "CalibError",
    "CalibrationResult",
    "Dataset",
    "InputError",
    "Plan",
    "NumericalError",
    "Robot",
    "calibrate",
    "compensate",
    "evaluate",
    "plan",
    "__version__",
]
