//! `calib._calib`: the host library for Python (PyO3, the stable ABI from Python 3.9). The
//! package `calib` (python/calib/__init__.py) re-exports it; python/calib/_calib.pyi documents
//! it. Robots and data come from files or numpy arrays; a calibration takes the options of
//! `calib calibrate` as keyword arguments, parsed by the same command-line definition, so that
//! defaults, checks and messages are the command's. Computation runs with the GIL released.

use host_tools::calibration::{Calibrated as Calibration, CalibrationConfig};
use host_tools::io::robot_file::RobotFile;
use host_tools::io::tracker_data::{Record, TrackerData};
use host_tools::kinematics::targets::{CompensationRequest, ConfigurationChoice, TargetsFrame};
use host_tools::measurement::dataset::Dataset as HostDataset;
use numpy::PyUntypedArrayMethods;
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

pyo3::create_exception!(
    _calib,
    CalibError,
    PyException,
    "Any error of the calibration toolkit; the message is the command line's."
);
pyo3::create_exception!(
    _calib,
    InputError,
    CalibError,
    "An input the toolkit refuses: a file, an array (shape, NaN, units), an option; the message says how to fix it."
);
pyo3::create_exception!(
    _calib,
    NumericalError,
    CalibError,
    "A computation that cannot stand behind its result (singular, not converged, implausible)."
);

pyo3::create_exception!(
    _calib,
    OptionConflictError,
    InputError,
    "Options that contradict each other; `.options` names them (by the command line's flags)."
);
pyo3::create_exception!(
    _calib,
    UnidentifiableError,
    InputError,
    "The data cannot determine every parameter asked for: `.rank` of `.parameters`, and `.undetermined` (the parameters auto_mask=True would drop)."
);
pyo3::create_exception!(
    _calib,
    NoHeldOutError,
    InputError,
    "A statement about held-out poses (accept=) with none held out: give validate= or a holdout Dataset."
);
pyo3::create_exception!(
    _calib,
    ImplausibleError,
    NumericalError,
    "A result that fails the plausibility check (nothing is returned): `.problems` says why, `.parameters` holds the refused values (mm, rad) by name."
);

pyo3::create_exception!(
    _calib,
    OptionError,
    InputError,
    "An option's value refused (out of range, not finite, the wrong count): `.option` names it (by the command line's flag)."
);
pyo3::create_exception!(
    _calib,
    InvalidInputError,
    InputError,
    "An input's content refused (a file's line, a section, data that do not come from this robot): `.input` names the file or input."
);
pyo3::create_exception!(
    _calib,
    UnsupportedError,
    InputError,
    "What this robot or model cannot do, or an output cannot carry: `.feature` names it."
);
pyo3::create_exception!(
    _calib,
    TooFewError,
    InputError,
    "Too few poses, equations or candidates: `.have` of `.need`."
);
pyo3::create_exception!(
    _calib,
    UndeterminedError,
    InputError,
    "Parameters the data cannot determine, found by a singular matrix: `.undetermined` names them where known (else empty)."
);
pyo3::create_exception!(
    _calib,
    OutputError,
    CalibError,
    "An output path that is not written (a directory, an input, another output's path): `.path`."
);
pyo3::create_exception!(
    _calib,
    ExternalProgramError,
    CalibError,
    "An outside program the toolkit needs (the headless browser that prints PDFs) is missing or failed: `.program`."
);

/// The exception class of the library's typed refusals, with their data as attributes; `None`
/// for the others.
fn typed_error(error: &host_tools::Error, message: &str) -> Option<PyErr> {
    use host_tools::Error as E;
    Python::attach(|py| -> PyResult<Option<PyErr>> {
        let err = match error {
            E::OptionConflict { options, .. } => {
                let err = OptionConflictError::new_err(message.to_string());
                err.value(py).setattr("options", options.clone())?;
                err
            }
            E::Unidentifiable {
                rank,
                parameters,
                undetermined,
                ..
            } => {
                let err = UnidentifiableError::new_err(message.to_string());
                let value = err.value(py);
                value.setattr("rank", *rank)?;
                value.setattr("parameters", *parameters)?;
                value.setattr("undetermined", undetermined.clone())?;
                err
            }
            E::NoHeldOut(_) => NoHeldOutError::new_err(message.to_string()),
            E::InvalidOption { option, .. } => {
                let err = OptionError::new_err(message.to_string());
                err.value(py).setattr("option", option.clone())?;
                err
            }
            E::InvalidInput { input, .. } => {
                let err = InvalidInputError::new_err(message.to_string());
                err.value(py).setattr("input", input.clone())?;
                err
            }
            E::Unsupported { feature, .. } => {
                let err = UnsupportedError::new_err(message.to_string());
                err.value(py).setattr("feature", feature.clone())?;
                err
            }
            E::TooFew { have, need, .. } => {
                let err = TooFewError::new_err(message.to_string());
                let value = err.value(py);
                value.setattr("have", *have)?;
                value.setattr("need", *need)?;
                err
            }
            E::Undetermined { parameters, .. } => {
                let err = UndeterminedError::new_err(message.to_string());
                err.value(py).setattr("undetermined", parameters.clone())?;
                err
            }
            E::ImplausibleModel { problem, .. } => {
                let err = ImplausibleError::new_err(message.to_string());
                let value = err.value(py);
                value.setattr("problems", vec![problem.clone()])?;
                value.setattr("parameters", PyDict::new(py))?;
                err
            }
            E::Output { path, .. } => {
                let err = OutputError::new_err(message.to_string());
                err.value(py).setattr("path", path.display().to_string())?;
                err
            }
            E::ExternalProgram { program, .. } => {
                let err = ExternalProgramError::new_err(message.to_string());
                err.value(py).setattr("program", program.clone())?;
                err
            }
            E::Implausible {
                problems, result, ..
            } => {
                let err = ImplausibleError::new_err(message.to_string());
                let value = err.value(py);
                value.setattr("problems", problems.clone())?;
                let parameters = PyDict::new(py);
                for p in &result.parameters {
                    parameters.set_item(p.parameter.to_string(), p.value)?;
                }
                value.setattr("parameters", parameters)?;
                err
            }
            _ => return Ok(None),
        };
        Ok(Some(err))
    })
    .unwrap_or_else(Some)
}

/// `OptionConflictError` for keyword arguments that contradict each other, named by the
/// command line's flags as the library names them.
fn conflict(options: &[&str], message: &str) -> PyErr {
    py_error(host_tools::Error::conflict(options, message).into())
}

/// The Python exception of a host error: its message and causes as `calib` prints them.
fn py_error(error: anyhow::Error) -> PyErr {
    let mut message = error.to_string();
    let causes: Vec<String> = error.chain().skip(1).map(ToString::to_string).collect();
    if !causes.is_empty() {
        message.push_str("\n\nCaused by:\n");
        for cause in causes {
            message.push_str(&format!("    {cause}\n"));
        }
    }
    use host_tools::Error as E;
    if let Some(err) = (error.chain())
        .find_map(|c| c.downcast_ref::<E>())
        .and_then(|e| typed_error(e, &message))
    {
        return err;
    }
    let numerical = error.chain().any(|c| {
        matches!(
            c.downcast_ref::<E>(),
            Some(
                E::Numerical(_)
                    | E::Kinematics(_)
                    | E::Problem(_)
                    | E::LeastSquares(_)
                    | E::Swarm(_)
            )
        )
    });
    if numerical {
        NumericalError::new_err(message)
    } else if error.chain().any(|c| {
        // A refusal of the library, of an input file's reader or of the options' parser.
        c.downcast_ref::<E>().is_some()
            || c.downcast_ref::<host_tools::io::robot_file::RobotFileError>()
                .is_some()
            || c.downcast_ref::<host_tools::io::tracker_data::DataError>()
                .is_some()
            || c.downcast_ref::<host_tools::io::profile::ProfileError>()
                .is_some()
            || c.downcast_ref::<clap::Error>().is_some()
    }) {
        InputError::new_err(message)
    } else {
        CalibError::new_err(message)
    }
}

/// Runs `work` on a thread of its own while this thread, with the GIL released while it waits,
/// checks for Python signals every 20 ms: on Ctrl-C (or any signal handler's exception) `cancel`
/// asks the work to stop, and once it has, the exception is raised. The result is taken the
/// moment the work sends it (no wait for the next look).
fn interruptible<T: Send + 'static>(
    py: Python<'_>,
    cancel: &host_tools::calibration::Cancel,
    work: impl FnOnce() -> T + Send + 'static,
) -> PyResult<T> {
    use std::sync::mpsc::RecvTimeoutError;
    let (send, receive) = std::sync::mpsc::channel();
    let handle = std::thread::spawn(move || {
        let _ = send.send(work());
    });
    let mut receive = receive;
    loop {
        // The receiver goes to the detached closure and back (it is Send, not Sync).
        let (back, look) = py.detach(move || {
            let look = receive.recv_timeout(std::time::Duration::from_millis(20));
            (receive, look)
        });
        receive = back;
        match look {
            Ok(value) => {
                let _ = py.detach(|| handle.join());
                return Ok(value);
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(CalibError::new_err(
                    "the computation stopped unexpectedly (a panic): please report it",
                ));
            }
            Err(RecvTimeoutError::Timeout) => {}
        }
        if let Err(signal) = py.check_signals() {
            cancel.cancel();
            let _ = py.detach(|| handle.join());
            return Err(signal);
        }
    }
}

