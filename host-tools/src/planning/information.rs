//! The identification Jacobian of candidate joint configurations at the nominal model: the
//! parameters `calibrate` would identify on such data, one block of rows per pose, and the rows
//! with unit-RMS columns that the greedy design and the conditioning use.

use super::*;

/// The identification Jacobian of a set of joint configurations at the nominal model: the
/// parameters `calibrate` identifies on such data and one block of rows per pose.
pub(super) struct Information {
    /// The identified parameters.
    pub(super) parameters: Vec<Parameter>,
    /// Parameters of the robot's set that the configurations do not determine.
    pub(super) undetermined: Vec<Parameter>,
    /// Per pose: its rows (3 position rows in mm, then for `pose` 3 orientation rows in rad
    /// times `sqrt(k)`), per mm or rad of each parameter.
    pub(super) rows: Vec<DMatrix<f64>>,
}

/// The information of configurations `q` (rad) of the robot in `file` measured as `measure`:
/// the frames identified as `calibrate` does on tracker data (`base+tool`), the robot file's
/// identification set, less what the configurations cannot determine.
pub(super) fn information(
    file: &RobotFile,
    robot_path: &std::path::Path,
    q: &[Vec<f64>],
    measure: Measure,
    k: f64,
) -> crate::Result<Information> {
    let model = file.to_model(robot_path)?;
    let nominal = Kinematics::nominal(&model.robot)?;
    let mut records = Vec::with_capacity(q.len());
    for (i, q) in q.iter().enumerate() {
        let angles = JointVec::<f64>::from_fn(q.len(), |j| q.get(j).copied().unwrap_or(0.0));
        let pose = nominal
            .forward(&angles)
            .with_context(|| format!("candidate {}", i + 1))?;
        records.push(Record {
            line: i as u64 + 1,
            id: (i + 1).to_string(),
            q: q.clone(),
            position: pose.translation.vector.into(),
            rotation: (measure == Measure::Pose).then(|| *pose.rotation.matrix()),
            weight: 1.0,
            role: None,
            configuration: None,
            time_s: None,
            temperature_c: None,
        });
    }
    // In a tracker's frame (here the base frame itself), as the measured file will be.
    let dataset = Dataset::from_records(file.clone(), records, false)?;
    let frames = Frames::chosen(None, &dataset.data);
    let (robot, _, mask) = crate::measurement::frames::prepare(frames, &dataset.as_given()?, k)?;
    let dataset = dataset.seen_by(&robot)?;
    let (mut mask, _) = crate::analysis::identifiability::default_mask(&dataset, mask, k)?;
    let report = analyse(&dataset, &mask, k)?;
    let undetermined = report.to_drop();
    for p in &undetermined {
        mask.set(*p, false);
    }
    let parameters: Vec<Parameter> = mask.iter().collect();
    let kinematics = Kinematics::nominal(&robot.model.robot)?;
    let rows = dataset
        .measurements()
        .iter()
        .map(|m| pose_rows(&kinematics, &parameters, &m.angles, measure, k))
        .collect::<crate::Result<_>>()?;
    Ok(Information {
        parameters,
        undetermined,
        rows,
    })
}

/// The rows of one pose: the change of the measured position (mm) and, for `pose`, orientation
/// (rad, times `sqrt(k)`) per mm or rad of each parameter, one parameter at a time.
pub(super) fn pose_rows(
    kinematics: &Kinematics<f64, Dyn>,
    parameters: &[Parameter],
    angles: &JointAngles<f64, Dyn>,
    measure: Measure,
    k: f64,
) -> crate::Result<DMatrix<f64>> {
    let rows = measure.rows();
    let mut out = DMatrix::zeros(rows, parameters.len());
    for (j, p) in parameters.iter().enumerate() {
        let mut one = ParameterMask::empty_for(kinematics.joint_count());
        one.set(*p, true);
        let set = ParameterSet::<Dyn, nalgebra::U1>::from_mask(&one)?;
        let (_, twist) = kinematics.parameter_jacobian(&set, angles);
        for i in 0..rows {
            let scale = if i < 3 { 1.0 } else { k.sqrt() };
            out[(i, j)] = twist[(i, 0)] * scale;
        }
    }
    Ok(out)
}

/// The columns' scales (RMS over the `count` candidates) and every candidate's rows with its
/// columns scaled to unit RMS: units and lever arms drop out of the greedy step's
/// regularisation and of the conditioning. Error: a parameter no candidate moves.
pub(super) fn unit_scaled(
    info: &Information,
    count: usize,
) -> crate::Result<(Vec<f64>, Vec<DMatrix<f64>>)> {
    let scale: Vec<f64> = (0..info.parameters.len())
        .map(|j| {
            let sum: f64 = info.rows.iter().map(|r| r.column(j).norm_squared()).sum();
            (sum / count as f64).sqrt()
        })
        .collect();
    if let Some(j) = scale
        .iter()
        .position(|s| s.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
    {
        return Err(
            crate::refused!(undetermined vec![info.parameters[j].to_string()];
                "{} changes no measurement at any candidate; leave it out of the robot file's identify list",
                info.parameters[j]
            ),
        );
    }
    let scaled = info
        .rows
        .iter()
        .map(|r| {
            let mut s = r.clone();
            for (j, mut c) in s.column_iter_mut().enumerate() {
                c /= scale[j];
            }
            s
        })
        .collect();
    Ok((scale, scaled))
}
