"""Robot geometric calibration from laser-tracker data, from Python.

The host library of the calib toolkit (the same code as the ``calib`` command line): robots
(``Robot.from_file``), measured data (``Dataset.from_file``, ``Dataset.from_arrays``), the
calibration (``calibrate``, with the options of ``calib calibrate`` as typed keyword arguments and
the same defaults), its JSON report as a dict and its HTML certificate. Units are in the names: mm,
rad. Errors are ``CalibError`` (``InputError``: an input refused, with how to fix it, among them
``OptionError``, ``OptionConflictError``, ``InvalidInputError``, ``UnsupportedError``,
``TooFewError``, ``UnidentifiableError``, ``UndeterminedError`` and ``NoHeldOutError``;
``NumericalError``: a computation that cannot stand behind its result, among them
``ImplausibleError``; ``OutputError`` and ``ExternalProgramError``), each with its data as
attributes.
"""

import csv as _csv
import io as _io
import json as _json
from os import PathLike as _PathLike
from typing import Any as _Any
from typing import Mapping as _Mapping
from typing import Optional as _Optional
from typing import Sequence as _Sequence
from typing import Union as _Union

from ._calib import (
    CalibError,
    CalibrationResult,
    Dataset,
    ImplausibleError,
    OptionError,
    InvalidInputError,
    UnsupportedError,
    TooFewError,
    UndeterminedError,
    OutputError,
    ExternalProgramError,
    InputError,
    NoHeldOutError,
    NumericalError,
    OptionConflictError,
    Plan,
    Robot,
    UnidentifiableError,
    __version__,
)
from ._calib import calibrate
from ._calib import calibrate_touches_json as _calibrate_touches_json
from ._calib import compensate_csv as _compensate_csv
from ._calib import evaluate_json as _evaluate_json
from ._calib import plan
from ._calib import registry_add
from ._calib import registry_list_json as _registry_list_json
from ._calib import registry_show_json as _registry_show_json
from ._calib import registry_compare_json as _registry_compare_json
from ._calib import registry_verify_json as _registry_verify_json
from ._calib import check_shift_json as _check_shift_json
from ._calib import iso9283_evaluate_json as _iso9283_evaluate_json
from ._calib import registry_checks_json as _registry_checks_json
from ._calib import registry_pose_tests_json as _registry_pose_tests_json
from ._calib import registry_fleet_html as _registry_fleet_html


def evaluate(
    robot: Robot,
    data: Dataset,
    *,
    fit_frames: _Optional[str] = None,
    fit_poses: _Optional[int] = None,
    seed: _Optional[int] = None,
    stored_registration: bool = False,
) -> dict[str, _Any]:
    """Table 3 statistics of ``robot`` (nominal or identified) on ``data`` as a dict, as
    ``calib evaluate --json`` prints them; its options as typed keyword arguments (``fit_frames``:
    "none", "base" or "base+tool"; ``fit_poses``, ``seed``, ``stored_registration``). The data,
    from a file or arrays, are checked against ``robot`` (a file, ``Robot.from_dh`` or
    ``CalibrationResult.robot``)."""
    evaluation: dict[str, _Any] = _json.loads(
        _evaluate_json(
            robot,
            data,
            fit_frames=fit_frames,
            fit_poses=fit_poses,
            seed=seed,
            stored_registration=stored_registration,
        )
    )
    return evaluation