/// The array-like `value` (a numpy array, a pandas frame or series, nested lists) as an array
/// of `f64` of dimension `D`: `numpy.asarray(value, dtype=float64)`, so numbers of other types
/// are converted and anything else (text, a mapping, the wrong number of axes) is an
/// `InputError` naming the argument `name`. (numpy's own `PyArrayLike` would read a one-axis
/// argument by iteration, and a frame iterates over its column labels.)
fn numbers<'py, D: numpy::ndarray::Dimension + 'py>(
    name: &str,
    value: &Bound<'py, PyAny>,
) -> PyResult<numpy::PyReadonlyArray<'py, f64, D>> {
    let py = value.py();
    let refused = |why: String| {
        let axes = D::NDIM.map_or("any number of".to_string(), |n| n.to_string());
        InputError::new_err(format!(
            "{name}: not an array of numbers with {axes} axes ({why})"
        ))
    };
    let array = (numpy::get_array_module(py)?)
        .call_method1("asarray", (value, numpy::dtype::<f64>(py)))
        .map_err(|e| refused(e.to_string()))?;
    let array = array
        .cast_into::<numpy::PyArray<f64, D>>()
        .map_err(|_| refused("a different number of axes".to_string()))?;
    Ok(numpy::PyArrayMethods::readonly(&array))
}

/// The JSON `text` as Python objects (`json.loads`).
fn json_loads<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// `Err(InputError(message))`.
fn input<T>(message: String) -> PyResult<T> {
    Err(InputError::new_err(message))
}

/// A robot: its file (TOML) as read, and the path that names it.
#[pyclass(module = "calib", name = "Robot", frozen)]
#[derive(Clone)]
struct Robot {
    file: RobotFile,
    path: PathBuf,
    /// `true` when read from `path` (a calibration from files can then run as the command does).
    on_disk: bool,
}

#[pymethods]
impl Robot {
    /// Reads a robot file (TOML).
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Self> {
        let file = RobotFile::read(&path).map_err(|e| py_error(e.into()))?;
        // Checked whole now (finite values, limits, frames, maps, compliance), not at first use.
        host_tools::kinematics::actual::ActualRobot::from_file(file.clone(), &path)
            .map_err(|e| py_error(e.into()))?;
        Ok(Self {
            file,
            path,
            on_disk: true,
        })
    }

    /// A robot from robot-file text; `name` names it in messages.
    #[staticmethod]
    #[pyo3(signature = (text, name = "<memory>"))]
    fn from_toml(text: &str, name: &str) -> PyResult<Self> {
        let path = PathBuf::from(name);
        let file = RobotFile::parse(text, &path).map_err(|e| py_error(e.into()))?;
        host_tools::kinematics::actual::ActualRobot::from_file(file.clone(), &path)
            .map_err(|e| py_error(e.into()))?;
        Ok(Self {
            file,
            path,
            on_disk: false,
        })
    }

    /// A robot from arrays of its Hayati-modified DH parameters, one value per joint
    /// (docs/ARCHITECTURE.md: `A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`,
    /// `theta_i = q_i + theta_offset_i`): lengths in mm, angles in rad; `limits_rad` (joints, 2);
    /// the base and tool frames as xyz (mm) and roll, pitch, yaw (rad, `R = Rz(yaw) Ry(pitch)
    /// Rx(roll)`). The robot file it makes is checked as a file is. Not for a table in Craig's
    /// modified DH convention (`Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)`, as Franka
    /// publishes the Panda's): the same numbers give another robot; such a table is
    /// `Robot.from_craig`'s.
    #[staticmethod]
    #[pyo3(signature = (name, a_mm, alpha_rad, theta_offset_rad, d_mm, beta_rad = None, limits_rad = None, base_xyz_mm = None, base_rpy_rad = None, tool_xyz_mm = None, tool_rpy_rad = None))]
    #[allow(clippy::too_many_arguments)]
    fn from_dh(
        name: &str,
        a_mm: Vec<f64>,
        alpha_rad: Vec<f64>,
        theta_offset_rad: Vec<f64>,
        d_mm: Vec<f64>,
        beta_rad: Option<Vec<f64>>,
        limits_rad: Option<Vec<[f64; 2]>>,
        base_xyz_mm: Option<[f64; 3]>,
        base_rpy_rad: Option<[f64; 3]>,
        tool_xyz_mm: Option<[f64; 3]>,
        tool_rpy_rad: Option<[f64; 3]>,
    ) -> PyResult<Self> {
        let joints = a_mm.len();
        let beta_rad = beta_rad.unwrap_or_else(|| vec![0.0; joints]);
        let columns = [&alpha_rad, &theta_offset_rad, &d_mm, &beta_rad];
        if columns.iter().any(|c| c.len() != joints)
            || limits_rad.as_ref().is_some_and(|l| l.len() != joints)
        {
            return input(format!(
                "from_dh: every parameter needs {joints} values, one per joint"
            ));
        }
        let named = [
            ("a_mm", &a_mm),
            ("alpha_rad", &alpha_rad),
            ("theta_offset_rad", &theta_offset_rad),
            ("d_mm", &d_mm),
            ("beta_rad", &beta_rad),
        ];
        let frames = [
            ("base_xyz_mm", base_xyz_mm),
            ("base_rpy_rad", base_rpy_rad),
            ("tool_xyz_mm", tool_xyz_mm),
            ("tool_rpy_rad", tool_rpy_rad),
        ];
        let every = (named.iter())
            .flat_map(|(n, v)| {
                v.iter()
                    .enumerate()
                    .map(move |(i, x)| (*n, i.to_string(), *x))
            })
            .chain(frames.iter().flat_map(|(n, v)| {
                (v.iter().flatten().enumerate()).map(move |(i, x)| (*n, i.to_string(), *x))
            }))
            .chain(limit_values(&limits_rad));
        finite("from_dh", every)?;
        let mut text = format!("name = {}\n\n", toml::Value::from(name));
        for j in 0..joints {
            text += &format!(
                "[[joint]]\na_mm = {:?}\nalpha_deg = {:?}\ntheta_offset_deg = {:?}\nd_mm = {:?}\nbeta_deg = {:?}\n",
                a_mm[j],
                alpha_rad[j].to_degrees(),
                theta_offset_rad[j].to_degrees(),
                d_mm[j],
                beta_rad[j].to_degrees()
            );
            text += &limits_line(&limits_rad, j);
            text += "\n";
        }
        for (section, xyz, rpy) in [
            ("base", base_xyz_mm, base_rpy_rad),
            ("tool", tool_xyz_mm, tool_rpy_rad),
        ] {
            if xyz.is_some() || rpy.is_some() {
                let [x, y, z] = xyz.unwrap_or_default();
                let [r, p, w] = rpy.unwrap_or_default().map(f64::to_degrees);
                text += &format!(
                    "[{section}]\nxyz_mm = [{x:?}, {y:?}, {z:?}]\nrpy_deg = [{r:?}, {p:?}, {w:?}]\n\n"
                );
            }
        }
        Self::from_toml(&text, &format!("<{name}>"))
    }

    /// A robot from arrays of a table in Craig's modified DH convention, one value per joint:
    /// `A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)`, `theta_i = q_i +
    /// theta_offset_i` (as Franka publishes the Panda's); lengths in mm, angles in rad;
    /// `limits_rad` (joints, 2); the flange after the last joint as Craig's last row
    /// (`flange_alpha_prev_rad`, `flange_a_prev_mm`, `flange_d_mm`, `flange_theta_rad`; none: the
    /// flange is the last joint's frame). Converted exactly into the toolkit's model, as a robot
    /// file's `[[craig_joint]]` rows are (docs/ARCHITECTURE.md).
    #[staticmethod]
    #[pyo3(signature = (name, alpha_prev_rad, a_prev_mm, d_mm, theta_offset_rad, limits_rad = None, flange_alpha_prev_rad = None, flange_a_prev_mm = None, flange_d_mm = None, flange_theta_rad = None))]
    #[allow(clippy::too_many_arguments)]
    fn from_craig(
        name: &str,
        alpha_prev_rad: Vec<f64>,
        a_prev_mm: Vec<f64>,
        d_mm: Vec<f64>,
        theta_offset_rad: Vec<f64>,
        limits_rad: Option<Vec<[f64; 2]>>,
        flange_alpha_prev_rad: Option<f64>,
        flange_a_prev_mm: Option<f64>,
        flange_d_mm: Option<f64>,
        flange_theta_rad: Option<f64>,
    ) -> PyResult<Self> {
        let joints = alpha_prev_rad.len();
        if [&a_prev_mm, &d_mm, &theta_offset_rad]
            .iter()
            .any(|c| c.len() != joints)
            || limits_rad.as_ref().is_some_and(|l| l.len() != joints)
        {
            return input(format!(
                "from_craig: every parameter needs {joints} values, one per joint"
            ));
        }
        let named = [
            ("alpha_prev_rad", &alpha_prev_rad),
            ("a_prev_mm", &a_prev_mm),
            ("d_mm", &d_mm),
            ("theta_offset_rad", &theta_offset_rad),
        ];
        let flange = [
            ("flange_alpha_prev_rad", flange_alpha_prev_rad),
            ("flange_a_prev_mm", flange_a_prev_mm),
            ("flange_d_mm", flange_d_mm),
            ("flange_theta_rad", flange_theta_rad),
        ];
        let every = (named.iter())
            .flat_map(|(n, v)| (v.iter().enumerate()).map(move |(i, x)| (*n, i.to_string(), *x)))
            .chain(
                flange
                    .iter()
                    .filter_map(|(n, v)| v.map(|x| (*n, "0".to_string(), x))),
            )
            .chain(limit_values(&limits_rad));
        finite("from_craig", every)?;
        let mut text = format!("name = {}\n\n", toml::Value::from(name));
        for j in 0..joints {
            text += &format!(
                "[[craig_joint]]\nalpha_prev_deg = {:?}\na_prev_mm = {:?}\nd_mm = {:?}\ntheta_offset_deg = {:?}\n",
                alpha_prev_rad[j].to_degrees(),
                a_prev_mm[j],
                d_mm[j],
                theta_offset_rad[j].to_degrees(),
            );
            text += &limits_line(&limits_rad, j);
            text += "\n";
        }
        if flange.iter().any(|(_, v)| v.is_some()) {
            text += &format!(
                "[craig_flange]\nalpha_prev_deg = {:?}\na_prev_mm = {:?}\nd_mm = {:?}\ntheta_deg = {:?}\n",
                flange_alpha_prev_rad.unwrap_or(0.0).to_degrees(),
                flange_a_prev_mm.unwrap_or(0.0),
                flange_d_mm.unwrap_or(0.0),
                flange_theta_rad.unwrap_or(0.0).to_degrees(),
            );
        }
        Self::from_toml(&text, &format!("<{name}>"))
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.file.name.clone()
    }

