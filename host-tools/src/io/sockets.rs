//! Touches of sockets, read from files: a ball on the flange held in fixed but unknown points
//! (the sockets of a printed tool) from several arm configurations, joint readings only, as the
//! MUKCa protocol records them (`DIR/<placement>/hole_0.csv`, `hole_1.csv`: one configuration
//! per line, the joints in radians, comma-separated, no header). Each folder of `DIR` is a
//! placement of the tool, each `hole_<n>.csv` in it one socket; the core fits them as common
//! points (`calib_core::identify::common_point`).
//!
//! Contacts of the ball with planes (a flat surface touched from many configurations, the
//! plane unknown) are read the same way: `plane_0.csv`, `plane_1.csv`, ... in a placement's
//! folder, beside or instead of its sockets.
//!
//! Our own format is one CSV file of every touch ([`read_touches_csv`]): a header
//! `placement,socket,q1_deg,...,qN_deg` (or `q1_rad,...`), then one touch per line, the placement
//! a name, the socket a number from 0, the joints in the header's unit as in our tracker CSV;
//! lines starting with `#` are comments. A file of plane contacts names its second column
//! `plane` instead (`placement,plane,q1_deg,...`).
//!
//! Tracker positions of the same ball, for a calibration that mixes them with touches
//! ([`read_tracker_csv`]): a header `q1_deg,...,qN_deg,x_mm,y_mm,z_mm` (or the joints in `_rad`),
//! one position per line, the ball's centre in the tracker's frame, mm.
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

/// The readings of one socket (or one plane) of a placement: one file.
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
    /// The planes touched, numbered as their files (`plane_<n>.csv`): each one's contacts.
    pub planes: Vec<Socket>,
}

/// What the touches of a file or a list touch: sockets (common points) or planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// Sockets: the ball held at one point (`hole_<n>.csv`, the column `socket`).
    Socket,
    /// Planes: the ball pressed on one flat surface (`plane_<n>.csv`, the column `plane`).
    Plane,
}

impl Feature {
    /// The word of its files and column: `socket` or `plane`.
    pub fn word(self) -> &'static str {
        match self {
            Self::Socket => "socket",
            Self::Plane => "plane",
        }
    }

    /// The prefix of its files in a placement's folder: `hole_` or `plane_`.
    fn file_prefix(self) -> &'static str {
        match self {
            Self::Socket => "hole_",
            Self::Plane => "plane_",
        }
    }
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

/// The sockets and planes of the placement folder `folder`: `hole_0.csv`, `hole_1.csv`, ... and
/// `plane_0.csv`, ... each without a gap; at least one of them.
fn read_placement(folder: &Path, joints: usize) -> crate::Result<Placement> {
    let name = folder
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let sockets = read_numbered(folder, Feature::Socket, joints)?;
    let planes = read_numbered(folder, Feature::Plane, joints)?;
    if sockets.is_empty() && planes.is_empty() {
        return Err(crate::refused!(input folder.display();
            "{}: no hole_0.csv or plane_0.csv: a placement folder holds one file per socket, hole_0.csv, hole_1.csv, ..., and one per plane, plane_0.csv, ...",
            folder.display()
        ));
    }
    Ok(Placement {
        name,
        sockets,
        planes,
    })
}

/// The files `<prefix>0.csv`, `<prefix>1.csv`, ... of `feature` in `folder`, without a gap.
fn read_numbered(folder: &Path, feature: Feature, joints: usize) -> crate::Result<Vec<Socket>> {
    let prefix = feature.file_prefix();
    let mut read = Vec::new();
    loop {
        let path = folder.join(format!("{prefix}{}.csv", read.len()));
        if !path.is_file() {
            break;
        }
        read.push(read_socket(&path, joints)?);
    }
    let listed = std::fs::read_dir(folder).map_or(0, |entries| {
        (entries.filter_map(Result::ok))
            .filter(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.starts_with(prefix) && !name.contains("_pose") && name.ends_with(".csv")
            })
            .count()
    });
    if listed != read.len() {
        let what = if feature == Feature::Socket {
            "hole"
        } else {
            "plane"
        };
        return Err(crate::refused!(input folder.display();
            "{}: {listed} {what} files, but {prefix}{}.csv is missing: number the {}s' files {prefix}0.csv, {prefix}1.csv, ... without a gap",
            folder.display(),
            read.len(),
            feature.word()
        ));
    }
    Ok(read)
}

