//! A tracker's export merged into the plan it measured (`calib merge`): each measured point is
//! given its planned pose's id, role and joints, so that `calibrate` takes the result directly,
//! with the plan's verification poses held out and its prediction kept.
//!
//! A tracker exports points, not joints: the merge pairs them with the plan's poses by the `id`
//! the export names them with ([`MatchBy::Id`]) or by their order ([`MatchBy::Order`]; the robot
//! program of `calib plan --urscript` moves through the plan in its order), or by the time each
//! was measured ([`MatchBy::Time`]): the robot's log says when the robot stood at each planned
//! pose, and the point measured nearest that time (within a tolerance) is its measurement, so that
//! a tracker measuring continuously, points taken while the robot moved, or an export sorted by
//! name, pair correctly. When the export (or the log) has joint columns, every pair's joints must
//! agree with the plan's; a mismatch names the row, so that a skipped or repeated point cannot
//! shift the data silently.

use crate::io::tracker_data::{PoseRow, Record, Role, TrackerData};

/// How measured points are paired with the plan's poses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MatchBy {
    /// The export's `id` column names the planned pose (as the plan's `id` column).
    Id,
    /// The export's rows are the plan's poses in the plan's order, one each.
    Order,
    /// The export's `time_s` column against a robot log's: each planned pose's point is the one
    /// measured nearest the time the log says the robot stood at it.
    Time,
}

/// The robot's log for a merge by time: when the robot stood at each planned pose.
pub struct RobotLog<'a> {
    /// The log as read: a time column, and an `id` column naming the planned poses (else its rows
    /// are the plan's poses in order); joint columns, when present, are checked against the plan.
    pub log: &'a TrackerData,
    /// Largest time between a logged pose and its measured point, s.
    pub tolerance_s: f64,
}

/// The measured plan: one row per planned pose, the plan's id, role and joints with the
/// measured position (and orientation), and the plan's prediction line among `comments`.
pub struct Merged {
    /// The rows, in the plan's order.
    pub rows: Vec<PoseRow>,
    /// Each row's role.
    pub roles: Vec<Role>,
    /// Comment lines for the written file (without `#`).
    pub comments: Vec<String>,
}

impl Merged {
    /// The merged data as tracker CSV text (with the `role` column).
    pub fn csv(&self) -> crate::Result<String> {
        crate::io::tracker_data::tracker_csv_with_roles(
            &self.comments,
            &self.rows,
            Some(&self.roles),
        )
    }
}

/// Merges `measured` into `plan` (both as read: the plan's joints, the export's points),
/// pairing them `by` id or order; joints in the export must agree with the plan's within
/// `tolerance_rad`. Refused, naming the row, when a planned pose has no point or several, a point
/// names no planned pose, or joints disagree.
pub fn merge(
    plan: &TrackerData,
    measured: &TrackerData,
    by: MatchBy,
    tolerance_rad: f64,
    log: Option<&RobotLog<'_>>,
) -> crate::Result<Merged> {
    let pairs = match (by, log) {
        (MatchBy::Time, Some(log)) => pairs_by_time(plan, measured, log, tolerance_rad)?,
        (MatchBy::Time, None) => {
            return Err(crate::refused!(option "--robot-log";
                "merging by time needs the robot's log of when it stood at each planned pose (--robot-log)"
            ));
        }
        (_, Some(_)) => {
            return Err(crate::refused!(option "--robot-log";
                "a robot log pairs points by time; merge --by time, or leave the log out"
            ));
        }
        (_, None) => pairs(plan, measured, by)?,
    };
    let mut rows = Vec::with_capacity(pairs.len());
    let mut roles = Vec::with_capacity(pairs.len());
    for (planned, point) in pairs {
        check_joints(planned, point, measured, tolerance_rad)?;
        rows.push(PoseRow {
            id: planned.id.clone(),
            q: planned.q.clone(),
            position: point.position,
            rotation: point.rotation,
        });
        roles.push(planned.role.unwrap_or(Role::Fill));
    }
    if rows.iter().any(|r| r.rotation.is_some()) != rows.iter().all(|r| r.rotation.is_some()) {
        return Err(crate::refused!(input measured.path.display();
            "{}: some points have an orientation and some do not",
            measured.path.display()
        ));
    }
    let mut comments = vec![format!(
        "measured plan: {} merged with the points of {} by {}",
        plan.path.display(),
        measured.path.display(),
        match by {
            MatchBy::Id => "id",
            MatchBy::Order => "order",
            MatchBy::Time => "time",
        }
    )];
    let unused = measured.records.len() - rows.len();
    if unused > 0 {
        comments.push(format!(
            "{unused} points of the export were measured at no logged pose (while the robot moved) and are left out"
        ));
    }
    if let Some(planned) = &plan.planned {
        comments.push(planned.comment());
    }
    if measured.base_frame {
        comments.push("frame: base".to_string());
    }
    Ok(Merged {
        rows,
        roles,
        comments,
    })
}