    /// The number of joints.
    #[getter]
    fn joints(&self) -> usize {
        self.file.joint.len()
    }

    /// The file it came from (or the name given to `from_toml`).
    #[getter]
    fn path(&self) -> String {
        self.path.display().to_string()
    }

    /// The robot file as TOML text.
    fn to_toml(&self) -> PyResult<String> {
        toml::to_string(&self.file).map_err(|e| py_error(e.into()))
    }

    /// Writes the robot file (TOML) to `path`, replacing it atomically.
    fn to_file(&self, path: PathBuf) -> PyResult<()> {
        let text = self.to_toml()?;
        let mut outputs = host_tools::io::outputs::Outputs::new(&[]);
        outputs
            .stage("path", &path, text.as_bytes())
            .and_then(|()| outputs.commit().map(|_| ()))
            .map_err(|e| py_error(e.into()))
    }

    /// Forward kinematics of the whole model (geometry, joint maps, gravity compliance), as
    /// `calib fk`: joint readings in rad, shape (joints,) or (n, joints), to homogeneous
    /// transforms in mm, shape (4, 4) or (n, 4, 4).
    fn fk<'py>(
        &self,
        py: Python<'py>,
        joints_rad: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let array = numbers::<numpy::IxDyn>("joints_rad", joints_rad)?;
        let array = array.as_array();
        let (count, columns, single) = match *array.shape() {
            [columns] => (1, columns, true),
            [count, columns] => (count, columns, false),
            ref shape => {
                return input(format!(
                    "joints_rad: shape {shape:?}: expected (joints,) or (n, joints), in rad"
                ));
            }
        };
        let kinematics = host_tools::kinematics::fk::FileKinematics::new(&self.file, &self.path)
            .map_err(|e| py_error(e.into()))?;
        let joints = kinematics.joints();
        if columns != joints {
            return input(format!(
                "joints_rad: shape {:?}: the robot {} has {joints} joints (one column per joint, in rad)",
                array.shape(),
                self.file.name
            ));
        }
        // A copy, row after row (whatever the input's memory order: a pandas frame's is often
        // by column), that no Python thread can change while the GIL is released; it and the
        // result allocated fallibly (a broadcast array of a billion rows is a MemoryError, not
        // the end of the interpreter).
        let mut all = allocated(count.checked_mul(columns), "joints_rad")?;
        all.extend(array.iter().copied());
        let cells = allocated(count.checked_mul(16), "the transforms")?;
        let out = py.detach(|| -> Result<Array3<f64>, host_tools::Error> {
            let mut cells = cells;
            cells.resize(count * 16, 0.0);
            let mut out = Array3::<f64>::from_shape_vec((count, 4, 4), cells)
                .map_err(|e| host_tools::refused!(input "joints_rad"; "joints_rad: {e}"))?;
            for (i, q) in all.chunks_exact(columns).enumerate() {
                let m = kinematics
                    .pose(q, &|| format!("joints_rad row {i}"))?
                    .to_homogeneous();
                for r in 0..4 {
                    for c in 0..4 {
                        out[(i, r, c)] = m[(r, c)];
                    }
                }
            }
            Ok(out)
        });
        let out = out.map_err(|e| py_error(e.into()))?;
        if single {
            let m: Array2<f64> = out.index_axis(numpy::ndarray::Axis(0), 0).to_owned();
            Ok(m.into_pyarray(py).into_any())
        } else {
            Ok(out.into_pyarray(py).into_any())
        }
    }

    /// The robot as `calib export --format FORMAT` writes it, as bytes: "block" (the controller's
    /// parameter block), "toml", "json", "urdf", "ur-kinematics-yaml"; the options of `calib
    /// export` as typed keyword arguments (`scalar="f64"`, `geometry_only=True`, ...), the
    /// library's export request (an option of another format is an OptionConflictError).
    #[pyo3(signature = (
        format, *, scalar = None, sequence = None, link_names = None, joint_names = None,
        base_link = None, flange_link = None, tool_link = None, joints_only = false,
        geometry_only = false
    ))]
    #[allow(clippy::too_many_arguments)]
    fn export<'py>(
        &self,
        py: Python<'py>,
        format: &str,
        scalar: Option<&str>,
        sequence: Option<u32>,
        link_names: Option<Vec<String>>,
        joint_names: Option<Vec<String>>,
        base_link: Option<String>,
        flange_link: Option<String>,
        tool_link: Option<String>,
        joints_only: bool,
        geometry_only: bool,
    ) -> PyResult<Bound<'py, pyo3::types::PyBytes>> {
        let Some(format) = choice("format", Some(format))? else {
            return input("format: a format is needed".into());
        };
        let request = host_tools::formats::export::ExportRequest {
            format,
            scalar: choice("scalar", scalar)?,
            sequence,
            link_names,
            joint_names,
            base_link,
            flange_link,
            tool_link,
            joints_only,
            geometry_only,
        };
        let bytes = (request.export(&self.file, &self.path)).map_err(|e| py_error(e.into()))?;
        Ok(pyo3::types::PyBytes::new(py, &bytes))
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(name={:?}, joints={}, path={:?})",
            self.file.name,
            self.file.joint.len(),
            self.path.display().to_string()
        )
    }
}

/// Where a dataset came from: files (a calibration can then run as the command does) or memory.
#[derive(Clone)]
enum Source {
    Files {
        data: PathBuf,
        profile: Option<PathBuf>,
    },
    Memory,
}

/// Measured poses: joint readings with the tracker's positions (and orientations), read from a
/// file or given as arrays. They are checked against a robot (joint count, limits, the profile's
/// orientation convention) when one is given, and again against every robot they are used with.
#[pyclass(module = "calib", name = "Dataset", frozen)]
#[derive(Clone)]
struct Dataset {
    data: TrackerData,
    /// The data profile's orientation convention, checked against each robot (files only).
    euler: Option<host_tools::io::profile::EulerConvention>,
    source: Source,
    /// The poses checked against the robot given when they were read.
    bound: Option<(Robot, HostDataset)>,
}

impl Dataset {
    /// `data` read from `source`, checked against `robot` when given.
    fn new(
        data: TrackerData,
        euler: Option<host_tools::io::profile::EulerConvention>,
        source: Source,
        robot: Option<&Robot>,
    ) -> anyhow::Result<Self> {
        let mut dataset = Self {
            data,
            euler,
            source,
            bound: None,
        };
        if let Some(robot) = robot {
            dataset.bound = Some((robot.clone(), dataset.against(robot)?));
        }
        Ok(dataset)
    }

    /// The poses checked against `robot` (joint count, limits, the profile's orientation
    /// convention) and converted for the core: those checked when the data were read when that
    /// was the robot, else checked now (a model identified on them, one built in memory).
    fn against(&self, robot: &Robot) -> anyhow::Result<HostDataset> {
        if let Some((r, bound)) = &self.bound
            && r.path == robot.path
            && r.file == robot.file
        {
            return Ok(bound.clone());
        }
        let dataset = HostDataset::from_data(robot.file.clone(), &robot.path, self.data.clone())?;
        if let Some(euler) = &self.euler {
            // The check `calib` makes of every data file it reads (Euler conventions).
            host_tools::measurement::orientation_check::check(&dataset, euler)?;
        }
        Ok(dataset)
    }
}

#[pymethods]
impl Dataset {
    /// Reads a tracker data file (CSV), through a data profile (TOML) when given; checked
    /// against `robot` now when given, else against the robot it is used with.
    #[staticmethod]
    #[pyo3(signature = (path, profile = None, robot = None))]
    fn from_file(
        py: Python<'_>,
        path: PathBuf,
        profile: Option<PathBuf>,
        robot: Option<&Robot>,
    ) -> PyResult<Self> {
        py.detach(|| -> anyhow::Result<Self> {
            let p = host_tools::io::profile::DataProfile::load(profile.as_deref())?;
            let data = TrackerData::read_with(&path, &p)?;
            let source = Source::Files {
                data: path.clone(),
                profile: profile.clone(),
            };
            Self::new(data, Some(p.euler), source, robot)
        })
        .map_err(py_error)
    }

