//! Touches of sockets, read from files: a ball on the flange held in fixed but unknown points
//! (the sockets of a printed tool) from several arm configurations, joint readings only, as the
//! MUKCa protocol records them (`DIR/<placement>/hole_0.csv`, `hole_1.csv`: one configuration
//! per line, the joints in radians, comma-separated, no header). Each folder of `DIR` is a
//! placement of the tool, each `hole_<n>.csv` in it one socket; the core fits them as common
//! points (`calib_core::identify::common_point`).
//!
//! Every file is read whole and checked before anything is used: a line of another joint count
//! than the robot's, a value that is not a finite number, a placement without `hole_0.csv` or
//! with a gap in its numbering, a file without readings are refused naming the file and line.

use crate::io::input::{Input, read_text};
use crate::io::tracker_data::DataError;
use std::path::{Path, PathBuf};

/// One arm configuration with the ball in a socket.
#[derive(Clone, Debug, PartialEq)]
pub struct Reading {
    /// The line of the file, 1-based.
    pub line: u64,
    /// The joint readings, rad.
    pub q_rad: Vec<f64>,
}

/// The readings of one socket of a placement: one file.
#[derive(Clone, Debug, PartialEq)]
pub struct Socket {
    /// The file read.
    pub path: PathBuf,
    /// Its configurations, in file order.
    pub readings: Vec<Reading>,
}

/// One placement of the sockets' tool: its folder's name and its sockets (`hole_0`, `hole_1`,
/// ... in order).
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// The folder's name, such as `frontcenter`.
    pub name: String,
    /// The sockets, numbered as their files.
    pub sockets: Vec<Socket>,
}

/// The placements in the folder `dir` (each sub-folder one, in name order) of a robot of
/// `joints` joints. Refused: a folder that cannot be read or holds no placement, and every
/// refusal of [`read_socket`].
pub fn read_layout(dir: &Path, joints: usize) -> crate::Result<Vec<Placement>> {
    let unreadable = |source| DataError::Read {
        path: dir.to_path_buf(),
        source,
    };
    let mut folders = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(unreadable)? {
        let entry = entry.map_err(unreadable)?;
        if entry.file_type().map_err(unreadable)?.is_dir() {
            folders.push(entry.path());
        }
    }
    folders.sort();
    if folders.is_empty() {
        return Err(crate::refused!(input dir.display();
            "{}: no placement folders: the layout is {}/<placement>/hole_0.csv, hole_1.csv, ...",
            dir.display(),
            dir.display()
        ));
    }
    folders
        .iter()
        .map(|folder| read_placement(folder, joints))
        .collect()
}

/// The sockets of the placement folder `folder`: `hole_0.csv`, `hole_1.csv`, ... without a gap.
fn read_placement(folder: &Path, joints: usize) -> crate::Result<Placement> {
    let mut sockets = Vec::new();
    loop {
        let path = folder.join(format!("hole_{}.csv", sockets.len()));
        if !path.is_file() {
            break;
        }
        sockets.push(read_socket(&path, joints)?);
    }
    let name = folder
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if sockets.is_empty() {
        return Err(crate::refused!(input folder.display();
            "{}: no hole_0.csv: a placement folder holds one file per socket, hole_0.csv, hole_1.csv, ...",
            folder.display()
        ));
    }
    let listed = std::fs::read_dir(folder).map_or(0, |entries| {
        (entries.filter_map(Result::ok))
            .filter(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.starts_with("hole_") && !name.contains("_pose") && name.ends_with(".csv")
            })
            .count()
    });
    if listed != sockets.len() {
        return Err(crate::refused!(input folder.display();
            "{}: {listed} hole files, but hole_{} is missing: number the sockets' files hole_0.csv, hole_1.csv, ... without a gap",
            folder.display(),
            sockets.len()
        ));
    }
    Ok(Placement { name, sockets })
}

