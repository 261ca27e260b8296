//! The library's one error type: what went wrong, typed by where it came from, with its causes
//! kept (`source()`), so that a program can tell a bad robot file from a refused option or a
//! failed write, and a person reads the same messages as on the command line (`calib` prints an
//! error and then its causes, one per line).
//!
//! Every public function of the library returns [`Result`]; `anyhow` is only the command line's
//! (the `calib` binary, `src/bin/calib/`), where any of these errors is printed and turned into
//! exit status 1.
//!
//! ```
//! use host_tools::error::Error;
//! use host_tools::io::robot_file::RobotFile;
//!
//! let error = RobotFile::read(std::path::Path::new("no-such-robot.toml")).unwrap_err();
//! assert!(matches!(error, host_tools::io::robot_file::RobotFileError::Read { .. }));
//! // The same error as the library's type, with its message unchanged.
//! let message = error.to_string();
//! assert_eq!(Error::from(error).to_string(), message);
//! ```

use std::fmt::Display;

/// Every error the host library returns.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An option's value the library refuses: out of its range, not finite, of the wrong count,
    /// or meaningless for these inputs. The message says what to give instead.
    #[error("{message}")]
    InvalidOption {
        /// The option, by its command-line flag (`--poses`, `--near-deg`).
        option: String,
        /// What is wrong and what to give, for people.
        message: String,
    },
    /// An input's content the library refuses: a line of a data, candidates, targets, plan or
    /// socket file, a section of a robot file or report, data that do not come from this robot
    /// as stated. The message names the file (and line) and says how to fix it.
    #[error("{message}")]
    InvalidInput {
        /// The input: a file's path (as given), or what it is ("the data", "the candidates").
        input: String,
        /// What is wrong and how to fix it, for people.
        message: String,
    },
    /// What this robot or model cannot do, or an output cannot carry: a joint count outside a
    /// method's range, gravity compliance on a robot it is not modelled for, joint maps in a
    /// format without them.
    #[error("{message}")]
    Unsupported {
        /// The feature or output refused, such as `gravity compliance` or `UR kinematics file`.
        feature: String,
        /// Why and what to do instead, for people.
        message: String,
    },
    /// Too few measurements, equations or candidates for what was asked.
    #[error("{message}")]
    TooFew {
        /// How many there are (poses, equations or candidates, as the message says).
        have: usize,
        /// How many are needed.
        need: usize,
        /// What to add or ask for instead, for people.
        message: String,
    },
    /// Parameters the data cannot determine, found where no rank is computed (a singular
    /// information matrix or posterior, a parameter that changes no residual).
    #[error("{message}")]
    Undetermined {
        /// The parameters found undetermined (`dd2`), empty when the matrix does not say which.
        parameters: Vec<String>,
        /// What to change, for people.
        message: String,
    },
    /// Identified joint maps or gravity compliance that fail their plausibility bounds; nothing
    /// was written.
    #[error("{message}")]
    ImplausibleModel {
        /// The bound that failed, naming the value.
        problem: String,
        /// The likely causes and what to do, for people.
        message: String,
    },
    /// An output path the library will not write: a directory, an input, another output's path.
    #[error("{message}")]
    Output {
        /// The path as given.
        path: std::path::PathBuf,
        /// Why, and what to give instead, for people.
        message: String,
    },
    /// An outside program the library needs (the headless browser that prints PDFs) is missing
    /// or failed.
    #[error("{message}")]
    ExternalProgram {
        /// The program, such as `chromium`.
        program: String,
        /// What happened and what to do instead, for people.
        message: String,
    },
    /// A computation that could not finish (a matrix lost its definiteness, a value is not
    /// finite); the message says which.
    #[error("{0}")]
    Numerical(String),
    /// Settings or options that contradict each other (such as a robust loss's scale with the
    /// plain l2 loss, or the swarm's settings with least squares alone): the message names them
    /// and says which to drop.
    #[error("{message}")]
    OptionConflict {
        /// The conflicting options, by their command-line flags (`--loss-scale-mm`, `--c1`).
        options: Vec<String>,
        /// What to change, for people.
        message: String,
    },
    /// The data cannot determine every parameter asked for (the identification Jacobian's rank
    /// is below their count), and dropping them was not allowed (`--auto-mask`).
    #[error("{message}")]
    Unidentifiable {
        /// The numerical rank of the identification Jacobian.
        rank: usize,
        /// The number of parameters asked for.
        parameters: usize,
        /// The parameters the data cannot determine (dropped with `--auto-mask`), such as `dd2`.
        undetermined: Vec<String>,
        /// The analysis and what to do, for people.
        message: String,
    },
    /// A calibration whose result fails the plausibility check
    /// ([`crate::calibration::plausibility`]); the result is kept here for inspection, and
    /// nothing was written.
    #[error("{message}")]
    Implausible {
        /// Each problem, naming the value and its bound.
        problems: Vec<String>,
        /// The result that was refused.
        result: Box<crate::calibration::CalibrationResult>,
        /// The problems, the likely causes and what to do, for people.
        message: String,
    },
    /// A statement about held-out poses (an acceptance criterion) with none held out.
    #[error("{0}")]
    NoHeldOut(String),
    /// The calibration was cancelled ([`crate::calibration::Cancel`]).
    #[error("the calibration was cancelled")]
    Cancelled,
    /// A robot file that cannot be read or does not describe a robot.
    #[error(transparent)]
    RobotFile(#[from] crate::io::robot_file::RobotFileError),
    /// A data file that cannot be read (file, line and column named).
    #[error(transparent)]
    Data(#[from] crate::io::tracker_data::DataError),
    /// A data profile that cannot be read.
    #[error(transparent)]
    Profile(#[from] crate::io::profile::ProfileError),
    /// The tracker's registration to the robot failed.
    #[error(transparent)]
    Registration(#[from] crate::measurement::frames::RegistrationError),
    /// The core refused a model or joint readings.
    #[error(transparent)]
    Kinematics(#[from] calib_core::KinematicsError),
    /// The core refused a calibration problem.
    #[error(transparent)]
    Problem(#[from] calib_core::identify::ProblemError),
    /// The core refused a measurement.
    #[error(transparent)]
    Measurement(#[from] calib_core::identify::objective::MeasurementError),
    /// A packed parameter vector of another length than its set.
    #[error(transparent)]
    Shape(#[from] calib_core::model::parameters::ShapeError),
    /// The core's least squares failed.
    #[error(transparent)]
    LeastSquares(#[from] calib_core::identify::lm::LmError),
    /// The core's particle swarm refused its settings.
    #[error(transparent)]
    Swarm(#[from] calib_core::identify::ipso::IpsoError),
    /// The core's controller-side model or block was refused.
    #[error(transparent)]
    Storage(#[from] calib_core::controller::storage::StorageError),
    /// The independent reference was asked for a parameter it does not know.
    #[error(transparent)]
    Reference(#[from] calib_reference::lm::UnknownParameter),
    /// Reading or writing a file failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A JSON document could not be read or written.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A CSV file could not be read or written.
    #[error(transparent)]
    Csv(#[from] csv::Error),
    /// A TOML document could not be read.
    #[error(transparent)]
    TomlRead(#[from] toml::de::Error),
    /// A TOML document could not be written.
    #[error(transparent)]
    TomlWrite(#[from] toml::ser::Error),
    /// Text could not be formatted (writing into a `String` does not fail; a `Display` of ours
    /// could).
    #[error(transparent)]
    Format(#[from] std::fmt::Error),
    /// Bytes meant as text are not UTF-8.
    #[error(transparent)]
    Utf8(#[from] std::str::Utf8Error),
    /// A plot could not be drawn (the plotting crate's message).
    #[error("{0}")]
    Plot(String),
    /// What the library was doing when the cause failed.
    #[error("{context}")]
    Context {
        /// What was being done, for example "robot file ur10.toml".
        context: String,
        /// Why it failed.
        #[source]
        source: Box<Error>,
    },
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// A refusal of the kind its first word names, with a message (`format!` arguments) that says
/// what to change:
///
/// - `refused!(option "--poses"; "...")`: [`Error::InvalidOption`];
/// - `refused!(input path.display(); "...")`: [`Error::InvalidInput`];
/// - `refused!(unsupported "gravity compliance"; "...")`: [`Error::Unsupported`];
/// - `refused!(too_few have, need; "...")`: [`Error::TooFew`];
/// - `refused!(undetermined names; "...")`: [`Error::Undetermined`] (`names`: `Vec<String>`);
/// - `refused!(implausible problem; "...")`: [`Error::ImplausibleModel`];
/// - `refused!(output path; "...")`: [`Error::Output`] (`path`: anything `AsRef<Path>`);
/// - `refused!(program "chromium"; "...")`: [`Error::ExternalProgram`].
#[macro_export]
macro_rules! refused {
    (option $option:expr; $($message:tt)*) => {
        $crate::error::Error::InvalidOption {
            option: $option.to_string(),
            message: format!($($message)*),
        }
    };
    (input $input:expr; $($message:tt)*) => {
        $crate::error::Error::InvalidInput {
            input: $input.to_string(),
            message: format!($($message)*),
        }
    };
    (unsupported $feature:expr; $($message:tt)*) => {
        $crate::error::Error::Unsupported {
            feature: $feature.to_string(),
            message: format!($($message)*),
        }
    };
    (too_few $have:expr, $need:expr; $($message:tt)*) => {
        $crate::error::Error::TooFew {
            have: $have,
            need: $need,
            message: format!($($message)*),
        }
    };
    (undetermined $parameters:expr; $($message:tt)*) => {
        $crate::error::Error::Undetermined {
            parameters: $parameters,
            message: format!($($message)*),
        }
    };
    (implausible $problem:expr; $($message:tt)*) => {
        $crate::error::Error::ImplausibleModel {
            problem: $problem.to_string(),
            message: format!($($message)*),
        }
    };
    (output $path:expr; $($message:tt)*) => {
        $crate::error::Error::Output {
            path: ::std::convert::AsRef::<::std::path::Path>::as_ref(&$path).to_path_buf(),
            message: format!($($message)*),
        }
    };
    (program $program:expr; $($message:tt)*) => {
        $crate::error::Error::ExternalProgram {
            program: $program.to_string(),
            message: format!($($message)*),
        }
    };
}

/// A computation that could not finish: `Error::Numerical(format!(...))`.
#[macro_export]
macro_rules! numerical {
    ($($message:tt)*) => {
        $crate::error::Error::Numerical(format!($($message)*))
    };
}

impl Error {
    /// Options in conflict, named by their flags, with what to change.
    pub fn conflict(options: &[&str], message: impl Display) -> Self {
        Self::OptionConflict {
            options: options.iter().map(ToString::to_string).collect(),
            message: message.to_string(),
        }
    }

    /// A plotting error, by its message.
    pub fn plot(error: impl Display) -> Self {
        Self::Plot(error.to_string())
    }

    /// This error as the cause of `context`.
    pub fn context(self, context: impl Display) -> Self {
        Self::Context {
            context: context.to_string(),
            source: Box::new(self),
        }
    }
}

/// Says what was being done when a result failed, as `anyhow::Context` does, but into the
/// library's [`Error`].
pub trait Context<T> {
    /// The error, if any, as the cause of `context`.
    fn context(self, context: impl Display) -> Result<T>;
    /// The error, if any, as the cause of the context `f` gives (computed only on failure).
    fn with_context<C: Display>(self, f: impl FnOnce() -> C) -> Result<T>;
}

impl<T, E: Into<Error>> Context<T> for std::result::Result<T, E> {
    fn context(self, context: impl Display) -> Result<T> {
        self.map_err(|e| e.into().context(context))
    }

    fn with_context<C: Display>(self, f: impl FnOnce() -> C) -> Result<T> {
        self.map_err(|e| e.into().context(f()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error as _;

    /// The causes are kept in order, and each is printed once: the chain `calib` prints.
    #[test]
    fn context_keeps_the_cause_chain() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let error = Err::<(), _>(io)
            .context("robot file r.toml")
            .context("calibrating")
            .unwrap_err();
        let mut chain = vec![error.to_string()];
        let mut cause = error.source();
        while let Some(c) = cause {
            chain.push(c.to_string());
            cause = c.source();
        }
        assert_eq!(chain, ["calibrating", "robot file r.toml", "no such file"]);
    }
}