    /// Poses from arrays: `joints_rad` (n, joints) in rad, `positions_mm` (n, 3) in mm, optional
    /// orientations as `rotations` (n, 3, 3) rotation matrices or `quaternions_wxyz` (n, 4), optional
    /// `weights` (n,); `frame` is "base" (the robot's base frame) or "tracker" (a tracker's
    /// frame, registered by the calibration). Each array may be a numpy array, a pandas frame
    /// or series (columns in that order) or nested lists. Checked against `robot` now when
    /// given, else against the robot it is used with.
    #[staticmethod]
    #[pyo3(signature = (joints_rad, positions_mm, rotations = None, quaternions_wxyz = None, weights = None, frame = "base", robot = None))]
    #[allow(clippy::too_many_arguments)]
    fn from_arrays(
        joints_rad: &Bound<'_, PyAny>,
        positions_mm: &Bound<'_, PyAny>,
        rotations: Option<&Bound<'_, PyAny>>,
        quaternions_wxyz: Option<&Bound<'_, PyAny>>,
        weights: Option<&Bound<'_, PyAny>>,
        frame: &str,
        robot: Option<&Robot>,
    ) -> PyResult<Self> {
        let joints_rad = numbers::<numpy::Ix2>("joints_rad", joints_rad)?;
        let positions_mm = numbers::<numpy::Ix2>("positions_mm", positions_mm)?;
        let rotations = rotations
            .map(|r| numbers::<numpy::Ix3>("rotations", r))
            .transpose()?;
        let quaternions_wxyz =
            (quaternions_wxyz.map(|r| numbers::<numpy::Ix2>("quaternions_wxyz", r))).transpose()?;
        let weights = weights
            .map(|r| numbers::<numpy::Ix1>("weights", r))
            .transpose()?;
        let base_frame = match frame {
            "base" => true,
            "tracker" => false,
            other => {
                return input(format!(
                    "frame = {other:?}: expected \"base\" or \"tracker\""
                ));
            }
        };
        let q = joints_rad.as_array();
        let p = positions_mm.as_array();
        let n = q.nrows();
        if n > MAX_POSES {
            return input(format!(
                "joints_rad: {n} rows: at most {MAX_POSES} poses (a data file's size limit holds fewer)"
            ));
        }
        if p.shape() != [n, 3] {
            return input(format!(
                "positions_mm: shape {:?}, expected ({n}, 3): one x, y, z row in mm per row of joints_rad",
                p.shape()
            ));
        }
        if let Some(robot) = robot
            && q.ncols() != robot.file.joint.len()
        {
            return input(format!(
                "joints_rad: shape {:?}: the robot {} has {} joints (one column per joint, in rad)",
                q.shape(),
                robot.file.name,
                robot.file.joint.len()
            ));
        }
        let rotations = orientations(n, rotations.as_ref(), quaternions_wxyz.as_ref())?;
        let weights = match weights {
            Some(w) if w.len() != n => {
                return input(format!("weights: {} values for {n} poses", w.len()));
            }
            Some(w) => w.as_array().to_vec(),
            None => vec![1.0; n],
        };
        let mut records = Vec::with_capacity(n);
        for i in 0..n {
            let row: Vec<f64> = q.row(i).to_vec();
            let position = [p[(i, 0)], p[(i, 1)], p[(i, 2)]];
            if let Some(v) = row.iter().chain(&position).find(|v| !v.is_finite()) {
                return input(format!(
                    "row {i}: {v} is not a finite number (joints_rad, positions_mm)"
                ));
            }
            records.push(Record {
                line: i as u64 + 1,
                id: (i + 1).to_string(),
                q: row,
                position,
                rotation: rotations.as_ref().map(|r| r[i]),
                weight: weights[i],
                role: None,
                configuration: None,
                time_s: None,
                temperature_c: None,
            });
        }
        let data =
            TrackerData::from_records(records, base_frame).map_err(|e| py_error(e.into()))?;
        Self::new(data, None, Source::Memory, robot).map_err(py_error)
    }

    /// The number of poses.
    fn __len__(&self) -> usize {
        self.data.records.len()
    }

    /// The joint readings, (n, joints), rad.
    #[getter]
    fn joints_rad<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let r = &self.data.records;
        let j = self.data.joints;
        Array2::from_shape_fn((r.len(), j), |(i, k)| r[i].q[k]).into_pyarray(py)
    }

    /// The measured positions, (n, 3), mm.
    #[getter]
    fn positions_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let r = &self.data.records;
        Array2::from_shape_fn((r.len(), 3), |(i, k)| r[i].position[k]).into_pyarray(py)
    }

    /// The measured orientations as rotation matrices, (n, 3, 3); `None` for position-only data.
    #[getter]
    fn rotations<'py>(&self, py: Python<'py>) -> Option<Bound<'py, numpy::PyArray3<f64>>> {
        let r = &self.data.records;
        if r.iter().any(|r| r.rotation.is_none()) {
            return None;
        }
        let m: Vec<nalgebra::Matrix3<f64>> = r.iter().filter_map(|r| r.rotation).collect();
        Some(Array3::from_shape_fn((m.len(), 3, 3), |(i, a, b)| m[i][(a, b)]).into_pyarray(py))
    }

    /// The data file's line of each pose (1-based rows for arrays).
    #[getter]
    fn lines(&self) -> Vec<u64> {
        self.data.records.iter().map(|r| r.line).collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "Dataset(poses={}, robot={:?}, source={:?})",
            self.data.records.len(),
            self.bound.as_ref().map(|(r, _)| r.file.name.clone()),
            match &self.source {
                Source::Files { data, .. } => data.display().to_string(),
                Source::Memory => "arrays".to_string(),
            }
        )
    }
}

/// The orientations of `n` poses from rotation matrices or quaternions (w, x, y, z), checked.
fn orientations(
    n: usize,
    rotations: Option<&PyReadonlyArray3<'_, f64>>,
    quaternions: Option<&PyReadonlyArray2<'_, f64>>,
) -> PyResult<Option<Vec<nalgebra::Matrix3<f64>>>> {
    match (rotations, quaternions) {
        (Some(_), Some(_)) => input("give rotations or quaternions_wxyz, not both".into()),
        (None, None) => Ok(None),
        (Some(r), None) => {
            let r = r.as_array();
            if r.shape() != [n, 3, 3] {
                return input(format!(
                    "rotations: shape {:?}, expected ({n}, 3, 3)",
                    r.shape()
                ));
            }
            let mut out = Vec::with_capacity(n);
            for i in 0..n {
                let m = nalgebra::Matrix3::from_fn(|a, b| r[(i, a, b)]);
                let orthonormal = (m.transpose() * m - nalgebra::Matrix3::identity()).norm() < 1e-6
                    && (m.determinant() - 1.0).abs() < 1e-6;
                if !orthonormal {
                    return input(format!(
                        "rotations[{i}] is not a rotation matrix (orthonormal, determinant 1, to 1e-6)"
                    ));
                }
                out.push(m);
            }
            Ok(Some(out))
        }
        (None, Some(q)) => {
            let q = q.as_array();
            if q.shape() != [n, 4] {
                return input(format!(
                    "quaternions_wxyz: shape {:?}, expected ({n}, 4)",
                    q.shape()
                ));
            }
            let mut out = Vec::with_capacity(n);
            for i in 0..n {
                let v = nalgebra::Quaternion::new(q[(i, 0)], q[(i, 1)], q[(i, 2)], q[(i, 3)]);
                if !v.norm().is_finite() || (v.norm() - 1.0).abs() >= 1e-6 {
                    return input(format!(
                        "quaternions_wxyz[{i}] has norm {}, not a unit quaternion (to 1e-6)",
                        v.norm()
                    ));
                }
                out.push(
                    *nalgebra::UnitQuaternion::from_quaternion(v)
                        .to_rotation_matrix()
                        .matrix(),
                );
            }
            Ok(Some(out))
        }
    }
}

/// A calibration's result.
#[pyclass(module = "calib", name = "CalibrationResult", frozen)]
struct CalibrationResult {
    calibration: Calibration,
}

#[pymethods]
impl CalibrationResult {
    /// The JSON report (the keys of `calib calibrate --report`) as text.
    fn report_json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.calibration.report()).map_err(|e| py_error(e.into()))
    }

    /// The JSON report as a dict: the keys of `calib calibrate --report`.
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.report_json()?)
    }

    /// The certificate as one self-contained HTML page (`calib calibrate --html`).
    fn html(&self) -> PyResult<String> {
        let report = self.calibration.report();
        host_tools::report::html::render(&report, &host_tools::report::html::Rendering::now())
            .map_err(|e| py_error(e.into()))
    }

    /// The text `calib calibrate` prints.
    #[getter]
    fn text(&self) -> String {
        self.calibration.text()
    }

    /// The identified robot (its file as `calib calibrate --out` writes it).
    #[getter]
    fn robot(&self) -> PyResult<Robot> {
        Robot::from_toml(&self.calibration.robot_toml(), "<identified robot>")
    }

    /// The identified robot file's text, as `calib calibrate --out` writes it.
    #[getter]
    fn robot_toml(&self) -> String {
        self.calibration.robot_toml()
    }

    /// The identified parameters' names, in canonical order.
    #[getter]
    fn parameter_names(&self) -> Vec<String> {
        self.calibration.result.names()
    }

    /// The identified parameters' values (mm for lengths, rad for angles), in the order of
    /// `parameter_names`.
    #[getter]
    fn parameter_values<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        let v: Vec<f64> = self
            .calibration
            .result
            .parameters
            .iter()
            .map(|p| p.value)
            .collect();
        v.into_pyarray(py)
    }

    /// Their standard errors (same units; NaN where least squares gave none).
    #[getter]
    fn standard_errors<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        let v: Vec<f64> = (self.calibration.result.parameters.iter())
            .map(|p| p.std_error.unwrap_or(f64::NAN))
            .collect();
        v.into_pyarray(py)
    }

    /// With acceptance criteria (`accept=`): whether all are met; `None` without.
    #[getter]
    fn accepted(&self) -> Option<bool> {
        self.calibration.result.acceptance.as_ref().map(|a| a.pass)
    }

    /// The unit of each of `parameter_values` and `standard_errors`: "mm" or "rad".
    #[getter]
    fn parameter_units(&self) -> Vec<&'static str> {
        (self.calibration.result.parameters.iter())
            .map(|p| host_tools::analysis::truth::unit_of(p.parameter))
            .collect()
    }

    fn __repr__(&self) -> String {
        let r = &self.calibration.result;
        let held_out = r.validation.as_ref().map_or_else(
            || "no held-out poses".to_string(),
            |v| format!("held-out mean {:.4} mm", v.after.position_mm.mean),
        );
        format!(
            "CalibrationResult(robot={:?}, parameters={}, {held_out}, accepted={})",
            r.robot,
            r.parameters.len(),
            r.acceptance
                .as_ref()
                .map_or("None", |a| if a.pass { "True" } else { "False" })
        )
    }
}

/// The value `value` of the keyword argument `name` as one of the choices of `T` (the command
/// line's words: `"ipso+lm"`, `"base+tool"`, ...), or an InputError listing them.
fn choice<T: clap::ValueEnum>(name: &str, value: Option<&str>) -> PyResult<Option<T>> {
    let Some(value) = value else {
        return Ok(None);
    };
    T::from_str(value, false).map(Some).map_err(|_| {
        let choices: Vec<String> = (T::value_variants().iter())
            .filter_map(|v| v.to_possible_value())
            .map(|v| format!("'{}'", v.get_name()))
            .collect();
        InputError::new_err(format!(
            "{name}: invalid value '{value}': choose {}",
            choices.join(", ")
        ))
    })
}

