//! Files in and out: robot files (TOML, Craig tables), tracker data (CSV through data profiles and
//! their columns), the outputs every command writes (staged and replaced all together), and the
//! provenance of a calibration (its input files and their SHA-256), and the touches of sockets
//! (a ball held in unknown points, joint readings only).

pub mod columns;
pub mod dates;
pub mod input;
pub mod outputs;
pub mod profile;
pub mod provenance;
pub mod robot_file;
pub mod sockets;
pub mod text;
pub mod tracker_data;
