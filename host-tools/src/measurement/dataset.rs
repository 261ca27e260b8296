//! A dataset: the poses measured on a robot, checked against its robot file and converted into
//! the core's units and types (mm, rad, [`Measurement`]), read from files or built in memory;
//! the poses as a model of the robot sees them ([`Seen`]); and the held-out split used for
//! validation.

use crate::error::Context;
use crate::io::profile::DataProfile;
use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::{Record, TrackerData};
use crate::kinematics::actual::ActualRobot;
use calib_core::identify::objective::Measurement;
use calib_core::model::JointVec;
use nalgebra::Dyn;
use nalgebra::Vector3;
use rand_core::{Rng, SeedableRng};
use std::borrow::Cow;
use std::path::Path;

/// The poses measured on a robot, read once and checked against the robot file they were
/// measured with, in the core's units and types.
///
/// A dataset is never rewritten: a calibration's stages each take a model of the robot
/// ([`ActualRobot`]: the given one, then the one with the frames registered, the identified one)
/// and see the poses through it ([`Dataset::seen_by`]: its joint maps added to the readings, its
/// compliance taken off the measured poses).
#[derive(Clone)]
pub struct Dataset {
    /// The robot as given: the robot file the data were checked against, read and converted.
    pub robot: ActualRobot,
    /// The data file as read.
    pub data: TrackerData,
    /// One core measurement per data row, as measured: the joint readings (rad; a robot's joint
    /// maps are not added) and the measured pose (mm).
    pub readings: Vec<Measurement<f64, Dyn>>,
}

/// The robot, the data file and the number of poses (the poses themselves are many).
impl std::fmt::Debug for Dataset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dataset")
            .field("robot", &self.robot.model.name)
            .field("data", &self.data.path)
            .field("poses", &self.readings.len())
            .finish()
    }
}

/// The poses of a dataset as one model of the robot sees them: the kinematic angles (the joint
/// readings with the model's maps added) and the measured poses (with the model's compliance
/// taken off, when asked for): what the model's geometry must explain.
#[derive(Clone)]
pub struct Seen<'a> {
    /// The model that sees the poses.
    pub robot: &'a ActualRobot,
    /// The data file as read.
    pub data: &'a TrackerData,
    /// One core measurement per data row: the kinematic angles (rad) and the measured pose (mm);
    /// borrowed from the dataset's readings when the model has no maps or compliance.
    pub(crate) measurements: Cow<'a, [Measurement<f64, Dyn>]>,
}

impl Seen<'_> {
    /// One core measurement per data row: the kinematic angles (rad) and the measured pose (mm).
    pub fn measurements(&self) -> &[Measurement<f64, Dyn>] {
        &self.measurements
    }

    /// Number of residual rows: 6 per full pose, 3 per position-only pose.
    pub fn rows(&self) -> usize {
        self.measurements
            .iter()
            .map(|m| if m.rotation.is_some() { 6 } else { 3 })
            .sum()
    }

    /// These poses as `robot` sees them, a model with the same joint maps and compliance as
    /// this one and other frames or geometry (a registration's start, the reflector moved): the
    /// measurements borrowed, not computed again.
    pub(crate) fn for_robot<'b>(&'b self, robot: &'b ActualRobot) -> Seen<'b> {
        Seen {
            robot,
            data: self.data,
            measurements: Cow::Borrowed(&self.measurements),
        }
    }

    /// The core's identification problem on these poses: the parameters of `set` of this
    /// model's geometry, the others at zero error; `k` weights orientation, mm^2/rad^2 (eq. 7).
    pub fn problem(
        &self,
        set: calib_core::ParameterSet<Dyn, Dyn>,
        k: f64,
    ) -> crate::Result<calib_core::Problem<'_, f64, Dyn, Dyn>> {
        let robot = &self.robot.model.robot;
        let zero = calib_core::ParameterErrors::zeros_for(robot.joint_count());
        Ok(calib_core::Problem::new(
            robot,
            &zero,
            set,
            &self.measurements,
            k,
        )?)
    }

    /// The data as this geometry sees them: each record's joint readings replaced by the
    /// kinematic angles of its measurement (the joint maps added, in (-pi, pi]), its pose by the
    /// measured pose the measurement holds (the compliance taken off, when it was). For the
    /// reference kinematics, which knows neither maps nor compliance.
    pub(crate) fn as_tracker_data(&self) -> TrackerData {
        let mut data = self.data.clone();
        for (r, m) in data.records.iter_mut().zip(self.measurements.iter()) {
            r.q = m
                .angles
                .sin
                .iter()
                .zip(&m.angles.cos)
                .map(|(s, c)| s.atan2(*c))
                .collect();
            r.position = m.position.into();
            r.rotation = m.rotation;
        }
        data
    }
}

impl Dataset {
    /// A dataset from poses held in memory (joints in rad, positions in mm, rotations as
    /// matrices); `base_frame` says the positions are already in the robot's base frame. The same
    /// checks as for files apply; lines in messages are the 1-based index of the pose.
    pub fn from_records(
        file: RobotFile,
        records: Vec<Record>,
        base_frame: bool,
    ) -> crate::Result<Self> {
        let data = TrackerData::from_records(records, base_frame)?;
        Self::from_parts(file, Path::new("<memory>"), data)
    }

