//! The independent float64 reference that checks the core: forward kinematics and pose error
//! written plainly from the elementary transforms ([`kinematics`]), and a least-squares fit with
//! the `levenberg-marquardt` crate on them ([`lm`]). Nothing here may use calib-core, or agreement
//! with the core would prove nothing; the test `reference_is_independent_of_the_core` checks it.

pub mod kinematics;
pub mod lm;

pub use kinematics::*;

#[cfg(test)]
mod tests {
    /// Fails if any file of the reference mentions the core crate.
    #[test]
    fn reference_is_independent_of_the_core() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/reference");
        let mut checked = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let text = std::fs::read_to_string(&path).unwrap();
            let uses_core = text
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .any(|l| l.contains("calib_core") || l.contains("calib-core"));
            assert!(!uses_core, "{} uses calib-core", path.display());
            checked += 1;
        }
        assert_eq!(checked, 3, "kinematics.rs, lm.rs and mod.rs");
    }
}
