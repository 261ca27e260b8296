//! How the host runs the identification fast: the swarm's cost evaluated in vector lanes
//! (AVX-512 where the CPU has it) and the swarm team (particles evaluated on several cores).

pub mod lanes;
pub mod swarm_team;