/// Each planned pose with the point measured nearest the time the log says the robot stood at
/// it; the log's joints (when it has them) are checked against the plan's.
fn pairs_by_time<'a>(
    plan: &'a TrackerData,
    measured: &'a TrackerData,
    log: &RobotLog<'_>,
    tolerance_rad: f64,
) -> crate::Result<Vec<(&'a Record, &'a Record)>> {
    let (log_path, data_path) = (log.log.path.display(), measured.path.display());
    for (file, path) in [(log.log, &log_path), (measured, &data_path)] {
        if !file.has_times {
            return Err(crate::refused!(input path;
                "{path} has no time column (time_s or time_ms); merge by time needs one in the export and in the log \
                 (map the tracker's timestamp to time_s in a data profile)"
            ));
        }
    }
    let by = if log.log.has_ids {
        MatchBy::Id
    } else {
        MatchBy::Order
    };
    let logged = pairs(plan, log.log, by)?;
    // Both files have a time column (checked above): every record has its time.
    let time = |r: &Record| r.time_s.unwrap_or(0.0);
    let mut by_time: Vec<(f64, &Record)> = measured.records.iter().map(|r| (time(r), r)).collect();
    by_time.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut claimed = std::collections::HashMap::new();
    let mut out = Vec::with_capacity(logged.len());
    for (planned, entry) in logged {
        check_joints(planned, entry, log.log, tolerance_rad)?;
        let t = time(entry);
        let after = by_time.partition_point(|(s, _)| *s < t);
        // The nearest point in time and how far it is, s.
        let nearest = [after.checked_sub(1), Some(after)]
            .into_iter()
            .flatten()
            .filter_map(|i| by_time.get(i))
            .map(|(s, p)| ((s - t).abs(), *p))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let point = nearest
            .filter(|(away, _)| *away <= log.tolerance_s)
            .map(|(_, p)| p)
            .ok_or_else(|| {
                crate::refused!(input log_path;
                    "{log_path}:{}: the robot stood at the planned pose {} at {t} s, but {data_path} has no point within \
                     --time-tolerance-s {} of it{}: was the pose measured, and do both clocks count from the same epoch?",
                    entry.line,
                    planned.id,
                    log.tolerance_s,
                    nearest.map_or_else(String::new, |(away, p)| format!(
                        " (the nearest, line {}, is {away:.3} s away)",
                        p.line
                    ))
                )
            })?;
        if let Some(other) = claimed.insert(point.line, (entry.line, &planned.id)) {
            return Err(crate::refused!(input data_path;
                "{data_path}:{}: the point is the nearest in time to two planned poses, {} (log line {}) and {} (log \
                 line {}); one of them was not measured: make --time-tolerance-s smaller than the time between poses",
                point.line,
                other.1,
                other.0,
                planned.id,
                entry.line
            ));
        }
        check_joints(planned, point, measured, tolerance_rad)?;
        out.push((planned, point));
    }
    Ok(out)
}

/// Refuses an export whose ids name the plan's poses (any of them does) and contradict the
/// order `--by order` pairs them in (a pose skipped, repeated or measured out of turn). Ids of
/// the tracker's own, none of them a planned id, say nothing of the order.
fn ids_agree_with_order(plan: &TrackerData, measured: &TrackerData) -> crate::Result<()> {
    if !(measured.has_ids && plan.has_ids) {
        return Ok(());
    }
    let planned_ids: std::collections::HashSet<&str> =
        plan.records.iter().map(|r| r.id.as_str()).collect();
    if !(measured.records.iter()).any(|p| planned_ids.contains(p.id.as_str())) {
        return Ok(());
    }
    let contradiction = (plan.records.iter().zip(&measured.records))
        .find(|(planned, point)| planned.id != point.id);
    match contradiction {
        Some((planned, point)) => Err(crate::refused!(input measured.path.display();
            "{}:{}: the point {} is the planned pose {}'s by order (line {} of {}): the export's ids \
             contradict its order (a pose skipped, repeated or measured out of turn); merge --by id",
            measured.path.display(),
            point.line,
            point.id,
            planned.id,
            planned.line,
            plan.path.display()
        )),
        None => Ok(()),
    }
}

