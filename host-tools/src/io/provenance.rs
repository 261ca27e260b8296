//! Where a calibration came from: each input file's path, the flag it was given with, and the
//! SHA-256 of its content, recorded in the identified robot file (`[calibration]` for the files
//! the geometry was identified from, `[measurement]` for those the frames were registered from),
//! so that a file on the controller can be traced back to the exact data behind it, and a changed
//! input found by hashing it again (`sha256sum FILE`).

use serde::{Deserialize, Serialize};
use sha2::Digest as _;
use std::io::Read as _;
use std::path::Path;

/// One input file of a calibration.
#[derive(Clone, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InputFile {
    /// The command-line flag it was given with (`--robot`, `--data`, `--profile`, `--holdout`).
    pub flag: String,
    /// The path as given.
    pub path: String,
    /// SHA-256 of the file's bytes, 64 lowercase hexadecimal digits (as `sha256sum` prints it).
    pub sha256: String,
}

impl InputFile {
    /// The record of the file at `path`, given with `flag`: the hash of the bytes this process
    /// read from it ([`crate::io::input::read`]), or, for a file it did not read, of its content
    /// as it is now.
    pub fn of(flag: &str, path: &Path) -> crate::Result<Self> {
        let sha256 = match crate::io::input::sha256_of_read(path) {
            Some(hash) => hash,
            None => sha256_hex(path)?,
        };
        Ok(Self {
            flag: flag.to_string(),
            path: path.display().to_string(),
            sha256,
        })
    }

    /// The records of `inputs` (flag, path), in order.
    pub fn all(inputs: &[(&str, &Path)]) -> crate::Result<Vec<Self>> {
        inputs
            .iter()
            .map(|(flag, path)| Self::of(flag, path))
            .collect()
    }
}

/// The SHA-256 of `bytes`, 64 lowercase hexadecimal digits.
pub fn sha256(bytes: &[u8]) -> String {
    use sha2::Digest as _;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The SHA-256 of the file at `path` as 64 lowercase hexadecimal digits, read in blocks (a data
/// file may be large).
pub(crate) fn sha256_hex(path: &Path) -> crate::Result<String> {
    use crate::error::Context as _;
    let read = || -> std::io::Result<String> {
        let mut file = std::fs::File::open(path)?;
        let mut hasher = sha2::Sha256::new();
        let mut block = vec![0u8; 1 << 16];
        loop {
            let n = file.read(&mut block)?;
            if n == 0 {
                break;
            }
            hasher.update(&block[..n]);
        }
        Ok(hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect())
    };
    read().with_context(|| format!("{}: cannot read the file to hash it", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The FIPS 180-2 test vectors: "abc" and the empty message.
    #[test]
    fn hashes_are_the_standards_test_vectors() {
        let dir = tempfile::tempdir().unwrap();
        let abc = dir.path().join("abc");
        std::fs::write(&abc, "abc").unwrap();
        assert_eq!(
            sha256_hex(&abc).unwrap(),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let empty = dir.path().join("empty");
        std::fs::write(&empty, "").unwrap();
        assert_eq!(
            sha256_hex(&empty).unwrap(),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
        let missing = dir.path().join("missing.csv");
        let err = sha256_hex(&missing).unwrap_err().to_string();
        assert!(
            err.contains("missing.csv: cannot read the file to hash it"),
            "{err}"
        );
    }
}
