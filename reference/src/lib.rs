//! An independent float64 reference that checks the core: forward kinematics and pose error
//! written plainly from the elementary transforms ([`kinematics`]), and a least-squares fit with
//! the `levenberg-marquardt` crate on them ([`lm`]). It takes plain numbers (a [`RefRobot`] in mm
//! and rad, [`lm::Observation`]s); host-tools converts its files into them.
//!
//! A crate of its own so that Cargo keeps it from calib-core: agreement between the two would
//! prove nothing if the reference used the core. The test `depends_on_no_calib_crate` keeps the
//! manifest so.
#![deny(missing_docs)]

pub mod kinematics;
pub mod lm;

pub use kinematics::*;

#[cfg(test)]
mod tests {
    /// Fails if the manifest lists any crate of this workspace (calib-core, host-tools, ...)
    /// among the reference's dependencies.
    #[test]
    fn depends_on_no_calib_crate() {
        let manifest = include_str!("../Cargo.toml");
        let mut section = "";
        let mut dependencies = Vec::new();
        for line in manifest.lines().map(str::trim) {
            if line.starts_with('[') {
                section = line;
            } else if section.contains("dependencies") && !line.is_empty() && !line.starts_with('#')
            {
                dependencies.push(
                    line.split(['=', ' '])
                        .next()
                        .unwrap_or_default()
                        .to_string(),
                );
            }
        }
        assert_eq!(
            dependencies,
            ["levenberg-marquardt", "nalgebra034", "thiserror"]
        );
        assert!(
            !manifest.contains("path ="),
            "no path dependency on a workspace crate"
        );
    }
}