/// The text of the file at `path`, read whole within the data limit.
fn text_of(path: &Path) -> Result<String, DataError> {
    read_text(path, Input::Data).map_err(|source| DataError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// A refusal of `path`'s `line` (and `column`) saying why.
fn at(path: &Path, line: u64, column: Option<String>, message: String) -> DataError {
    DataError::At {
        path: path.to_path_buf(),
        line,
        column,
        message,
    }
}

/// The readings of one socket file at `path` of a robot of `joints` joints: every non-empty line
/// `joints` numbers (rad). Refused, naming the file and line: another count, a value that is not
/// a finite number, no readings.
pub fn read_socket(path: &Path, joints: usize) -> Result<Socket, DataError> {
    let text = text_of(path)?;
    let at = |line: u64, column: Option<String>, message: String| at(path, line, column, message);
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

/// The touches of our CSV file at `path` (see the module) for a robot of `joints` joints, as
/// placements in the order they first appear, their sockets by number. Refused, naming the file
/// and line: a header other than `placement,socket,q1_deg,...` (or `_rad`), a line of another field count, an
/// empty placement name, a socket that is not a number, a joint value that is not a finite
/// number, a placement whose socket numbers have a gap, no touches.
pub fn read_touches_csv(path: &Path, joints: usize) -> Result<Vec<Placement>, DataError> {
    let text = text_of(path)?;
    let at = |line: u64, column: Option<String>, message: String| at(path, line, column, message);
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let header_in = |feature: Feature, unit: &str| -> Vec<String> {
        ["placement".to_string(), feature.word().to_string()]
            .into_iter()
            .chain((1..=joints).map(|j| format!("q{j}_{unit}")))
            .collect()
    };
    let mut expected = header_in(Feature::Socket, "deg");
    let (mut degrees, mut feature) = (true, Feature::Socket);
    let mut header = false;
    let mut touches = Vec::new();
    for (index, text_line) in text.lines().enumerate() {
        let line = index as u64 + 1;
        let trimmed = text_line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = trimmed.split(',').map(str::trim).collect();
        if !header {
            let known = [Feature::Socket, Feature::Plane]
                .into_iter()
                .flat_map(|f| [(f, "deg", true), (f, "rad", false)])
                .find(|(f, unit, _)| fields == header_in(*f, unit));
            let Some((f, unit, in_degrees)) = known else {
                return Err(at(
                    line,
                    None,
                    format!(
                        "the header is \"{trimmed}\"; a touch file of a {joints}-joint robot starts with {} (or the joints in _rad, or plane for socket in a file of plane contacts)",
                        expected.join(",")
                    ),
                ));
            };
            (expected, degrees, feature) = (header_in(f, unit), in_degrees, f);
            header = true;
            continue;
        }
        let touch = touch_of_line(&fields, (&expected, degrees), line)
            .map_err(|(column, message)| at(line, column, message))?;
        touches.push(touch);
    }
    if touches.is_empty() {
        return Err(at(
            1,
            None,
            "no touches: the file has no lines after its header".into(),
        ));
    }
    group_touches(touches, path, feature)
}

/// One line of our touch CSV, `fields` under the header `expected` (joints in degrees when
/// `degrees`): (placement, socket, reading), or the column and why it is refused.
fn touch_of_line(
    fields: &[&str],
    (expected, degrees): (&[String], bool),
    line: u64,
) -> Result<(String, usize, Reading), (Option<String>, String)> {
    if fields.len() != expected.len() {
        return Err((
            None,
            format!(
                "has {} fields, the header {}: placement, {}, then the {} joints",
                fields.len(),
                expected.len(),
                expected[1],
                expected.len() - 2
            ),
        ));
    }
    let name = fields[0];
    if name.is_empty() {
        return Err((Some("placement".into()), "no placement name".into()));
    }
    let socket: usize = (fields[1].parse().ok())
        .filter(|s| *s < 1000)
        .ok_or_else(|| {
            (
                Some(expected[1].clone()),
                format!(
                    "\"{}\" is not a {} number (0, 1, ...)",
                    fields[1], expected[1]
                ),
            )
        })?;
    let mut q_rad = Vec::with_capacity(fields.len() - 2);
    for (field, column) in fields[2..].iter().zip(&expected[2..]) {
        let value = finite_field(field, column)?;
        q_rad.push(if degrees { value.to_radians() } else { value });
    }
    Ok((name.to_string(), socket, Reading { line, q_rad }))
}

/// Touches as placements: `touches` (placement name, socket or plane number, reading) of
/// `feature` grouped by placement in the order they first appear, each placement's sockets (or
/// planes) by number; `path` names the source (a file, or `<memory>`). Refused: a placement
/// whose numbers have a gap.
pub fn group_touches(
    touches: Vec<(String, usize, Reading)>,
    path: &Path,
    feature: Feature,
) -> Result<Vec<Placement>, DataError> {
    let mut placements: Vec<(String, Vec<Vec<Reading>>)> = Vec::new();
    for (name, socket, reading) in touches {
        let index = match placements.iter().position(|(n, _)| *n == name) {
            Some(i) => i,
            None => {
                placements.push((name, Vec::new()));
                placements.len() - 1
            }
        };
        let sockets = &mut placements[index].1;
        if sockets.len() <= socket {
            sockets.resize_with(socket + 1, Vec::new);
        }
        sockets[socket].push(reading);
    }
    placements
        .into_iter()
        .map(|(name, sockets)| {
            if let Some(gap) = sockets.iter().position(Vec::is_empty) {
                let word = feature.word();
                return Err(at(path, 1, Some(word.into()), format!(
                    "placement {name} has no touch of {word} {gap} but touches of {word} {}: number the {word}s 0, 1, ... without a gap",
                    sockets.len() - 1
                )));
            }
            let read: Vec<Socket> = (sockets.into_iter())
                .map(|readings| Socket {
                    path: path.to_path_buf(),
                    readings,
                })
                .collect();
            let (sockets, planes) = match feature {
                Feature::Socket => (read, Vec::new()),
                Feature::Plane => (Vec::new(), read),
            };
            Ok(Placement {
                name,
                sockets,
                planes,
            })
        })
        .collect()
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
        assert!(
            e.contains("front: 1 hole files, but hole_0.csv is missing"),
            "{e}"
        );
        std::fs::remove_file(placement.join("hole_1.csv")).unwrap();
        std::fs::write(placement.join("notes.txt"), "").unwrap();
        let e = read_layout(empty.path(), 3).unwrap_err().to_string();
        assert!(e.contains("front: no hole_0.csv or plane_0.csv"), "{e}");
        // Plane contacts alone make a placement; a gap in their numbers is refused.
        std::fs::write(placement.join("plane_0.csv"), "0.1,0.2,0.3\n0.2,0.2,0.3\n").unwrap();
        let read = read_layout(empty.path(), 3).unwrap();
        assert_eq!((read[0].sockets.len(), read[0].planes.len()), (0, 1));
        assert_eq!(read[0].planes[0].readings[1].q_rad, [0.2, 0.2, 0.3]);
        std::fs::write(placement.join("plane_2.csv"), "0.1,0.2,0.3\n").unwrap();
        let e = read_layout(empty.path(), 3).unwrap_err().to_string();
        assert!(
            e.contains("2 plane files, but plane_1.csv is missing"),
            "{e}"
        );
        std::fs::remove_file(placement.join("plane_2.csv")).unwrap();
        std::fs::write(placement.join("hole_1.csv"), "0.1,0.2,0.3\n").unwrap();
        std::fs::write(placement.join("hole_0.csv"), "0.1,0.2,0.3\n").unwrap();
        std::fs::write(placement.join("hole_3.csv"), "0.1,0.2,0.3\n").unwrap();
        let e = read_layout(empty.path(), 3).unwrap_err().to_string();
        assert!(e.contains("3 hole files, but hole_2.csv is missing"), "{e}");
        std::fs::remove_file(placement.join("hole_3.csv")).unwrap();
        let read = read_layout(empty.path(), 3).unwrap();
        assert_eq!((read.len(), read[0].sockets.len()), (1, 2));
    }

    /// Our CSV: read as the bundled layout reads (the same configurations, degrees converted),
    /// and bad lines refused with the file and line.
    #[test]
    fn our_csv_reads_what_the_layout_reads() {
        let layout = read_layout(Path::new(PANDA_3), 7).unwrap();
        let mut csv = String::from(
            "# panda_3 converted\nplacement,socket,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,q7_deg\n",
        );
        for p in &layout {
            for (s, socket) in p.sockets.iter().enumerate() {
                for r in &socket.readings {
                    let q: Vec<String> = r
                        .q_rad
                        .iter()
                        .map(|v| format!("{:?}", v.to_degrees()))
                        .collect();
                    csv.push_str(&format!("{},{s},{}\n", p.name, q.join(",")));
                }
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("touches.csv");
        std::fs::write(&path, &csv).unwrap();
        let read = read_touches_csv(&path, 7).unwrap();
        assert_eq!(read.len(), layout.len());
        for (a, b) in read.iter().zip(&layout) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.sockets.len(), b.sockets.len());
            for (x, y) in a.sockets.iter().zip(&b.sockets) {
                assert_eq!(x.readings.len(), y.readings.len());
                for (u, v) in x.readings.iter().zip(&y.readings) {
                    for (p, q) in u.q_rad.iter().zip(&v.q_rad) {
                        assert!((p - q).abs() < 1e-15, "{p} {q}");
                    }
                }
            }
        }
        let refused = |text: &str| {
            std::fs::write(&path, text).unwrap();
            read_touches_csv(&path, 2).unwrap_err().to_string()
        };
        let e = refused("placement,socket,q1,q2\n");
        assert!(e.contains(":1: the header is"), "{e}");
        let e = refused("placement,socket,q1_deg,q2_deg\nfront,0,1.0\n");
        assert!(e.contains(":2: has 3 fields"), "{e}");
        let e = refused("placement,socket,q1_deg,q2_deg\nfront,x,1.0,2.0\n");
        assert!(
            e.contains(":2: column socket: \"x\" is not a socket number"),
            "{e}"
        );
        let e = refused("placement,socket,q1_deg,q2_deg\nfront,0,1.0,inf\n");
        assert!(
            e.contains(":2: column q2_deg: \"inf\" is not a finite number"),
            "{e}"
        );
        let e = refused("placement,socket,q1_deg,q2_deg\nfront,1,1.0,2.0\n");
        assert!(
            e.contains("placement front has no touch of socket 0"),
            "{e}"
        );
        let e = refused("placement,socket,q1_deg,q2_deg\n");
        assert!(e.contains("no touches"), "{e}");
        std::fs::write(&path, "placement,socket,q1_rad,q2_rad\nfront,0,0.5,-1.5\n").unwrap();
        let rad = read_touches_csv(&path, 2).unwrap();
        assert_eq!(rad[0].sockets[0].readings[0].q_rad, [0.5, -1.5]);
        // A file of plane contacts: the column `plane`, read into the planes.
        std::fs::write(&path, "placement,plane,q1_deg,q2_deg\ntable,0,90,-45\n").unwrap();
        let planes = read_touches_csv(&path, 2).unwrap();
        assert!(planes[0].sockets.is_empty());
        assert_eq!(
            planes[0].planes[0].readings[0].q_rad,
            [90f64.to_radians(), (-45f64).to_radians()]
        );
        let e = refused("placement,plane,q1_deg,q2_deg\ntable,1,1.0,2.0\n");
        assert!(e.contains("placement table has no touch of plane 0"), "{e}");
        let e = refused("placement,plane,q1_deg,q2_deg\ntable,-1,1.0,2.0\n");
        assert!(
            e.contains(":2: column plane: \"-1\" is not a plane number"),
            "{e}"
        );
    }
}

/// One position of the ball measured by a tracker (for a calibration that mixes tracker
/// positions with touches).
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerPoint {
    /// The joint readings, rad.
    pub q_rad: Vec<f64>,
    /// The ball's centre in the tracker's frame, mm.
    pub position_mm: [f64; 3],
}

/// The tracker positions of our CSV file at `path` for a robot of `joints` joints: a header
/// `q1_deg,...,qN_deg,x_mm,y_mm,z_mm` (or the joints in `_rad`), then one position per line;
/// lines starting with `#` are comments. Refused, naming the file and line: another header, a
/// line of another field count, a value that is not a finite number, no positions.
pub fn read_tracker_csv(path: &Path, joints: usize) -> Result<Vec<TrackerPoint>, DataError> {
    let text = text_of(path)?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let header_in = |unit: &str| -> Vec<String> {
        ((1..=joints).map(|j| format!("q{j}_{unit}")))
            .chain(["x_mm", "y_mm", "z_mm"].map(String::from))
            .collect()
    };
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes());
    let header: Vec<String> = (reader.headers())
        .map_err(|e| at(path, 1, None, format!("unreadable header: {e}")))?
        .iter()
        .map(String::from)
        .collect();
    let degrees = header == header_in("deg");
    if !degrees && header != header_in("rad") {
        return Err(at(
            path,
            1,
            None,
            format!(
                "the header is \"{}\"; a file of tracker positions of a {joints}-joint robot starts with {} (or the joints in _rad)",
                header.join(","),
                header_in("deg").join(",")
            ),
        ));
    }
    let mut points = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, csv::Position::line);
            at(path, line, None, format!("unreadable line: {e}"))
        })?;
        points.push(tracker_point(&record, &header, degrees, joints).map_err(
            |(column, message)| {
                let line = record.position().map_or(0, csv::Position::line);
                at(path, line, column, message)
            },
        )?);
    }
    if points.is_empty() {
        return Err(at(
            path,
            1,
            None,
            "no positions: the file has no lines after its header".into(),
        ));
    }
    Ok(points)
}