/// Calibrates `robot` on `data`: a [`Session`] of the library. Every keyword argument is the
/// command line's option of the same name (underscores for dashes), `None` its default (that of
/// [`CalibrationConfig::default`]); `holdout` is a Dataset held out for validation. Data from
/// files are recorded with their SHA-256 in the identified robot file, as the command records
/// them, and a measured plan's verification rows are its hold-out.
#[pyfunction]
#[pyo3(signature = (
    robot, data, holdout = None, *, validate = None, validate_seed = None, method = None,
    frames = None, identify = None, model = None, harmonics = None, k = None, lm_iterations = None,
    loss = None,
    loss_scale_mm = None, auto_mask = false, keep_ill_conditioned = false,
    accept_implausible = false, accept = None, payload_kg = None, swarm = None,
    generations = None, c1 = None, c2 = None, seed = None, init_angle_rad = None,
    init_length_mm = None, bound_factor = None, stall_generations = None, target = None,
    halton_start = None, scrambling = None
))]
#[allow(clippy::too_many_arguments)]
fn calibrate(
    py: Python<'_>,
    robot: &Robot,
    data: &Dataset,
    holdout: Option<&Dataset>,
    validate: Option<f64>,
    validate_seed: Option<u64>,
    method: Option<&str>,
    frames: Option<&str>,
    identify: Option<&str>,
    model: Option<&str>,
    harmonics: Option<usize>,
    k: Option<f64>,
    lm_iterations: Option<u32>,
    loss: Option<&str>,
    loss_scale_mm: Option<f64>,
    auto_mask: bool,
    keep_ill_conditioned: bool,
    accept_implausible: bool,
    accept: Option<Vec<String>>,
    payload_kg: Option<f64>,
    swarm: Option<usize>,
    generations: Option<u32>,
    c1: Option<f64>,
    c2: Option<f64>,
    seed: Option<u64>,
    init_angle_rad: Option<f64>,
    init_length_mm: Option<f64>,
    bound_factor: Option<f64>,
    stall_generations: Option<u32>,
    target: Option<f64>,
    halton_start: Option<u64>,
    scrambling: Option<String>,
) -> PyResult<CalibrationResult> {
    use host_tools::calibration::{HoldOut, Provenance, Session};
    let swarm = host_tools::calibration::SwarmOptions {
        swarm,
        generations,
        c1,
        c2,
        seed,
        init_angle_rad,
        init_length_mm,
        bound_factor,
        stall_generations,
        target,
        halton_start,
        scrambling: choice("scrambling", scrambling.as_deref())?,
    };
    let d = CalibrationConfig::default();
    let acceptance = (accept.unwrap_or_default().iter())
        .map(|c| {
            c.parse()
                .map_err(|e: String| InputError::new_err(format!("accept: {e}")))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let cancel = host_tools::calibration::Cancel::default();
    let config = CalibrationConfig {
        method: choice("method", method)?.unwrap_or(d.method),
        frames: choice("frames", frames)?,
        identify: choice("identify", identify)?.unwrap_or(d.identify),
        model: choice("model", model)?.unwrap_or(d.model),
        harmonics,
        k: k.unwrap_or(d.k),
        swarm: swarm.config(),
        lm_iterations: lm_iterations.unwrap_or(d.lm_iterations),
        loss: choice("loss", loss)?.unwrap_or(d.loss),
        loss_scale_mm,
        auto_mask,
        keep_ill_conditioned,
        accept_implausible,
        acceptance,
        payload_kg,
        progress: false,
        cancel: cancel.clone(),
    };
    if validate_seed.is_some() && validate.is_none() {
        return Err(py_error(
            host_tools::Error::conflict(
                &["--validate-seed", "--validate"],
                "validate_seed= seeds the random hold-out of validate=: give validate=FRACTION, or drop validate_seed=",
            )
            .into(),
        ));
    }
    let all = data.against(robot).map_err(py_error)?;
    let held = (holdout.map(|h| h.against(robot)).transpose()).map_err(py_error)?;
    let hold_out = match (held, validate) {
        (Some(_), Some(_)) => {
            return Err(py_error(
                host_tools::Error::conflict(
                    &["--holdout", "--validate"],
                    "give either validate= or a holdout Dataset, not both",
                )
                .into(),
            ));
        }
        (Some(held), None) => HoldOut::poses(held),
        (None, Some(fraction)) => HoldOut::Fraction {
            fraction,
            seed: validate_seed.unwrap_or(0),
        },
        (None, None) => HoldOut::of_data(&all),
    };
    let inputs = file_inputs(robot, data, holdout).map_err(|e| py_error(e.into()))?;
    let session = Session {
        hold_out,
        provenance: Provenance {
            command_line: Vec::new(),
            inputs,
        },
        ..Session::new(all, config)
    };
    let calibration =
        interruptible(py, &cancel, move || session.run())?.map_err(|e| py_error(e.into()))?;
    Ok(CalibrationResult { calibration })
}

/// The input files of a calibration of `data` (validated on `holdout`) on `robot` with their
/// SHA-256, as `calib calibrate` records them: when the robot, the data and the hold-out all
/// come from files; else none (poses from memory have no file to trace back to).
fn file_inputs(
    robot: &Robot,
    data: &Dataset,
    holdout: Option<&Dataset>,
) -> host_tools::Result<Vec<host_tools::io::provenance::InputFile>> {
    let Source::Files {
        data: path,
        profile,
    } = &data.source
    else {
        return Ok(Vec::new());
    };
    if !robot.on_disk {
        return Ok(Vec::new());
    }
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![
        ("--robot", robot.path.as_path()),
        ("--data", path.as_path()),
    ];
    if let Some(p) = profile {
        inputs.push(("--profile", p.as_path()));
    }
    match holdout.map(|h| &h.source) {
        Some(Source::Files { data: h, .. }) => inputs.push(("--holdout", h.as_path())),
        Some(Source::Memory) => return Ok(Vec::new()),
        None => {}
    }
    host_tools::io::provenance::InputFile::all(&inputs)
}

/// Table 3 statistics of `robot` (any model, nominal or identified) on `data`, as `calib evaluate
/// --json` gives them (JSON text; the package's `evaluate` returns the dict): the library's
/// evaluation, its options as typed keyword arguments (`fit_frames="base"`, `fit_poses=30`,
/// `seed=1`, `stored_registration=True`); the data, from a file or arrays, are checked against
/// `robot`.
#[pyfunction]
#[pyo3(signature = (robot, data, *, fit_frames = None, fit_poses = None, seed = None, stored_registration = false))]
fn evaluate_json(
    py: Python<'_>,
    robot: &Robot,
    data: &Dataset,
    fit_frames: Option<&str>,
    fit_poses: Option<usize>,
    seed: Option<u64>,
    stored_registration: bool,
) -> PyResult<String> {
    use host_tools::analysis::evaluation::{FitPoses, Registration};
    let frames = choice("fit_frames", fit_frames)?;
    if seed.is_some() && fit_poses.is_none() {
        return Err(py_error(
            host_tools::Error::conflict(
                &["--seed", "--fit-poses"],
                "seed= chooses the fit_poses= poses, and none are chosen: give fit_poses=N, or drop seed=",
            )
            .into(),
        ));
    }
    if stored_registration && frames.is_some() {
        return Err(py_error(
            host_tools::Error::conflict(
                &["--stored-registration", "--fit-frames"],
                "stored_registration=True uses the model's own registration, and fit_frames= fits the frames: drop one of the two",
            )
            .into(),
        ));
    }
    let registration = if stored_registration {
        Registration::Stored
    } else {
        Registration::Fit(frames)
    };
    let fit_poses = fit_poses.map(|count| FitPoses {
        count,
        seed: seed.unwrap_or(0),
    });
    let dataset = data.against(robot).map_err(py_error)?;
    let evaluation = py
        .detach(|| {
            host_tools::analysis::evaluation::evaluate_model(&dataset, registration, fit_poses)
        })
        .map_err(|e| py_error(e.into()))?;
    serde_json::to_string(&evaluation).map_err(|e| py_error(e.into()))
}

/// Calibrates `robot` from a ball touched in sockets (`calib sockets`): `joints_rad` (n, joints)
/// the configurations, `placements` (n) the placement of each touch, `sockets` (n) its socket
/// (0, 1, ...); `ball_mm` the ball's centre in the robot file's tool frame (its flange without a `[tool]`); `train` the placements fitted
/// (default all); `distance` (mm) the known distance between sockets `distance_between` of every
/// placement (default sockets 0 and 1), with standard uncertainty `distance_sd` (mm); `feature`
/// `"plane"` makes the rows contacts with planes (`sockets` then numbers the planes);
/// `leave_one_out` also judges each placement by a calibration of all the others;
/// `tracker_joints_rad` (m, joints) and `tracker_xyz_mm` (m, 3) positions of the same ball
/// measured by a tracker (its frame, mm; at least three), fitted with the touches at the
/// tracker's standard uncertainty `tracker_sd` (mm per coordinate); `datum_planes` planes known in
/// the base frame, `(plane, (nx, ny, nz), offset_mm)` each (`calib sockets --datum-plane`);
/// `compliance` the joints' torsion under gravity (`calib sockets --compliance`). Returns the identified robot, the
/// JSON report (text; the package's `calibrate_touches` gives the dict) and the text `calib
/// sockets` prints. The library's `TouchSession`, nothing written.
#[pyfunction]
#[pyo3(signature = (
    robot, joints_rad, placements, sockets, *, ball_mm, train = None, distance = None,
    distance_sd = 0.05, distance_between = None, keep_ill_conditioned = false,
    feature = "socket", leave_one_out = false, tracker_joints_rad = None, tracker_xyz_mm = None,
    tracker_sd = 0.02, datum_planes = None, compliance = false
))]
#[allow(clippy::too_many_arguments)]
fn calibrate_touches_json(
    py: Python<'_>,
    robot: &Robot,
    joints_rad: &Bound<'_, PyAny>,
    placements: Vec<String>,
    sockets: Vec<usize>,
    ball_mm: [f64; 3],
    train: Option<Vec<String>>,
    distance: Option<f64>,
    distance_sd: f64,
    distance_between: Option<(u16, u16)>,
    keep_ill_conditioned: bool,
    feature: &str,
    leave_one_out: bool,
    tracker_joints_rad: Option<&Bound<'_, PyAny>>,
    tracker_xyz_mm: Option<&Bound<'_, PyAny>>,
    tracker_sd: f64,
    datum_planes: Option<Vec<(u16, [f64; 3], f64)>>,
    compliance: bool,
) -> PyResult<(Robot, String, String)> {
    let tracker = tracker_points(robot, tracker_joints_rad, tracker_xyz_mm)?;
    if tracker.is_some() && leave_one_out {
        return input(
            "leave_one_out with tracker positions: leave one placement out judges touches alone; drop one of them".to_string(),
        );
    }
    let (a, b) = distance_between.unwrap_or((0, 1));
    let feature = match feature {
        "socket" => host_tools::io::sockets::Feature::Socket,
        "plane" => host_tools::io::sockets::Feature::Plane,
        other => {
            return input(format!(
                "feature {other:?}: \"socket\" (the rows touch sockets) or \"plane\" (contacts with planes)"
            ));
        }
    };
    use host_tools::calibration::touches::{Gauge, TouchSession};
    use host_tools::io::sockets::{Reading, group_touches};
    let q = numbers::<numpy::Ix2>("joints_rad", joints_rad)?;
    let q = q.as_array();
    let (n, joints) = (q.nrows(), robot.file.joint.len());
    if q.ncols() != joints {
        return input(format!(
            "joints_rad: {} columns, the robot has {joints} joints: one row of joint readings (rad) per touch",
            q.ncols()
        ));
    }
    if placements.len() != n || sockets.len() != n {
        return input(format!(
            "placements ({}) and sockets ({}) need one entry per row of joints_rad ({n})",
            placements.len(),
            sockets.len()
        ));
    }
    if n > MAX_POSES || sockets.iter().any(|s| *s >= 1000) {
        return input(format!(
            "at most {MAX_POSES} touches and socket numbers below 1000"
        ));
    }
    let mut touches = Vec::with_capacity(n);
    for (i, (name, socket)) in placements.into_iter().zip(sockets).enumerate() {
        let row: Vec<f64> = q.row(i).to_vec();
        if let Some(j) = row.iter().position(|v| !v.is_finite()) {
            return input(format!(
                "joints_rad[{i}, {j}] is {}: every reading must be a finite number (rad)",
                row[j]
            ));
        }
        let reading = Reading {
            line: i as u64 + 1,
            q_rad: row,
        };
        touches.push((name, socket, reading));
    }
    let path = PathBuf::from("<memory>");
    let placements = group_touches(touches, &path, feature).map_err(|e| py_error(e.into()))?;
    let session = TouchSession {
        robot: robot.file.clone(),
        robot_path: robot.path.clone(),
        ball_mm,
        placements,
        train: train.unwrap_or_default(),
        gauge: distance.map(|mm| Gauge {
            sockets: [a, b],
            mm,
            sd_mm: distance_sd,
        }),
        datums: datums(datum_planes.unwrap_or_default())?,
        config: host_tools::calibration::CalibrationConfig {
            keep_ill_conditioned,
            ..Default::default()
        },
        compliance,
    };
    let (calibrated, tracker, left_out) = py
        .detach(|| {
            let (calibrated, tracker) = match tracker {
                Some(points) => {
                    let mixed = host_tools::calibration::mixed::MixedSession {
                        touches: session.clone(),
                        tracker: points,
                        tracker_sd_mm: tracker_sd,
                    }
                    .run()?;
                    (mixed.calibrated, Some(mixed.tracker))
                }
                None => (session.run()?, None),
            };
            let left_out = match leave_one_out {
                true => session.leave_one_out()?,
                false => Vec::new(),
            };
            Ok::<_, host_tools::Error>((calibrated, tracker, left_out))
        })
        .map_err(|e| py_error(e.into()))?;
    let mut text = host_tools::report::touches::touches_text(&calibrated);
    if let Some(tracker) = &tracker {
        text.push_str(&host_tools::report::touches::tracker_text(tracker));
    }
    if leave_one_out {
        text.push_str(&host_tools::report::touches::leave_one_out_text(&left_out));
    }
    let report = host_tools::calibration::touches::TouchReport {
        leave_one_out: left_out,
        tracker,
        ..calibrated.report(&session)
    };
    let report = serde_json::to_string(&report).map_err(|e| py_error(e.into()))?;
    let identified = Robot {
        file: calibrated.file,
        path: PathBuf::from("<identified from touches>"),
        on_disk: false,
    };
    Ok((identified, report, text))
}

