//! A dataset: a robot file and its measured poses, checked against each other and converted into
//! the core's units and types (mm, rad, [`Measurement`]), read from files or built in memory;
//! and the held-out split used for validation.

use crate::JOINTS;
use crate::error::Context;
use crate::io::profile::DataProfile;
use crate::io::robot_file::{RobotFile, RobotModel};
use crate::io::tracker_data::{Record, TrackerData};
use calib_core::identify::objective::Measurement;
use calib_core::model::JointVec;
use nalgebra::Dyn;
use nalgebra::Vector3;
use rand_core::{Rng, SeedableRng};
use std::path::Path;

/// A robot file, a data file and the measurements prepared for the core.
///
/// `N` is the robot's joint count (the robot file's; 6 unless said).
#[derive(Clone)]
pub struct Dataset {
    /// The robot file as read.
    pub file: RobotFile,
    /// The robot in core units, with its identification mask.
    pub model: RobotModel,
    /// The data file as read.
    pub data: TrackerData,
    /// One core measurement per data row.
    pub measurements: Vec<Measurement<f64, Dyn>>,
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
        let model: RobotModel = file.to_model(robot)?;
        let joints = model.robot.joints.len();
        if joints != JOINTS && file.compliance.is_some() {
            return Err(crate::refused!(
                "{}: gravity compliance is modelled for {JOINTS}-joint robots; this robot has {joints} joints: remove [compliance]",
                robot.display()
            ));
        }
        let data = data_file.path.clone();
        let data = data.as_path();
        if data_file.joints != joints {
            return Err(crate::refused!(
                "{}:{}: has {} joint columns, the robot {} has {joints} joints",
                data.display(),
                data_file.header_line,
                data_file.joints,
                model.name
            ));
        }
        if !data_file.records.is_empty() && data_file.records.iter().all(|r| r.weight == 0.0) {
            return Err(crate::refused!(
                "{}: every pose has weight 0, so no pose counts; give the poses to use a weight above 0",
                data.display()
            ));
        }
        let mut measurements = Vec::with_capacity(data_file.records.len());
        for r in &data_file.records {
            let q = JointVec::<f64>::from_fn(r.q.len(), |i| r.q[i]);
            for (i, (qi, limits)) in q.iter().zip(&model.robot.limits).enumerate() {
                if !limits.contains(*qi) {
                    return Err(crate::refused!(
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
            let m = Measurement::new(&q, Vector3::from(r.position), r.rotation, r.weight)
                .with_context(|| format!("{}:{}", data.display(), r.line))?;
            measurements.push(m);
        }
        let dataset = Self {
            file,
            model,
            data: data_file,
            measurements,
        };
        // Joint maps of the robot file are part of the model: the kinematics sees the readings
        // with each joint's angle error added.
        let actual = crate::kinematics::actual::ActualRobot::from_model(
            dataset.model.clone(),
            &dataset.file,
            robot,
        )?;
        match &actual.maps {
            Some(maps) => {
                dataset.warn_extrapolated(maps, robot);
                dataset.with_maps(maps)
            }
            None => Ok(dataset),
        }
    }

    /// The dataset with `maps` added to every joint reading: what the kinematics sees.
    pub fn with_maps(&self, maps: &crate::model::joint_maps::JointMaps) -> crate::Result<Self> {
        let mut out = self.clone();
        for (m, r) in out.measurements.iter_mut().zip(&self.data.records) {
            let q = JointVec::<f64>::from_fn(r.q.len(), |j| r.q[j]);
            *m = Measurement::new(
                &maps.apply(&q),
                Vector3::from(r.position),
                r.rotation,
                r.weight,
            )
            .with_context(|| format!("{}:{}", self.data.path.display(), r.line))?;
        }
        Ok(out)
    }

    /// The dataset, whose measurements already see the joint maps `maps` (if any), with the
    /// gravity compliance displacement of `gains` taken off every measured pose: what the geometry
    /// `robot + errors` (in the dataset's frames) alone must explain. The displacement is
    /// evaluated at the kinematic angles (the readings with the maps).
    pub(crate) fn without_compliance(
        &self,
        robot: &calib_core::Robot<f64, Dyn>,
        errors: &calib_core::ParameterErrors<f64, Dyn>,
        maps: Option<&crate::model::joint_maps::JointMaps>,
        gravity: &crate::model::compliance::Gravity,
        gains: &[f64; crate::model::compliance::GAIN_COUNT],
    ) -> crate::Result<Self> {
        let mut out = self.clone();
        for (m, r) in out.measurements.iter_mut().zip(&self.data.records) {
            let q = JointVec::<f64>::from_fn(r.q.len(), |j| r.q.get(j).copied().unwrap_or(0.0));
            let angles = maps.map_or(q, |maps| maps.apply(&q));
            let columns = crate::model::compliance::columns(gravity, robot, errors, &angles)?;
            let d = crate::model::compliance::displacement(&columns, gains);
            m.position -= Vector3::new(d[0], d[1], d[2]);
            if let Some(rotation) = m.rotation.as_mut() {
                *rotation =
                    nalgebra::Rotation3::new(-Vector3::new(d[3], d[4], d[5])).matrix() * *rotation;
            }
        }
        Ok(out)
    }

    /// The dataset with the gravity compliance of its robot file (if any; held fixed) taken off
    /// every measured pose, evaluated for the geometry `robot + errors` (the file's model in the
    /// data's frames): what that geometry alone must explain. Without `[compliance]` the dataset
    /// unchanged. Commands that fit or check the geometry of a file with compliance use it (the
    /// deflection depends on the geometry only to second order: a few tenths of a millimetre
    /// times its relative change).
    pub(crate) fn without_file_compliance(
        &self,
        robot: &calib_core::Robot<f64, Dyn>,
        errors: &calib_core::ParameterErrors<f64, Dyn>,
    ) -> crate::Result<Self> {
        let actual = crate::kinematics::actual::ActualRobot::from_model(
            self.model.clone(),
            &self.file,
            &self.model.path,
        )?;
        let Some(compliance) = &actual.compliance else {
            return Ok(self.clone());
        };
        self.without_compliance(
            robot,
            errors,
            actual.maps.as_ref(),
            &compliance.gravity,
            &compliance.gains,
        )
    }

    /// The data as the geometry sees them: each record's joint readings replaced by the kinematic
    /// angles of its measurement (the joint maps added, in (-pi, pi]), its pose by the measured
    /// pose the measurement holds (the compliance taken off, when it was). For the reference
    /// kinematics, which knows neither maps nor compliance.
    pub(crate) fn as_seen_by_the_geometry(&self) -> TrackerData {
        let mut data = self.data.clone();
        for (r, m) in data.records.iter_mut().zip(&self.measurements) {
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

    /// The dataset with its file in its measurement setup (`RobotFile::in_measurement_setup`:
    /// the identified probe or reflector as the tool), the identification mask kept.
    pub fn in_measurement_setup(&self) -> crate::Result<Self> {
        let mut kept = self.clone();
        kept.file = self.file.in_measurement_setup();
        let mask = kept.model.mask;
        kept.model = kept.file.to_model(&self.model.path)?;
        kept.model.mask = mask;
        Ok(kept)
    }

    /// The probe or reflector identified with the file's model (`[measurement] flange_tool`).
    pub(crate) fn identified_probe(&self) -> Option<&crate::io::robot_file::FrameEntry> {
        self.file
            .measurement
            .as_ref()
            .and_then(|m| m.flange_tool.as_ref())
    }

    /// Warns on standard error for every joint whose non-zero map (of the robot file at `robot`)
    /// is extrapolated: readings outside the range it was identified on.
    fn warn_extrapolated(&self, maps: &crate::model::joint_maps::JointMaps, robot: &Path) {
        let ranges = self
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
        let chosen = mask(self.measurements.len(), indices);
        let taken_count = chosen.iter().filter(|c| **c).count();
        let mut kept = self.empty_like(self.measurements.len() - taken_count);
        let mut taken = self.empty_like(taken_count);
        for ((record, m), taken_here) in
            self.data.records.iter().zip(&self.measurements).zip(chosen)
        {
            let side = if taken_here { &mut taken } else { &mut kept };
            side.data.records.push(record.clone());
            side.measurements.push(*m);
        }
        (kept, taken)
    }

    /// The same robot and file with no pose, room for `capacity` poses.
    fn empty_like(&self, capacity: usize) -> Self {
        let data = &self.data;
        Self {
            file: self.file.clone(),
            model: self.model.clone(),
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
            measurements: Vec::with_capacity(capacity),
        }
    }

    /// Number of residual rows: 6 per full pose, 3 per position-only pose.
    pub fn rows(&self) -> usize {
        self.measurements
            .iter()
            .map(|m| if m.rotation.is_some() { 6 } else { 3 })
            .sum()
    }
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
        return Err(crate::refused!(
            "--validate must be a fraction between 0 and 1, got {fraction}"
        ));
    }
    let n = dataset.measurements.len();
    let held = ((n as f64) * fraction).round() as usize;
    if held == 0 || held >= n {
        return Err(crate::refused!(
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
