"""Type stubs of the extension module (python/src/lib.rs). Units are in the names: mm, rad."""

from os import PathLike
from typing import Any, Optional, Sequence, Union, final

import numpy as np
import numpy.typing as npt

__version__: str
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
    "NumericalError",
    "OptionConflictError",
    "Plan",
    "Robot",
    "UnidentifiableError",
    "__version__",
    "calibrate",
    "calibrate_touches_json",
    "compensate_csv",
    "evaluate_json",
    "plan",
    "registry_add",
    "registry_list_json",
    "registry_show_json",
    "registry_compare_json",
    "registry_verify_json",
    "check_shift_json",
    "iso9283_evaluate_json",
    "registry_checks_json",
    "registry_pose_tests_json",
    "registry_fleet_html",
]

class CalibError(Exception):
    """Any error of the toolkit; the message is the command line's."""

class InputError(CalibError):
    """An input refused (a file, an array's shape, NaN, units, an option), with how to fix it."""

class NumericalError(CalibError):
    """A computation that cannot stand behind its result."""

class OptionConflictError(InputError):
    """Options that contradict each other."""

    options: list[str]
    """The options, by the command line's flags (``--loss-scale-mm``, ``--c1``)."""

class UnidentifiableError(InputError):
    """The data cannot determine every parameter asked for."""

    rank: int
    """The rank of the identification Jacobian."""
    parameters: int
    """The number of parameters asked for."""
    undetermined: list[str]
    """The parameters ``auto_mask=True`` would drop (such as ``dd2``)."""

class NoHeldOutError(InputError):
    """An acceptance criterion (``accept=``) with no held-out poses."""

class OptionError(InputError):
    """An option's value refused (out of range, not finite, the wrong count)."""

    option: str
    """The option, by the command line's flag (``--poses``)."""

class InvalidInputError(InputError):
    """An input's content refused (a file's line, a section, data not from this robot)."""

    input: str
    """The file (as given) or the input (``"the data"``, ``"joints_rad"``)."""

class UnsupportedError(InputError):
    """What this robot or model cannot do, or an output cannot carry."""

    feature: str
    """The feature or output, such as ``"gravity compliance"``."""

class TooFewError(InputError):
    """Too few poses, equations or candidates for what was asked."""

    have: int
    """How many there are."""
    need: int
    """How many are needed."""

class UndeterminedError(InputError):
    """Parameters the data cannot determine, found by a singular matrix."""

    undetermined: list[str]
    """The parameters found undetermined, where the matrix says which (else empty)."""

class OutputError(CalibError):
    """An output path that is not written (a directory, an input, another output's path)."""

    path: str
    """The path as given."""

class ExternalProgramError(CalibError):
    """An outside program the toolkit needs (a headless browser for PDFs) is missing or failed."""

    program: str
    """The program, such as ``"chromium"``."""

class ImplausibleError(NumericalError):
    """A result that fails the plausibility check; nothing is returned."""

    problems: list[str]
    """Each problem, naming the value and its bound."""
    parameters: dict[str, float]
    """The refused result's identified values by name, mm and rad."""

_Path = Union[str, "PathLike[str]"]