/// One line of a tracker-position file under `header` (joints in degrees when `degrees`), or
/// the column and why it is refused.
fn tracker_point(
    record: &csv::StringRecord,
    header: &[String],
    degrees: bool,
    joints: usize,
) -> Result<TrackerPoint, (Option<String>, String)> {
    if record.len() != header.len() {
        return Err((
            None,
            format!(
                "has {} fields, the header {}: the {joints} joints, then x_mm, y_mm, z_mm",
                record.len(),
                header.len()
            ),
        ));
    }
    let mut values = Vec::with_capacity(record.len());
    for (field, column) in record.iter().zip(header) {
        values.push(finite_field(field, column)?);
    }
    let (q, xyz) = values.split_at(joints.min(values.len()));
    let [x, y, z] = xyz[..] else {
        return Err((
            None,
            "three coordinates x_mm, y_mm, z_mm after the joints".into(),
        ));
    };
    Ok(TrackerPoint {
        q_rad: (q.iter())
            .map(|v| if degrees { v.to_radians() } else { *v })
            .collect(),
        position_mm: [x, y, z],
    })
}

/// The finite number in `field` of `column`, or the column and why it is refused.
fn finite_field(field: &str, column: &str) -> Result<f64, (Option<String>, String)> {
    (field.parse::<f64>().ok())
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            (
                Some(column.to_string()),
                format!("\"{field}\" is not a finite number"),
            )
        })
}