    /// Reads and checks both files (the data in our format).
    pub fn load(robot: &Path, data: &Path) -> crate::Result<Self> {
        Self::load_with(robot, data, &DataProfile::default())
    }

    /// Reads and checks both files, the data through a data profile.
    pub fn load_with(robot: &Path, data: &Path, profile: &DataProfile) -> crate::Result<Self> {
        let file = RobotFile::read(robot)?;
        let data_file = TrackerData::read_with(data, profile)?;
        Self::from_parts(file, robot, data_file)
    }

    /// The poses `data`, read or built before a robot was chosen, checked against the robot file
    /// `file` (named `robot` in messages) and converted for the core, as a file is read.
    pub fn from_data(file: RobotFile, robot: &Path, data: TrackerData) -> crate::Result<Self> {
        Self::from_parts(file, robot, data)
    }

    /// Checks the data against the robot and converts them for the core.
    fn from_parts(file: RobotFile, robot: &Path, data_file: TrackerData) -> crate::Result<Self> {
        let actual = ActualRobot::from_file(file, robot)?;
        let joints = actual.model.robot.joints.len();
        let data = data_file.path.clone();
        let data = data.as_path();
        if data_file.joints != joints {
            return Err(crate::refused!(input data.display();
                "{}:{}: has {} joint columns, the robot {} has {joints} joints",
                data.display(),
                data_file.header_line,
                data_file.joints,
                actual.model.name
            ));
        }
        if !data_file.records.is_empty() && data_file.records.iter().all(|r| r.weight == 0.0) {
            return Err(crate::refused!(input data.display();
                "{}: every pose has weight 0, so no pose counts; give the poses to use a weight above 0",
                data.display()
            ));
        }
        let mut readings = Vec::with_capacity(data_file.records.len());
        for r in &data_file.records {
            let q = joint_readings(r);
            for (i, (qi, limits)) in q.iter().zip(&actual.model.robot.limits).enumerate() {
                if !limits.contains(*qi) {
                    return Err(crate::refused!(input data.display();
                        "{}:{}: column q{}: {:.4} deg is outside the joint limits [{}, {}] deg of {}",
                        data.display(),
                        r.line,
                        i + 1,
                        qi.to_degrees(),
                        limits.lower.to_degrees(),
                        limits.upper.to_degrees(),
                        robot.display()
                    ));
                }
            }
            readings.push(measured_at(data, r, &q)?);
        }
        let dataset = Self {
            robot: actual,
            data: data_file,
            readings,
        };
        if let Some(maps) = &dataset.robot.maps {
            dataset.warn_extrapolated(maps, robot);
        }
        // The kinematic angles of every pose are checked once here, so that every later view
        // of the data through the same maps is known to succeed.
        dataset.seen_by(&dataset.robot)?;
        Ok(dataset)
    }

    /// The poses as the robot `robot` sees them: its joint maps (if any) added to every joint
    /// reading, the measured poses as measured. Borrows the readings when `robot` has no maps.
    pub fn seen_by<'a>(&'a self, robot: &'a ActualRobot) -> crate::Result<Seen<'a>> {
        let Some(maps) = &robot.maps else {
            return Ok(Seen {
                robot,
                data: &self.data,
                measurements: Cow::Borrowed(&self.readings),
            });
        };
        let measurements = (self.data.records.iter())
            .map(|r| measured_at(&self.data.path, r, &maps.apply(&joint_readings(r))))
            .collect::<crate::Result<_>>()?;
        Ok(Seen {
            robot,
            data: &self.data,
            measurements: Cow::Owned(measurements),
        })
    }

