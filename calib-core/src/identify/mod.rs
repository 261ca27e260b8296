//! Identification of the parameter errors from measurements: the calibration [`Problem`]
//! (robot, identified set, measurements, `k`), the paper's objective (eq. 7) and its swarm
//! (Halton start, eq. 8-10), Levenberg-Marquardt least squares, identifiability, and the
//! paper's Table 3 statistics.
//!
//! - [`objective`]: measurements and the objective of eq. (7);
//! - [`halton`]: the Halton sequence of eq. (8)-(9);
//! - [`ipso`]: the improved particle swarm (Halton start, constriction factor, eq. 10);
//! - [`residuals`]: what least squares minimises, by kind of measurement (measured poses, common
//!   points);
//! - [`common_point`]: a ball held in unknown sockets, joint readings only (no instrument);
//! - [`lm`]: least squares with streamed Givens QR, robust losses, standard errors;
//! - [`identifiability`]: rank, condition, observability and the undetermined parameters;
//! - [`statistics`]: the paper's Table 3 statistics, accumulated without storage.

pub mod common_point;
pub mod halton;
pub mod identifiability;
pub mod ipso;
pub mod known_plane;
pub mod lm;
pub mod objective;
mod problem;
pub mod residuals;
pub mod statistics;

pub use problem::{Problem, ProblemError};