/// The datum planes of `calibrate_touches_json`: (plane, normal, offset in mm) each, the normal
/// normalised as `calib sockets --datum-plane` does. Refused: a zero or non-finite normal, an
/// offset not finite.
fn datums(
    planes: Vec<(u16, [f64; 3], f64)>,
) -> PyResult<Vec<host_tools::calibration::touches::DatumPlane>> {
    planes
        .into_iter()
        .map(|(plane, [x, y, z], offset_mm)| {
            let length = (x * x + y * y + z * z).sqrt();
            if !(length.is_finite() && length > 0.0 && offset_mm.is_finite()) {
                return input(format!(
                    "datum_planes: plane {plane}: the normal must be a finite non-zero vector and the offset a finite number of mm"
                ));
            }
            Ok(host_tools::calibration::touches::DatumPlane {
                plane,
                normal: [x / length, y / length, z / length],
                offset_mm,
            })
        })
        .collect()
}

/// The tracker positions of `calibrate_touches_json` (both arrays or neither): one row of joint
/// readings (rad) and one position (mm) each, finite, as many of each.
fn tracker_points(
    robot: &Robot,
    joints_rad: Option<&Bound<'_, PyAny>>,
    xyz_mm: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<Vec<host_tools::io::sockets::TrackerPoint>>> {
    let (q, xyz) = match (joints_rad, xyz_mm) {
        (None, None) => return Ok(None),
        (Some(q), Some(xyz)) => (
            numbers::<numpy::Ix2>("tracker_joints_rad", q)?,
            numbers::<numpy::Ix2>("tracker_xyz_mm", xyz)?,
        ),
        _ => {
            return input(
                "tracker_joints_rad and tracker_xyz_mm: give both (one row each per tracker position) or neither".to_string(),
            );
        }
    };
    let (q, xyz) = (q.as_array(), xyz.as_array());
    let joints = robot.file.joint.len();
    if q.ncols() != joints || xyz.ncols() != 3 || q.nrows() != xyz.nrows() || q.nrows() > MAX_POSES
    {
        return input(format!(
            "tracker_joints_rad ({} x {}) and tracker_xyz_mm ({} x {}): one row per position, {joints} joint readings (rad) and x, y, z (mm), at most {MAX_POSES}",
            q.nrows(),
            q.ncols(),
            xyz.nrows(),
            xyz.ncols()
        ));
    }
    let mut points = Vec::with_capacity(q.nrows());
    for (row, position) in q.rows().into_iter().zip(xyz.rows()) {
        if row.iter().chain(position.iter()).any(|v| !v.is_finite()) {
            return input(format!(
                "tracker position {}: every reading and coordinate must be a finite number",
                points.len()
            ));
        }
        points.push(host_tools::io::sockets::TrackerPoint {
            q_rad: row.to_vec(),
            position_mm: [position[0], position[1], position[2]],
        });
    }
    Ok(Some(points))
}

/// A measurement plan (`calib plan`): the poses to measure in order, their roles, the prediction.
#[pyclass(module = "calib", name = "Plan", frozen)]
struct Plan {
    plan: host_tools::planning::Plan,
}

#[pymethods]
impl Plan {
    /// The poses' joints in measurement order, (n, joints), rad.
    #[getter]
    fn joints_rad<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let p = &self.plan.poses;
        let j = p.first().map_or(0, |p| p.q.len());
        Array2::from_shape_fn((p.len(), j), |(i, k)| p[i].q[k]).into_pyarray(py)
    }

    /// Each pose's role: "core", "fill" or "verify".
    #[getter]
    fn roles(&self) -> PyResult<Vec<String>> {
        (self.plan.poses.iter())
            .map(|p| {
                serde_json::to_value(p.role)
                    .map(|v| v.as_str().unwrap_or_default().to_owned())
                    .map_err(|e| py_error(e.into()))
            })
            .collect()
    }

    /// Each pose's id.
    #[getter]
    fn ids(&self) -> Vec<String> {
        self.plan.poses.iter().map(|p| p.id.clone()).collect()
    }

    /// The text `calib plan` prints.
    #[getter]
    fn text(&self) -> String {
        self.plan.text()
    }

    fn __repr__(&self) -> String {
        let count = |role| self.plan.of_role(role).count();
        use host_tools::io::tracker_data::Role;
        format!(
            "Plan(poses={}: core {}, fill {}, verify {}; from {} candidates)",
            self.plan.poses.len(),
            count(Role::Core),
            count(Role::Fill),
            count(Role::Verify),
            self.plan.candidates
        )
    }

    /// The plan as `calib plan --report` writes it (JSON text; `report()` gives the dict).
    fn report_json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.plan).map_err(|e| py_error(e.into()))
    }

    /// The plan as `calib plan --report` writes it, as a dict.
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.report_json()?)
    }

    fn __len__(&self) -> usize {
        self.plan.poses.len()
    }
}