def calibrate_touches(
    robot: Robot,
    joints_rad: _Any,
    placements: _Sequence[str],
    sockets: _Sequence[int],
    *,
    ball_mm: tuple[float, float, float],
    train: _Optional[_Sequence[str]] = None,
    distance: _Optional[float] = None,
    distance_sd: float = 0.05,
    distance_between: tuple[int, int] = (0, 1),
    keep_ill_conditioned: bool = False,
    feature: str = "socket",
    leave_one_out: bool = False,
    tracker_joints_rad: _Any = None,
    tracker_xyz_mm: _Any = None,
    tracker_sd: float = 0.02,
    datum_planes: _Optional[_Sequence[tuple[int, tuple[float, float, float], float]]] = None,
    compliance: bool = False,
) -> tuple[Robot, dict[str, _Any], str]:
    """Calibrates ``robot`` without an instrument, as ``calib sockets`` does: a ball on the
    flange touched in sockets. ``joints_rad`` (n, joints) the configurations (numpy array or
    nested lists), ``placements`` (n) each touch's placement name, ``sockets`` (n) its socket
    (0, 1, ...); ``ball_mm`` the ball's centre in the robot file's tool frame (its flange without a [tool]; mm); ``train`` the placements
    fitted (default all; the others are held out); ``distance`` the known distance (mm) between
    the sockets ``distance_between`` of every placement, with standard uncertainty
    ``distance_sd`` (mm). ``feature="plane"`` makes the rows contacts with planes (``sockets``
    then numbers each placement's planes; mixing sockets and planes goes through a folder of
    ``hole_<n>.csv`` and ``plane_<n>.csv``); ``leave_one_out=True`` also judges each placement by
    a calibration of all the others (``report["leave_one_out"]``). ``tracker_joints_rad`` (m,
    joints) and ``tracker_xyz_mm`` (m, 3): positions of the same ball measured by a laser tracker
    (its frame, mm; at least three), fitted with the touches at the tracker's standard
    uncertainty ``tracker_sd`` (mm per coordinate); they place the robot in the tracker's frame
    and fix the scale (``report["tracker"]``). ``datum_planes``: planes known in the robot's base
    frame, ``(plane, (nx, ny, nz), offset_mm)`` each, as ``calib sockets --datum-plane`` takes
    them. ``compliance=True`` also fits the joints' torsion under gravity from the robot file's
    ``[dynamics]`` masses, kept only when it predicts left-out touches better
    (``report["torsion"]``), as ``calib sockets --compliance``. Returns the identified robot,
    the report as a dict (``parameters``, ``ball_mm``, ``identifiability`` with ``left_free``,
    ``fitted`` and ``held_out`` per placement: consistency and distance error, never absolute
    accuracy, and for held-out placements the ``predicted`` consistency) and the text ``calib
    sockets`` prints."""
    identified, report, text = _calibrate_touches_json(
        robot,
        joints_rad,
        list(placements),
        list(sockets),
        ball_mm=ball_mm,
        train=None if train is None else list(train),
        distance=distance,
        distance_sd=distance_sd,
        distance_between=distance_between,
        keep_ill_conditioned=keep_ill_conditioned,
        feature=feature,
        leave_one_out=leave_one_out,
        tracker_joints_rad=tracker_joints_rad,
        tracker_xyz_mm=tracker_xyz_mm,
        tracker_sd=tracker_sd,
        datum_planes=None if datum_planes is None else list(datum_planes),
        compliance=compliance,
    )
    parsed: dict[str, _Any] = _json.loads(report)
    return identified, parsed, text


def compensate(
    robot: Robot,
    params: Robot,
    targets: _Union[str, "_PathLike[str]", _Mapping[str, _Any]],
    **options: _Any,
) -> dict[str, list[_Union[float, str, None]]]:
    """The joints that put the identified robot ``params`` on each target pose (``calib
    compensate``), for a controller that plans with the nominal ``robot``; its options as keyword
    arguments (``targets_frame``, ``joint_targets``, ``max_correction_mm``, ``near_deg``,
    ``branch``, ...). Either robot may come from a file or from memory
    (``CalibrationResult.robot``). ``targets`` is a file (CSV), or the targets' columns as a
    mapping of column name to values (a dict of lists or numpy arrays, a pandas DataFrame), named
    as in a targets file (docs/USAGE.md, "Input formats"): ``x_mm, y_mm, z_mm`` with ``qw, qx,
    qy, qz`` (or ``rx_deg, ry_deg, rz_deg``), optional ``id`` and ``q1_deg..qN_deg`` (the
    controller's joints); with ``joint_targets=True`` the joints ``q1_deg..qN_deg`` (or
    ``_rad``) and optional ``id``. Returns the output table as a dict: column name to list, one
    entry per target in order (numbers as float, empty cells as None); rows whose ``status`` is
    not ``ok`` carry the reason."""
    if isinstance(targets, (str, _PathLike)):
        text = _compensate_csv(robot, params, targets, **options)
    else:
        text = _compensate_csv(robot, params, "<targets arrays>", text=_columns_as_csv(targets), **options)
    rows = list(_csv.reader(line for line in _io.StringIO(text) if not line.startswith("#")))
    header, body = rows[0], rows[1:]

    def value(cell: str) -> _Union[float, str, None]:
        try:
            return float(cell)
        except ValueError:
            return cell if cell != "" else None

    return {name: [value(row[i]) if i < len(row) else None for row in body] for i, name in enumerate(header)}