@final
class Robot:
    """A robot model: its robot file (TOML)."""

    @staticmethod
    def from_file(path: _Path) -> "Robot": ...
    @staticmethod
    def from_toml(text: str, name: str = "<memory>") -> "Robot": ...
    @staticmethod
    def from_dh(
        name: str,
        a_mm: Sequence[float],
        alpha_rad: Sequence[float],
        theta_offset_rad: Sequence[float],
        d_mm: Sequence[float],
        beta_rad: Optional[Sequence[float]] = None,
        limits_rad: Optional[Sequence[Sequence[float]]] = None,
        base_xyz_mm: Optional[Sequence[float]] = None,
        base_rpy_rad: Optional[Sequence[float]] = None,
        tool_xyz_mm: Optional[Sequence[float]] = None,
        tool_rpy_rad: Optional[Sequence[float]] = None,
    ) -> "Robot":
        """A robot from arrays of its Hayati-modified DH parameters (mm, rad), one value per joint.
        Not for a table in Craig's modified DH convention: that is ``Robot.from_craig``'s."""
    @staticmethod
    def from_craig(
        name: str,
        alpha_prev_rad: Sequence[float],
        a_prev_mm: Sequence[float],
        d_mm: Sequence[float],
        theta_offset_rad: Sequence[float],
        limits_rad: Optional[Sequence[Sequence[float]]] = None,
        flange_alpha_prev_rad: Optional[float] = None,
        flange_a_prev_mm: Optional[float] = None,
        flange_d_mm: Optional[float] = None,
        flange_theta_rad: Optional[float] = None,
    ) -> "Robot":
        """A robot from a table in Craig's modified DH convention (mm, rad), one value per joint:
        ``A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``, as Franka publishes the Panda's;
        the flange as Craig's last row. Converted exactly, as ``[[craig_joint]]`` rows are."""
    @property
    def name(self) -> str: ...
    @property
    def joints(self) -> int: ...
    @property
    def path(self) -> str: ...
    def to_toml(self) -> str: ...
    def to_file(self, path: _Path) -> None: ...
    def export(
        self,
        format: str,
        *,
        scalar: Optional[str] = None,
        sequence: Optional[int] = None,
        link_names: Optional[Sequence[str]] = None,
        joint_names: Optional[Sequence[str]] = None,
        base_link: Optional[str] = None,
        flange_link: Optional[str] = None,
        tool_link: Optional[str] = None,
        joints_only: bool = False,
        geometry_only: bool = False,
    ) -> bytes:
        """What ``calib export --format FORMAT`` writes: "block", "toml", "json", "urdf",
        "ur-kinematics-yaml"; its other options as typed keyword arguments (an option of another
        format is an OptionConflictError)."""
    def fk(self, joints_rad: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Forward kinematics (geometry, joint maps, compliance) as ``calib fk``: joints in rad,
        shape (joints,) or (n, joints); homogeneous transforms in mm, (4, 4) or (n, 4, 4)."""

@final
class Dataset:
    """Measured poses: joint readings (rad) with the tracker's positions (mm) and orientations."""

    @staticmethod
    def from_file(path: _Path, profile: Optional[_Path] = None, robot: Optional[Robot] = None) -> "Dataset":
        """A tracker data file (CSV) through a data profile (TOML); checked against ``robot`` now
        when given, and against every robot it is used with."""
    @staticmethod
    def from_arrays(
        joints_rad: npt.ArrayLike,
        positions_mm: npt.ArrayLike,
        rotations: Optional[npt.ArrayLike] = None,
        quaternions_wxyz: Optional[npt.ArrayLike] = None,
        weights: Optional[npt.ArrayLike] = None,
        frame: str = "base",
        robot: Optional[Robot] = None,
    ) -> "Dataset":
        """``joints_rad`` (n, joints) rad, ``positions_mm`` (n, 3) mm, orientations as ``rotations``
        (n, 3, 3) or ``quaternions_wxyz`` (n, 4); ``frame`` "base" or "tracker". Any array-like
        of numbers (numpy arrays, pandas frames, nested lists)."""
    def __len__(self) -> int: ...
    @property
    def joints_rad(self) -> npt.NDArray[np.float64]: ...
    @property
    def positions_mm(self) -> npt.NDArray[np.float64]: ...
    @property
    def rotations(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def lines(self) -> list[int]: ...

@final
class CalibrationResult:
    """What a calibration found."""

    def report(self) -> dict[str, Any]:
        """The JSON report as a dict: the keys of ``calib calibrate --report``."""
    def report_json(self) -> str: ...
    def html(self) -> str:
        """The certificate as one self-contained HTML page."""
    @property
    def text(self) -> str: ...
    @property
    def robot(self) -> Robot:
        """The identified robot."""
    @property
    def robot_toml(self) -> str: ...
    @property
    def parameter_names(self) -> list[str]: ...
    @property
    def parameter_values(self) -> npt.NDArray[np.float64]:
        """Identified errors: mm for lengths, rad for angles."""
    @property
    def standard_errors(self) -> npt.NDArray[np.float64]:
        """Their standard errors (NaN where least squares gave none)."""
    @property
    def accepted(self) -> Optional[bool]: ...
    @property
    def parameter_units(self) -> list[str]:
        """The unit of each parameter value and standard error: "mm" or "rad"."""

def calibrate(
    robot: Robot,
    data: Dataset,
    holdout: Optional[Dataset] = None,
    *,
    validate: Optional[float] = None,
    validate_seed: Optional[int] = None,
    method: Optional[str] = None,
    frames: Optional[str] = None,
    identify: Optional[str] = None,
    model: Optional[str] = None,
    harmonics: Optional[int] = None,
    k: Optional[float] = None,
    lm_iterations: Optional[int] = None,
    loss: Optional[str] = None,
    loss_scale_mm: Optional[float] = None,
    auto_mask: bool = False,
    keep_ill_conditioned: bool = False,
    accept_implausible: bool = False,
    accept: Optional[Sequence[str]] = None,
    payload_kg: Optional[float] = None,
    swarm: Optional[int] = None,
    generations: Optional[int] = None,
    c1: Optional[float] = None,
    c2: Optional[float] = None,
    seed: Optional[int] = None,
    init_angle_rad: Optional[float] = None,
    init_length_mm: Optional[float] = None,
    bound_factor: Optional[float] = None,
    stall_generations: Optional[int] = None,
    target: Optional[float] = None,
    halton_start: Optional[int] = None,
    scrambling: Optional[str] = None,
) -> CalibrationResult:
    """Calibrates ``robot`` on ``data``. Each keyword is ``calib calibrate``'s option of the same
    name (underscores for dashes), ``None`` its default; ``holdout`` is a Dataset held out. A
    keyword no option has is a TypeError. Ctrl-C stops it (KeyboardInterrupt) within a swarm
    generation, where Python receives SIGINT (a process started with SIGINT ignored, as a
    non-interactive shell starts background jobs, never sees it)."""

def evaluate_json(
    robot: Robot,
    data: Dataset,
    *,
    fit_frames: Optional[str] = None,
    fit_poses: Optional[int] = None,
    seed: Optional[int] = None,
    stored_registration: bool = False,
) -> str:
    """``calib evaluate --json`` (the package's ``calib.evaluate`` returns the dict)."""

def calibrate_touches_json(
    robot: Robot,
    joints_rad: Any,
    placements: Sequence[str],
    sockets: Sequence[int],
    *,
    ball_mm: tuple[float, float, float],
    train: Optional[Sequence[str]] = None,
    distance: Optional[float] = None,
    distance_sd: float = 0.05,
    distance_between: Optional[tuple[int, int]] = None,
    keep_ill_conditioned: bool = False,
    feature: str = "socket",
    leave_one_out: bool = False,
    tracker_joints_rad: Any = None,
    tracker_xyz_mm: Any = None,
    tracker_sd: float = 0.02,
    datum_planes: Optional[Sequence[tuple[int, tuple[float, float, float], float]]] = None,
    compliance: bool = False,
) -> tuple[Robot, str, str]:
    """``calib sockets`` from arrays: the identified robot, the JSON report (text) and the text
    (the package's ``calib.calibrate_touches`` returns the report as a dict)."""

def registry_add(
    report: Union[str, PathLike[str]],
    *,
    db: Optional[Union[str, PathLike[str]]] = None,
    serial: Optional[str] = None,
    model: Optional[str] = None,
    identified: Optional[Union[str, PathLike[str]]] = None,
    certificate: Optional[Union[str, PathLike[str]]] = None,
    block: Optional[Union[str, PathLike[str]]] = None,
) -> int:
    """``calib registry add``: registers the calibration of ``report``; the record's number."""

def registry_list_json(db: Optional[Union[str, PathLike[str]]] = None, serial: Optional[str] = None) -> str:
    """``calib registry list --json`` as text."""

def registry_show_json(id: int, db: Optional[Union[str, PathLike[str]]] = None) -> str:
    """``calib registry show --json`` as text."""

def registry_compare_json(
    a: int, b: int, db: Optional[Union[str, PathLike[str]]] = None, poses: int = 1000
) -> str:
    """``calib registry compare A B --json`` as text."""

def registry_verify_json(
    serial: str,
    *,
    block: Optional[Union[str, PathLike[str]]] = None,
    robot: Optional[Union[str, PathLike[str]]] = None,
    db: Optional[Union[str, PathLike[str]]] = None,
) -> str:
    """``calib registry verify --json`` as text."""

def check_shift_json(
    serial: str,
    data: Union[str, PathLike[str]],
    *,
    profile: Optional[Union[str, PathLike[str]]] = None,
    record: Optional[int] = None,
    k: float = 3.0,
    limit_mm: Optional[float] = None,
    noise_mm: Optional[float] = None,
    register_tracker: bool = False,
    checked_at: Optional[str] = None,
    db: Optional[Union[str, PathLike[str]]] = None,
) -> str:
    """``calib check-shift --json`` as text."""

def registry_checks_json(serial: str, db: Optional[Union[str, PathLike[str]]] = None) -> str:
    """``calib registry checks --json`` as text."""

def registry_pose_tests_json(
    serial: str, id: Optional[int] = None, db: Optional[Union[str, PathLike[str]]] = None
) -> str:
    """``calib registry pose-tests --json`` as text."""

def registry_fleet_html(
    db: Optional[Union[str, PathLike[str]]] = None, interval_days: int = 365, today: Optional[str] = None
) -> str:
    """``calib registry fleet``: the page as HTML text."""

def iso9283_evaluate_json(
    targets: Union[str, PathLike[str]],
    data: Union[str, PathLike[str]],
    robot: Union[str, PathLike[str]],
    *,
    profile: Optional[Union[str, PathLike[str]]] = None,
) -> str:
    """``calib iso9283 evaluate --json`` as text."""

@final
class Plan:
    """A measurement plan: the poses to measure in order, their roles, the prediction."""

    @property
    def joints_rad(self) -> npt.NDArray[np.float64]: ...
    @property
    def roles(self) -> list[str]: ...
    @property
    def ids(self) -> list[str]: ...
    @property
    def text(self) -> str: ...
    def report(self) -> dict[str, Any]:
        """The plan as ``calib plan --report`` writes it."""
    def report_json(self) -> str: ...
    def __len__(self) -> int: ...

def plan(
    robot: Robot,
    *,
    poses: int,
    measure: str,
    candidates: Optional[_Path] = None,
    profile: Optional[_Path] = None,
    generate: Optional[int] = None,
    box_mm: Optional[Sequence[float]] = None,
    below_base: bool = False,
    core: Optional[int] = None,
    verify: Optional[int] = None,
    min_distance_deg: Optional[float] = None,
    model: Optional[str] = None,
    noise_mm: Optional[float] = None,
    noise_deg: Optional[float] = None,
    noise_from: Optional[_Path] = None,
    k: Optional[float] = None,
    seed: Optional[int] = None,
) -> Plan:
    """``calib plan`` (its options as keyword arguments, ``None`` the same defaults); nothing is written."""

def compensate_csv(
    robot: Robot,
    params: Robot,
    targets: _Path,
    *,
    text: Optional[str] = None,
    targets_frame: Optional[str] = None,
    joint_targets: bool = False,
    max_correction_mm: Optional[float] = None,
    max_correction_deg: Optional[float] = None,
    max_joint_correction_deg: Optional[float] = None,
    near_deg: Optional[Sequence[float]] = None,
    branch: Optional[int] = None,
    allow_extrapolation: bool = False,
    max_arm_angle_deg: Optional[float] = None,
    near_within_deg: Optional[float] = None,
) -> str:
    """The table ``calib compensate`` writes, as CSV text (``calib.compensate`` returns its
    columns), for the targets file ``targets``, or for the targets file's ``text`` (``targets``
    then names it in messages)."""
