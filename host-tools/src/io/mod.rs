//! Files in and out: robot files (TOML, Craig tables), tracker data (CSV through data profiles and
//! their columns), and the outputs every command writes (staged and replaced all together).

pub mod columns;
pub mod input;
pub mod outputs;
pub mod profile;
pub mod robot_file;
pub mod text;
pub mod tracker_data;