/// Each planned pose with its measured point.
fn pairs<'a, 'b>(
    plan: &'a TrackerData,
    measured: &'b TrackerData,
    by: MatchBy,
) -> crate::Result<Vec<(&'a Record, &'b Record)>> {
    let (plan_path, data_path) = (plan.path.display(), measured.path.display());
    match by {
        MatchBy::Order => {
            if plan.records.len() != measured.records.len() {
                return Err(crate::refused!(input data_path;
                    "{data_path} has {} points and the plan {plan_path} {} poses: a pose was skipped or measured twice, \
                     so the order does not pair them; give the export an id column and merge --by id",
                    measured.records.len(),
                    plan.records.len()
                ));
            }
            ids_agree_with_order(plan, measured)?;
            Ok(plan.records.iter().zip(&measured.records).collect())
        }
        MatchBy::Id => {
            if !measured.has_ids {
                return Err(crate::refused!(input data_path;
                    "{data_path} has no id column naming the planned poses; merge --by order, or export the point names as id"
                ));
            }
            let mut by_id = std::collections::HashMap::new();
            for point in &measured.records {
                if let Some(other) = by_id.insert(point.id.as_str(), point) {
                    return Err(crate::refused!(input data_path;
                        "{data_path}:{}: id {} was measured before, on line {}; keep one of them",
                        point.line,
                        point.id,
                        other.line
                    ));
                }
            }
            let mut out = Vec::with_capacity(plan.records.len());
            for planned in &plan.records {
                let point = by_id.remove(planned.id.as_str()).ok_or_else(|| {
                    crate::refused!(input plan_path;
                        "{plan_path}:{}: the planned pose {} has no point in {data_path}; measure it, or delete its row from the plan",
                        planned.line,
                        planned.id
                    )
                })?;
                out.push((planned, point));
            }
            if let Some(point) = by_id.values().min_by_key(|p| p.line) {
                return Err(crate::refused!(input data_path;
                    "{data_path}:{}: the point {} names no pose of the plan {plan_path} ({} such points)",
                    point.line,
                    point.id,
                    by_id.len()
                ));
            }
            Ok(out)
        }
        MatchBy::Time => Err(crate::refused!(option "--robot-log";
            "merging by time needs the robot's log (--robot-log)"
        )),
    }
}

/// Refuses a pair whose export row has joints that differ from the plan's.
fn check_joints(
    planned: &Record,
    point: &Record,
    measured: &TrackerData,
    tolerance_rad: f64,
) -> crate::Result<()> {
    if point.q.is_empty() {
        return Ok(());
    }
    if point.q.len() != planned.q.len() {
        return Err(crate::refused!(input measured.path.display();
            "{}:{}: has {} joints, the plan {}",
            measured.path.display(),
            point.line,
            point.q.len(),
            planned.q.len()
        ));
    }
    let worst = planned
        .q
        .iter()
        .zip(&point.q)
        .enumerate()
        .map(|(j, (a, b))| (j, (a - b).abs()))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    if let Some((j, difference)) = worst.filter(|(_, d)| *d > tolerance_rad || d.is_nan()) {
        return Err(crate::refused!(input measured.path.display();
            "{}:{}: q{} = {:.4} deg, but the planned pose {} it is paired with has {:.4} deg ({:.4} deg apart, more \
             than --tolerance-deg {:.4}): the points are not in the plan's order, or the robot was elsewhere",
            measured.path.display(),
            point.line,
            j + 1,
            point.q[j].to_degrees(),
            planned.id,
            planned.q[j].to_degrees(),
            difference.to_degrees(),
            tolerance_rad.to_degrees()
        ));
    }
    Ok(())
}