    /// The poses as the geometry of `robot` with the errors `errors` (mm and rad, in the frames
    /// of `robot`) alone must explain them: [`Self::seen_by`] with the gravity compliance's
    /// displacement of `robot` (if any; held fixed) taken off every measured pose, evaluated at
    /// the kinematic angles of that geometry. Commands that fit or check the geometry of a model
    /// with compliance use it (the deflection depends on the geometry only to second order: a few
    /// tenths of a millimetre times its relative change).
    pub(crate) fn seen_by_geometry<'a>(
        &'a self,
        robot: &'a ActualRobot,
        errors: &calib_core::ParameterErrors<f64, Dyn>,
    ) -> crate::Result<Seen<'a>> {
        if robot.compliance.is_none() {
            return self.seen_by(robot);
        }
        let mut measurements = Vec::with_capacity(self.readings.len());
        for r in &self.data.records {
            let angles = robot.kinematic_angles(&joint_readings(r));
            let mut m = measured_at(&self.data.path, r, &angles)?;
            if let Some(d) = robot.deflection(&robot.model.robot, errors, &angles)? {
                m.position -= Vector3::new(d[0], d[1], d[2]);
                if let Some(rotation) = m.rotation.as_mut() {
                    *rotation = nalgebra::Rotation3::new(-Vector3::new(d[3], d[4], d[5])).matrix()
                        * *rotation;
                }
            }
            measurements.push(m);
        }
        Ok(Seen {
            robot,
            data: &self.data,
            measurements: Cow::Owned(measurements),
        })
    }

    /// The poses as the robot file they were checked against sees them ([`Self::seen_by`] the
    /// given robot).
    pub(crate) fn as_given(&self) -> crate::Result<Seen<'_>> {
        self.seen_by(&self.robot)
    }

    /// Warns on standard error for every joint whose non-zero map (of the robot file at `robot`)
    /// is extrapolated: readings outside the range it was identified on.
    fn warn_extrapolated(&self, maps: &crate::model::joint_maps::JointMaps, robot: &Path) {
        let ranges = self
            .robot
            .file
            .joint_maps
            .as_ref()
            .map(crate::model::joint_maps::JointMapsSection::ranges)
            .unwrap_or_default();
        for (j, range) in ranges.iter().enumerate().filter(|(j, _)| !maps.is_zero(*j)) {
            let count = self
                .data
                .records
                .iter()
                .filter(|r| {
                    r.q.get(j)
                        .is_some_and(|q| *q < range[0] - 1e-9 || *q > range[1] + 1e-9)
                })
                .count();
            if count > 0 {
                eprintln!(
                    "warning: {}: {count} poses have joint {} outside the range its joint map was identified on \
                     ({:.1} to {:.1} deg, [joint_maps] of {}): the map is extrapolated there and may be wrong",
                    self.data.path.display(),
                    j + 1,
                    range[0].to_degrees(),
                    range[1].to_degrees(),
                    robot.display()
                );
            }
        }
    }

    /// `(the others, the poses at indices)`: the data split in two, file order kept. Linear in
    /// the poses, and each pose is copied once (2,000,000 poses are 1 GB).
    pub fn partition(&self, indices: &[usize]) -> (Self, Self) {
        let chosen = mask(self.readings.len(), indices);
        let taken_count = chosen.iter().filter(|c| **c).count();
        let mut kept = self.empty_like(self.readings.len() - taken_count);
        let mut taken = self.empty_like(taken_count);
        for ((record, m), taken_here) in self.data.records.iter().zip(&self.readings).zip(chosen) {
            let side = if taken_here { &mut taken } else { &mut kept };
            side.data.records.push(record.clone());
            side.readings.push(*m);
        }
        (kept, taken)
    }

    /// The same robot and file with no pose, room for `capacity` poses.
    fn empty_like(&self, capacity: usize) -> Self {
        let data = &self.data;
        Self {
            robot: self.robot.clone(),
            data: TrackerData {
                path: data.path.clone(),
                base_frame: data.base_frame,
                header_line: data.header_line,
                joints: data.joints,
                orientation: data.orientation,
                records: Vec::with_capacity(capacity),
                planned: data.planned,
                has_ids: data.has_ids,
                has_times: data.has_times,
                instrument: data.instrument.clone(),
            },
            readings: Vec::with_capacity(capacity),
        }
    }
}

/// The joint readings of the record `r` (rad).
fn joint_readings(r: &Record) -> JointVec<f64> {
    JointVec::<f64>::from_fn(r.q.len(), |j| r.q[j])
}

/// The core measurement of the record `r` of the data file `data` at the joint angles `angles`
/// (rad: its readings, or its kinematic angles); an error names the file and line.
fn measured_at(
    data: &Path,
    r: &Record,
    angles: &JointVec<f64>,
) -> crate::Result<Measurement<f64, Dyn>> {
    Measurement::new(angles, Vector3::from(r.position), r.rotation, r.weight)
        .with_context(|| format!("{}:{}", data.display(), r.line))
}

/// `true` at each of `indices` (those below `len`), `false` elsewhere: a mask, not
/// `indices.contains`, so that splits are linear in the poses.
pub(crate) fn mask(len: usize, indices: &[usize]) -> Vec<bool> {
    let mut chosen = vec![false; len];
    for &i in indices {
        if let Some(c) = chosen.get_mut(i) {
            *c = true;
        }
    }
    chosen
}

/// Splits `inputs` into calibration and validation poses: `fraction` of the poses, chosen at
/// random with `seed` (deterministic), are held out.
pub fn split(dataset: &Dataset, fraction: f64, seed: u64) -> crate::Result<(Dataset, Dataset)> {
    if !(fraction > 0.0 && fraction < 1.0) {
        return Err(crate::refused!(option "--validate";
            "--validate must be a fraction between 0 and 1, got {fraction}"
        ));
    }
    let n = dataset.readings.len();
    let held = ((n as f64) * fraction).round() as usize;
    if held == 0 || held >= n {
        return Err(crate::refused!(option "--validate";
            "--validate {fraction} of {n} poses leaves no pose on one side"
        ));
    }
    let order = shuffled(n, seed);
    let mut validation: Vec<usize> = order[..held].to_vec();
    validation.sort_unstable();
    Ok(dataset.partition(&validation))
}

/// `0..n` in a random order drawn with `seed` (Fisher-Yates; deterministic).
pub fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    for i in (1..n).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    order
}
