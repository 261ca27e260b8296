"""Robot geometric calibration from laser-tracker data, from Python.

The host library of the calib toolkit (the same code as the ``calib`` command line): robots
(``Robot.from_file``), measured data (``Dataset.from_file``, ``Dataset.from_arrays``), the
calibration (``calibrate``, with the options of ``calib calibrate`` as keyword arguments and the
same defaults), its JSON report as a dict and its HTML certificate. Units are in the names: mm,
rad. Errors are ``CalibError`` (``InputError``: an input refused, with how to fix it;
``NumericalError``: a computation that cannot stand behind its result).
"""

import json as _json

from ._calib import (
    CalibError,
    CalibrationResult,
    Dataset,
    InputError,
    NumericalError,
    Robot,
    __version__,
)
from ._calib import calibrate as _calibrate


def _report(self):
    """The JSON report as a dict: the keys of ``calib calibrate --report``."""
    return _json.loads(self.report_json())


CalibrationResult.report = _report


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


__all__ = [
    "CalibError",
    "CalibrationResult",
    "Dataset",
    "InputError",
    "NumericalError",
    "Robot",
    "calibrate",
    "__version__",
]