/// Plans the poses to measure for `robot` (`calib plan`): from the candidate configurations of
/// the file `candidates` (through `profile`), or with `generate=N` candidates within the joint
/// limits; every other keyword argument is `calib plan`'s option of the same name (underscores
/// for dashes), `None` its default: the library's [`PlanRequest`], no command-line words.
/// Nothing is written.
#[pyfunction]
#[pyo3(signature = (
    robot, *, poses, measure, candidates = None, profile = None, generate = None, box_mm = None,
    below_base = false, core = None, verify = None, min_distance_deg = None, model = None,
    noise_mm = None, noise_deg = None, noise_from = None, k = None, seed = None
))]
#[allow(clippy::too_many_arguments)]
fn plan(
    py: Python<'_>,
    robot: &Robot,
    poses: usize,
    measure: &str,
    candidates: Option<PathBuf>,
    profile: Option<PathBuf>,
    generate: Option<usize>,
    box_mm: Option<[f64; 6]>,
    below_base: bool,
    core: Option<usize>,
    verify: Option<usize>,
    min_distance_deg: Option<f64>,
    model: Option<&str>,
    noise_mm: Option<f64>,
    noise_deg: Option<f64>,
    noise_from: Option<PathBuf>,
    k: Option<f64>,
    seed: Option<u64>,
) -> PyResult<Plan> {
    use host_tools::planning::{Candidates, Noise, PlanRequest};
    let candidates = match (candidates, generate) {
        (Some(path), None) => Candidates::File { path, profile },
        (None, Some(count)) if profile.is_none() => Candidates::Generate {
            count,
            box_mm,
            below_base,
        },
        (None, Some(_)) => {
            return Err(conflict(
                &["--profile", "--generate"],
                "profile reads a candidates file, and generate reads none: drop profile",
            ));
        }
        (Some(_), Some(_)) => {
            return Err(conflict(
                &["--candidates", "--generate"],
                "give the candidates one way: candidates=FILE or generate=N",
            ));
        }
        (None, None) => {
            return Err(InputError::new_err(
                "give the candidates: candidates=FILE or generate=N",
            ));
        }
    };
    if matches!(candidates, Candidates::File { .. }) && (box_mm.is_some() || below_base) {
        return Err(conflict(
            &["--box-mm", "--below-base", "--candidates"],
            "box_mm and below_base select among generated candidates (generate=N); candidates are taken as the file gives them",
        ));
    }
    let noise = match (noise_mm, noise_from) {
        (Some(mm), None) => Noise::Given { mm, deg: noise_deg },
        (None, Some(path)) if noise_deg.is_none() => {
            let report =
                host_tools::calibration::Report::read(&path).map_err(|e| py_error(e.into()))?;
            Noise::Residuals(report.residuals(&path).map_err(|e| py_error(e.into()))?)
        }
        (None, None) => {
            return Err(InputError::new_err(
                "give the noise level: noise_mm or noise_from",
            ));
        }
        _ => {
            return Err(conflict(
                &["--noise-mm", "--noise-deg", "--noise-from"],
                "give the noise one way: noise_mm (and noise_deg), or noise_from",
            ));
        }
    };
    let measure =
        choice("measure", Some(measure))?.unwrap_or(host_tools::planning::Measure::Position);
    let defaults = PlanRequest::new(candidates, poses, measure, noise);
    let request = PlanRequest {
        core,
        verify: verify.unwrap_or(defaults.verify),
        min_distance_deg: min_distance_deg.unwrap_or(defaults.min_distance_deg),
        model: choice("model", model)?.unwrap_or(defaults.model),
        k,
        seed: seed.unwrap_or(defaults.seed),
        ..defaults
    };
    let (file, path) = (robot.file.clone(), PathBuf::from(robot.path()));
    let planned = py
        .detach(|| request.plan(&file, &path))
        .map_err(|e| py_error(e.into()))?;
    Ok(Plan { plan: planned })
}

/// The table `calib compensate` writes (CSV text; the package's `compensate` returns its
/// columns): the joints that put the identified robot `params` on each target of the file
/// `targets` (or, with `text`, of that text of a targets file, which the package makes from
/// arrays; `targets` then names it in messages), for a controller planning with the nominal
/// `robot`; every other keyword argument is `calib compensate`'s option of the same name
/// (underscores for dashes), `None` its default: the library's [`CompensationRequest`], no
/// command-line words. Either robot may be read from a file or built in memory
/// (`CalibrationResult.robot`). Nothing is written.
#[pyfunction]
#[pyo3(signature = (
    robot, params, targets, *, text = None, targets_frame = None, joint_targets = false,
    max_correction_mm = None, max_correction_deg = None, max_joint_correction_deg = None,
    near_deg = None, branch = None, allow_extrapolation = false, max_arm_angle_deg = None,
    near_within_deg = None
))]
#[allow(clippy::too_many_arguments)]
fn compensate_csv(
    py: Python<'_>,
    robot: &Robot,
    params: &Robot,
    targets: PathBuf,
    text: Option<String>,
    targets_frame: Option<&str>,
    joint_targets: bool,
    max_correction_mm: Option<f64>,
    max_correction_deg: Option<f64>,
    max_joint_correction_deg: Option<f64>,
    near_deg: Option<Vec<f64>>,
    branch: Option<usize>,
    allow_extrapolation: bool,
    max_arm_angle_deg: Option<f64>,
    near_within_deg: Option<f64>,
) -> PyResult<String> {
    let request = CompensationRequest {
        targets_text: text,
        frame: choice("targets_frame", targets_frame)?.unwrap_or(TargetsFrame::Base),
        joint_targets,
        configuration: configuration_choice(near_deg, branch)?,
        allow_extrapolation,
        max_arm_angle_deg,
        near_within_deg,
        ..CompensationRequest::new(targets)
    };
    let limits = (
        max_correction_mm,
        max_correction_deg,
        max_joint_correction_deg,
    );
    compensated_csv(py, (robot, params), with_limits(request, limits))
}

/// The configuration of targets without joints: a posture (deg) or a branch, not both.
fn configuration_choice(
    near_deg: Option<Vec<f64>>,
    branch: Option<usize>,
) -> PyResult<Option<ConfigurationChoice>> {
    match (near_deg, branch) {
        (Some(_), Some(_)) => Err(conflict(
            &["--near-deg", "--branch"],
            "near_deg and branch both name the arm configuration: give one",
        )),
        (Some(posture), None) => Ok(Some(ConfigurationChoice::NearDeg(posture))),
        (None, Some(branch)) => Ok(Some(ConfigurationChoice::Branch(branch))),
        (None, None) => Ok(None),
    }
}

/// `request` with the largest corrections given (mm, deg, deg), the others at their defaults.
fn with_limits(
    request: CompensationRequest,
    (mm, deg, joint_deg): (Option<f64>, Option<f64>, Option<f64>),
) -> CompensationRequest {
    CompensationRequest {
        max_correction_mm: mm.unwrap_or(request.max_correction_mm),
        max_correction_deg: deg.unwrap_or(request.max_correction_deg),
        max_joint_correction_deg: joint_deg.unwrap_or(request.max_joint_correction_deg),
        ..request
    }
}

/// The compensation table of `request` for the nominal `robot` and the identified `params`.
fn compensated_csv(
    py: Python<'_>,
    (robot, params): (&Robot, &Robot),
    request: CompensationRequest,
) -> PyResult<String> {
    if request.joint_targets && (request.configuration.is_some()) {
        return Err(conflict(
            &["--joint-targets", "--near-deg", "--branch"],
            "joint_targets: each target's joints name its configuration; drop near_deg and branch",
        ));
    }
    let nominal = (robot.file.clone(), PathBuf::from(robot.path()));
    let identified = (params.file.clone(), PathBuf::from(params.path()));
    let (outcomes, joints) = py
        .detach(|| {
            request.outcomes(
                (nominal.0, nominal.1.as_path()),
                (identified.0, identified.1.as_path()),
            )
        })
        .map_err(|e| py_error(e.into()))?;
    let csv = host_tools::kinematics::compensate::to_csv(&outcomes, joints)
        .map_err(|e| py_error(e.into()))?;
    String::from_utf8(csv).map_err(|e| CalibError::new_err(e.to_string()))
}

/// The values of a constructor's `limits_rad` (joints, 2) with their indices, for [`finite`].
fn limit_values(
    limits_rad: &Option<Vec<[f64; 2]>>,
) -> impl Iterator<Item = (&'static str, String, f64)> + '_ {
    (limits_rad.iter().flatten().enumerate())
        .flat_map(|(j, l)| [0, 1].map(|k| ("limits_rad", format!("{j}][{k}"), l[k])))
}

/// Joint `j`'s `limits_deg` line of a robot file from `limits_rad`, or nothing without limits.
fn limits_line(limits_rad: &Option<Vec<[f64; 2]>>, j: usize) -> String {
    limits_rad.as_ref().map_or_else(String::new, |l| {
        format!(
            "limits_deg = [{:?}, {:?}]\n",
            l[j][0].to_degrees(),
            l[j][1].to_degrees()
        )
    })
}

/// InputError naming the first value of `values` (argument, index, value) that is not a finite
/// number, for the constructor `function`.
fn finite<'a>(
    function: &str,
    values: impl IntoIterator<Item = (&'a str, String, f64)>,
) -> PyResult<()> {
    for (argument, at, value) in values {
        if !value.is_finite() {
            return input(format!(
                "{function}: {argument}[{at}] = {value} is not a finite number"
            ));
        }
    }
    Ok(())
}

/// `calib registry add`: registers the calibration of the JSON report `report` in the registry
/// `db` (default `calib.db`; created readable and writable by you only), with the identified robot file, the
/// certificate and the controller block beside it (hashed); `serial` when the report states none.
/// Returns the record's number.
#[pyfunction]
#[pyo3(signature = (report, *, db = None, serial = None, model = None, identified = None, certificate = None, block = None))]
#[allow(clippy::too_many_arguments)]
fn registry_add(
    py: Python<'_>,
    report: PathBuf,
    db: Option<PathBuf>,
    serial: Option<String>,
    model: Option<String>,
    identified: Option<PathBuf>,
    certificate: Option<PathBuf>,
    block: Option<PathBuf>,
) -> PyResult<i64> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry, record::NewRecord, record::RecordFiles};
    py.detach(|| -> host_tools::Result<i64> {
        let record = NewRecord::from_files(&RecordFiles {
            report: Some(&report),
            identified: identified.as_deref(),
            certificate: certificate.as_deref(),
            block: block.as_deref(),
            serial: serial.as_deref(),
            model: model.as_deref(),
        })?;
        Registry::open(&db, Access::Write)?.add(&record)
    })
    .map_err(|e| py_error(e.into()))
}

