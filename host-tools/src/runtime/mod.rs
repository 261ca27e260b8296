//! How the host runs the identification fast: the swarm team (particles evaluated in SIMD lanes
//! across worker threads) and the helper threads it and the cross-validation start.

pub(crate) mod helper_threads;
pub mod swarm_team;