def _columns_as_csv(columns: _Mapping[str, _Any]) -> str:
    """The text of a targets file with these columns: numbers written exactly (``repr``), the
    ``id`` column as text. InputError for columns of unequal length or a value that is not a
    number."""
    if not hasattr(columns, "keys"):
        raise TypeError(
            f"targets: give a file path or a mapping of column name to values, not {type(columns).__name__}"
        )
    names = [str(name) for name in columns.keys()]
    values = [list(columns[name]) for name in columns.keys()]
    lengths = {len(v) for v in values}
    if len(lengths) > 1:
        counts = ", ".join(f"{n} {len(v)}" for n, v in zip(names, values))
        raise InputError(f"targets: every column needs one value per target; the lengths differ ({counts})")
    out = _io.StringIO()
    writer = _csv.writer(out, lineterminator="\n")
    writer.writerow(names)
    rows = zip(*values) if values else iter(())
    for row, cells in enumerate(rows):
        line = []
        for name, cell in zip(names, cells):
            if name == "id":
                line.append(str(cell))
                continue
            try:
                line.append(repr(float(cell)))
            except (TypeError, ValueError):
                raise InputError(f"targets[{name!r}][{row}] = {cell!r} is not a number") from None
        writer.writerow(line)
    return out.getvalue()


def registry_list(db: _Union[str, "_PathLike[str]"] = "calib.db", serial: _Optional[str] = None) -> list[dict[str, _Any]]:
    """The calibrations registered in ``db`` (of robot ``serial`` only, when given), as ``calib
    registry list --json`` gives them: one dict per calibration (``id``, ``serial``, ``model``,
    ``kind``, ``calibrated_at``, ``held_out_mm``, ``software``), by robot and date. A pandas
    frame is ``pandas.DataFrame(calib.registry_list(db))``."""
    parsed: list[dict[str, _Any]] = _json.loads(_registry_list_json(db, serial))
    return parsed


def registry_show(id: int, db: _Union[str, "_PathLike[str]"] = "calib.db") -> dict[str, _Any]:
    """The registered calibration ``id`` of ``db`` whole, as ``calib registry show --json`` gives
    it: the report (parsed), the identified robot file, the files' SHA-256, the held-out figures
    and the covariance."""
    parsed: list[dict[str, _Any]] = _json.loads(_registry_show_json(id, db))
    return parsed[0]


def registry_compare(a: int, b: int, db: _Union[str, "_PathLike[str]"] = "calib.db", poses: int = 1000) -> dict[str, _Any]:
    """Calibration ``b`` against calibration ``a`` of ``db``, as ``calib registry compare A B
    --json`` gives it: each parameter's change with its standard deviation from both
    calibrations' uncertainty (``parameters``), the joint Mahalanobis test (``joint_test``) and
    the tool's movement over ``poses`` configurations (``movement``, mm)."""
    parsed: dict[str, _Any] = _json.loads(_registry_compare_json(a, b, db, poses))
    return parsed


def registry_verify(
    serial: str,
    *,
    block: _Optional[_Union[str, "_PathLike[str]"]] = None,
    robot: _Optional[_Union[str, "_PathLike[str]"]] = None,
    db: _Union[str, "_PathLike[str]"] = "calib.db",
) -> dict[str, _Any]:
    """Is the right calibration on the controller? A parameter block (``block``) or a robot file
    (``robot``) against robot ``serial``'s calibrations, as ``calib registry verify --json``
    gives it (``passed`` only for the latest calibration)."""
    parsed: dict[str, _Any] = _json.loads(_registry_verify_json(serial, block=block, robot=robot, db=db))
    return parsed


def registry_checks(serial: str, db: _Union[str, "_PathLike[str]"] = "calib.db") -> dict[str, _Any]:
    """Robot ``serial``'s shift checks in ``db``, oldest first, as ``calib registry checks --json``
    gives them: ``checks`` (one dict per check: ``checked_at``, ``mean_mm``, ``max_mm``,
    ``drifted``, ``cause``, ...) and ``drift_rate`` (mm per 30 days with its standard error, or
    ``None``). A pandas frame is ``pandas.DataFrame(calib.registry_checks(serial, db)["checks"])``."""
    parsed: dict[str, _Any] = _json.loads(_registry_checks_json(serial, db))
    return parsed