/// The readings of one socket file at `path` of a robot of `joints` joints: every non-empty line
/// `joints` numbers (rad). Refused, naming the file and line: another count, a value that is not
/// a finite number, no readings.
pub fn read_socket(path: &Path, joints: usize) -> Result<Socket, DataError> {
    let text = read_text(path, Input::Data).map_err(|source| DataError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let at = |line: u64, column: Option<String>, message: String| DataError::At {
        path: path.to_path_buf(),
        line,
        column,
        message,
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    // Split by lines here rather than by the csv crate, which skips empty lines without counting
    // them in its line numbers: a refusal must name the line an editor shows.
    let mut readings = Vec::new();
    for (index, text_line) in text.lines().enumerate() {
        let line = index as u64 + 1;
        if text_line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = text_line.split(',').map(str::trim).collect();
        if fields.len() != joints {
            return Err(at(
                line,
                None,
                format!(
                    "has {} values, the robot has {joints} joints: one configuration per line, the joints in radians",
                    fields.len()
                ),
            ));
        }
        let mut q_rad = Vec::with_capacity(joints);
        for (i, field) in fields.iter().enumerate() {
            let value = field.parse::<f64>().ok().filter(|v| v.is_finite());
            let Some(value) = value else {
                return Err(at(
                    line,
                    Some(format!("q{}", i + 1)),
                    format!("\"{field}\" is not a finite number (radians)"),
                ));
            };
            q_rad.push(value);
        }
        readings.push(Reading { line, q_rad });
    }
    if readings.is_empty() {
        return Err(at(1, None, "no configurations: the file is empty".into()));
    }
    Ok(Socket {
        path: path.to_path_buf(),
        readings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PANDA_3: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/mukca-sockets/panda_3");

    /// The bundled `panda_3`: six placements in name order, two sockets each, every line of every
    /// file read (counted independently, by lines), seven joints each.
    #[test]
    fn reads_the_bundled_layout_as_published() {
        let placements = read_layout(Path::new(PANDA_3), 7).unwrap();
        let names: Vec<&str> = placements.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "backcenter",
                "backleft",
                "backright",
                "frontcenter",
                "frontleft",
                "frontright"
            ]
        );
        for placement in &placements {
            assert_eq!(placement.sockets.len(), 2);
            for socket in &placement.sockets {
                let text = std::fs::read_to_string(&socket.path).unwrap();
                let lines = text.lines().filter(|l| !l.trim().is_empty()).count();
                assert_eq!(socket.readings.len(), lines, "{}", socket.path.display());
                assert!(socket.readings.iter().all(|r| r.q_rad.len() == 7));
            }
        }
        let first = &placements[3].sockets[0].readings[0];
        assert_eq!(first.line, 1);
        // The file's first value, 6.890856181302096317e-02, parsed to the nearest f64.
        assert_eq!(
            first.q_rad[0],
            "6.890856181302096317e-02".parse::<f64>().unwrap()
        );
    }

    /// Bad files are refused with the file and line (and the joint, for a value).
    #[test]
    fn bad_files_are_refused_naming_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let socket = |text: &str| {
            let path = dir.path().join("hole_0.csv");
            std::fs::write(&path, text).unwrap();
            read_socket(&path, 3).unwrap_err().to_string()
        };
        let e = socket("0.1,0.2,0.3\n0.1,0.2\n");
        assert!(e.ends_with("hole_0.csv:2: has 2 values, the robot has 3 joints: one configuration per line, the joints in radians"), "{e}");
        let e = socket("0.1,0.2,0.3\n\n0.1,nan,0.3\n");
        assert!(
            e.ends_with("hole_0.csv:3: column q2: \"nan\" is not a finite number (radians)"),
            "{e}"
        );
        let e = socket("0.1,0.2,x\n");
        assert!(e.contains(":1: column q3: \"x\""), "{e}");
        let e = socket("\n\n");
        assert!(
            e.ends_with("hole_0.csv:1: no configurations: the file is empty"),
            "{e}"
        );
        // A layout without placements, a placement without hole_0, one with a gap.
        let empty = tempfile::tempdir().unwrap();
        let e = read_layout(empty.path(), 3).unwrap_err().to_string();
        assert!(e.contains("no placement folders"), "{e}");
        let placement = empty.path().join("front");
        std::fs::create_dir(&placement).unwrap();
        std::fs::write(placement.join("hole_1.csv"), "0.1,0.2,0.3\n").unwrap();
        let e = read_layout(empty.path(), 3).unwrap_err().to_string();
        assert!(e.contains("front: no hole_0.csv"), "{e}");
        std::fs::write(placement.join("hole_0.csv"), "0.1,0.2,0.3\n").unwrap();
        std::fs::write(placement.join("hole_3.csv"), "0.1,0.2,0.3\n").unwrap();
        let e = read_layout(empty.path(), 3).unwrap_err().to_string();
        assert!(e.contains("3 hole files, but hole_2 is missing"), "{e}");
        std::fs::remove_file(placement.join("hole_3.csv")).unwrap();
        let read = read_layout(empty.path(), 3).unwrap();
        assert_eq!((read.len(), read[0].sockets.len()), (1, 2));
    }
}
