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
        // The crate's two spellings, assembled so that this test does not name them itself.
        let names = [["calib", "_core"].concat(), ["calib", "-core"].concat()];
        let mut checked = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let text = std::fs::read_to_string(&path).unwrap();
            let uses_core = text
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .any(|l| names.iter().any(|n| l.contains(n.as_str())));
            assert!(!uses_core, "{} uses the core crate", path.display());
            checked += 1;
        }
        assert_eq!(checked, 3, "kinematics.rs, lm.rs and mod.rs");
    }
}