/// `calib registry list --json`: the registered calibrations of `db` (of robot `serial` only,
/// when given) as JSON text (the package's `registry_list` returns the dicts).
#[pyfunction]
#[pyo3(signature = (db = None, serial = None))]
fn registry_list_json(
    py: Python<'_>,
    db: Option<PathBuf>,
    serial: Option<String>,
) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> anyhow::Result<String> {
        let list = Registry::open(&db, Access::Read)?.list(serial.as_deref())?;
        Ok(serde_json::to_string(&list)?)
    })
    .map_err(py_error)
}

/// `calib registry show --json`: the record `id` of `db` whole, as JSON text (its report parsed;
/// the package's `registry_show` returns the dict).
#[pyfunction]
#[pyo3(signature = (id, db = None))]
fn registry_show_json(py: Python<'_>, id: i64, db: Option<PathBuf>) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> host_tools::Result<String> {
        let record = Registry::open(&db, Access::Read)?.show(id)?;
        host_tools::registry::export::json(std::slice::from_ref(&record))
    })
    .map_err(|e| py_error(e.into()))
}

/// `calib registry compare A B --json`: calibration `b` against calibration `a` as JSON text
/// (the package's `registry_compare` returns the dict). `poses` defaults to
/// [`host_tools::registry::compare::DEFAULT_POSES`], written out for Python's signature.
#[pyfunction]
#[pyo3(signature = (a, b, db = None, poses = 1000))]
fn registry_compare_json(
    py: Python<'_>,
    a: i64,
    b: i64,
    db: Option<PathBuf>,
    poses: usize,
) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> anyhow::Result<String> {
        let registry = Registry::open(&db, Access::Read)?;
        let (a, b) = (registry.show(a)?, registry.show(b)?);
        let comparison = host_tools::registry::compare::compare(&a, &b, poses)?;
        Ok(serde_json::to_string(&comparison)?)
    })
    .map_err(py_error)
}

/// `calib registry verify --json`: a controller's parameter block (`block`) or a robot file
/// (`robot`) against robot `serial`'s calibrations, as JSON text.
#[pyfunction]
#[pyo3(signature = (serial, *, block = None, robot = None, db = None))]
fn registry_verify_json(
    py: Python<'_>,
    serial: String,
    block: Option<PathBuf>,
    robot: Option<PathBuf>,
    db: Option<PathBuf>,
) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::verify::{Given, verify};
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> anyhow::Result<String> {
        let given = match (block, robot) {
            (Some(block), None) => Given::Block(block),
            (None, Some(robot)) => Given::Robot(robot),
            _ => anyhow::bail!("give block= or robot=, one of the two"),
        };
        let records = Registry::open(&db, Access::Read)?.robot(&serial)?;
        Ok(serde_json::to_string(&verify(&serial, &records, &given)?)?)
    })
    .map_err(py_error)
}

/// `calib check-shift --json`: checks robot `serial` with the poses in `data`, records the
/// check and states the drift rate, as JSON text. `k` defaults to
/// [`host_tools::registry::shift::DEFAULT_K`], written out for Python's signature.
#[pyfunction]
#[pyo3(signature = (serial, data, *, profile = None, record = None, k = 3.0, limit_mm = None, noise_mm = None, register_tracker = false, checked_at = None, db = None))]
#[allow(clippy::too_many_arguments)]
fn check_shift_json(
    py: Python<'_>,
    serial: String,
    data: PathBuf,
    profile: Option<PathBuf>,
    record: Option<i64>,
    k: f64,
    limit_mm: Option<f64>,
    noise_mm: Option<f64>,
    register_tracker: bool,
    checked_at: Option<String>,
    db: Option<PathBuf>,
) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::shift::{ShiftSettings, check_and_record};
    py.detach(|| -> anyhow::Result<String> {
        let profile = host_tools::io::profile::DataProfile::load(profile.as_deref())?;
        let settings = ShiftSettings {
            k,
            limit_mm,
            noise_mm,
            register_tracker,
        };
        let when = (record, checked_at.as_deref());
        let recorded = check_and_record(&db, &serial, &data, &profile, when, settings)?;
        Ok(serde_json::to_string(&recorded)?)
    })
    .map_err(py_error)
}

/// `calib iso9283 evaluate --json`: the ISO 9283 characteristics of the measured run `data`
/// against the commanded poses `targets`, in the measurement setup of the identified robot file
/// `robot`, as JSON text.
#[pyfunction]
#[pyo3(signature = (targets, data, robot, *, profile = None))]
fn iso9283_evaluate_json(
    py: Python<'_>,
    targets: PathBuf,
    data: PathBuf,
    robot: PathBuf,
    profile: Option<PathBuf>,
) -> PyResult<String> {
    py.detach(|| -> anyhow::Result<String> {
        let profile = host_tools::io::profile::DataProfile::load(profile.as_deref())?;
        let test = host_tools::pose_test::PoseTest::evaluate(&targets, &data, &robot, &profile)?;
        Ok(serde_json::to_string(&test)?)
    })
    .map_err(py_error)
}

/// `calib registry checks --json`: robot `serial`'s shift checks, oldest first, and its drift
/// rate, as JSON text (the package's `registry_checks` returns the dict).
#[pyfunction]
#[pyo3(signature = (serial, db = None))]
fn registry_checks_json(py: Python<'_>, serial: String, db: Option<PathBuf>) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> anyhow::Result<String> {
        let checks = Registry::open(&db, Access::Read)?.checks(&serial)?;
        let rate = host_tools::registry::shift::drift_rate(&checks);
        Ok(serde_json::to_string(
            &serde_json::json!({"checks": checks, "drift_rate": rate}),
        )?)
    })
    .map_err(py_error)
}

/// `calib registry pose-tests --json`: robot `serial`'s ISO 9283 pose tests, oldest first, as
/// JSON text; with `id`, that test whole (the package's `registry_pose_tests` returns the dicts).
#[pyfunction]
#[pyo3(signature = (serial, id = None, db = None))]
fn registry_pose_tests_json(
    py: Python<'_>,
    serial: String,
    id: Option<i64>,
    db: Option<PathBuf>,
) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> anyhow::Result<String> {
        let registry = Registry::open(&db, Access::Read)?;
        let Some(id) = id else {
            return Ok(serde_json::to_string(&registry.pose_tests(&serial)?)?);
        };
        Ok(serde_json::to_string(
            &registry.robot_pose_test(&serial, id)?,
        )?)
    })
    .map_err(py_error)
}

/// `calib registry fleet`: the fleet page of `db` as HTML text, due `interval_days` after each
/// robot's last calibration, judged on `today` (`YYYY-MM-DD`, default today).
#[pyfunction]
#[pyo3(signature = (db = None, interval_days = 365, today = None))]
fn registry_fleet_html(
    py: Python<'_>,
    db: Option<PathBuf>,
    interval_days: u32,
    today: Option<String>,
) -> PyResult<String> {
    let db = db.unwrap_or_else(|| PathBuf::from(host_tools::registry::DEFAULT_PATH));
    use host_tools::registry::{Access, Registry};
    py.detach(|| -> host_tools::Result<String> {
        let registry = Registry::open(&db, Access::Read)?;
        let source = db.display().to_string();
        let (page, _) =
            host_tools::registry::fleet::page(&registry, &source, interval_days, today.as_deref())?;
        Ok(page)
    })
    .map_err(|e| py_error(e.into()))
}

/// The module.
#[pymodule]
fn _calib(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Robot>()?;
    m.add_class::<Dataset>()?;
    m.add_class::<CalibrationResult>()?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate_json, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(compensate_csv, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate_touches_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_add, m)?)?;
    m.add_function(wrap_pyfunction!(registry_list_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_show_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_compare_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_verify_json, m)?)?;
    m.add_function(wrap_pyfunction!(check_shift_json, m)?)?;
    m.add_function(wrap_pyfunction!(iso9283_evaluate_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_checks_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_pose_tests_json, m)?)?;
    m.add_function(wrap_pyfunction!(registry_fleet_html, m)?)?;
    m.add_class::<Plan>()?;
    m.add("CalibError", m.py().get_type::<CalibError>())?;
    m.add("InputError", m.py().get_type::<InputError>())?;
    m.add("NumericalError", m.py().get_type::<NumericalError>())?;
    m.add(
        "OptionConflictError",
        m.py().get_type::<OptionConflictError>(),
    )?;
    m.add(
        "UnidentifiableError",
        m.py().get_type::<UnidentifiableError>(),
    )?;
    m.add("NoHeldOutError", m.py().get_type::<NoHeldOutError>())?;
    m.add("ImplausibleError", m.py().get_type::<ImplausibleError>())?;
    m.add("OptionError", m.py().get_type::<OptionError>())?;
    m.add("InvalidInputError", m.py().get_type::<InvalidInputError>())?;
    m.add("UnsupportedError", m.py().get_type::<UnsupportedError>())?;
    m.add("TooFewError", m.py().get_type::<TooFewError>())?;
    m.add("UndeterminedError", m.py().get_type::<UndeterminedError>())?;
    m.add("OutputError", m.py().get_type::<OutputError>())?;
    m.add(
        "ExternalProgramError",
        m.py().get_type::<ExternalProgramError>(),
    )?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

/// The most poses a dataset made from arrays may hold (a calibration's data file within its
/// 1 GiB limit holds fewer): more is refused before anything is copied.
const MAX_POSES: usize = 10_000_000;

/// An empty vector with room for `len` values (`None`: the count overflowed), or MemoryError
/// naming `what` when that much memory cannot be had.
fn allocated(len: Option<usize>, what: &str) -> PyResult<Vec<f64>> {
    let mut values = Vec::new();
    len.and_then(|len| values.try_reserve_exact(len).ok().map(|()| len))
        .ok_or_else(|| {
            pyo3::exceptions::PyMemoryError::new_err(format!(
                "{what}: {} values of 8 bytes cannot be allocated",
                len.map_or_else(|| "more than 2^64".to_string(), |l| l.to_string())
            ))
        })?;
    Ok(values)
}