def registry_pose_tests(serial: str, db: _Union[str, "_PathLike[str]"] = "calib.db") -> list[dict[str, _Any]]:
    """Robot ``serial``'s ISO 9283 pose tests in ``db``, oldest first, as ``calib registry
    pose-tests --json`` gives them (``id``, ``tested_at``, ``cycles``, the largest ``ap_mm`` and
    ``rp_mm``, ...); a pandas frame is ``pandas.DataFrame(calib.registry_pose_tests(serial, db))``.
    One test whole: :func:`registry_pose_test`."""
    parsed: list[dict[str, _Any]] = _json.loads(_registry_pose_tests_json(serial, None, db))
    return parsed


def registry_pose_test(serial: str, id: int, db: _Union[str, "_PathLike[str]"] = "calib.db") -> dict[str, _Any]:
    """Robot ``serial``'s ISO 9283 pose test ``id`` whole, as ``calib registry pose-tests --id ID
    --json`` gives it (each point's AP and RP, distance and drift characteristics)."""
    parsed: dict[str, _Any] = _json.loads(_registry_pose_tests_json(serial, id, db))
    return parsed


def registry_fleet(
    db: _Union[str, "_PathLike[str]"] = "calib.db", interval_days: int = 365, today: _Optional[str] = None
) -> str:
    """The fleet page of ``db`` as HTML text (``calib registry fleet``): every robot with its last
    calibration, when it falls due (``interval_days`` after it; overdue before ``today``,
    ``YYYY-MM-DD``, default today), its last shift check and pose test."""
    return _registry_fleet_html(db, interval_days, today)


def check_shift(
    serial: str,
    data: _Union[str, "_PathLike[str]"],
    *,
    profile: _Optional[_Union[str, "_PathLike[str]"]] = None,
    record: _Optional[int] = None,
    k: float = 3.0,
    limit_mm: _Optional[float] = None,
    noise_mm: _Optional[float] = None,
    register_tracker: bool = False,
    checked_at: _Optional[str] = None,
    db: _Union[str, "_PathLike[str]"] = "calib.db",
) -> dict[str, _Any]:
    """``calib check-shift``: robot ``serial``'s poses in ``data`` against its registered
    calibration, the check recorded in ``db``; as ``--json`` gives it (``result["drifted"]``,
    ``result["cause"]``, ``drift_rate``). A drift is a result, not an exception."""
    parsed: dict[str, _Any] = _json.loads(
        _check_shift_json(
            serial, data, profile=profile, record=record, k=k, limit_mm=limit_mm, noise_mm=noise_mm,
            register_tracker=register_tracker, checked_at=checked_at, db=db,
        )
    )
    return parsed


def iso9283_evaluate(
    targets: _Union[str, "_PathLike[str]"],
    data: _Union[str, "_PathLike[str]"],
    robot: _Union[str, "_PathLike[str]"],
    *,
    profile: _Optional[_Union[str, "_PathLike[str]"]] = None,
) -> dict[str, _Any]:
    """``calib iso9283 evaluate``: the ISO 9283 pose characteristics of the measured run
    ``data`` against the commanded poses ``targets`` (``calib iso9283 plan --targets``), in the
    measurement setup of the identified robot file ``robot``; as ``--json`` gives it
    (``result["characteristics"]["points"]`` with ``ap_mm`` and ``rp_mm``, ``distance``,
    ``drift``)."""
    parsed: dict[str, _Any] = _json.loads(_iso9283_evaluate_json(targets, data, robot, profile=profile))
    return parsed


__all__ = [
    "CalibError",
    "CalibrationResult",
    "Dataset",
    "ImplausibleError",
    "OptionError",
    "InvalidInputError",
    "UnsupportedError",
    "TooFewError",
    "UndeterminedError",
    "OutputError",
    "ExternalProgramError",
    "InputError",
    "NoHeldOutError",
    "OptionConflictError",
    "Plan",
    "NumericalError",
    "Robot",
    "UnidentifiableError",
    "calibrate",
    "calibrate_touches",
    "compensate",
    "evaluate",
    "plan",
    "check_shift",
    "iso9283_evaluate",
    "registry_add",
    "registry_checks",
    "registry_compare",
    "registry_fleet",
    "registry_list",
    "registry_pose_test",
    "registry_pose_tests",
    "registry_show",
    "registry_verify",
    "__version__",
]
