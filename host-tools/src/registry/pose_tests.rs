//! The ISO 9283 pose tests of the registry (schema 4): each evaluated test
//! ([`crate::pose_test::PoseTest`]) kept whole against the robot's serial, with its largest
//! `AP` and `RP` for listings; the same run against the same commanded poses is kept once.

use super::{Registry, database_error};
use crate::pose_test::PoseTest;
use rusqlite::{OptionalExtension as _, TransactionBehavior, params};
use serde::{Deserialize, Serialize};

/// A pose test as a listing shows it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseTestSummary {
    /// Its number.
    pub id: i64,
    /// The robot's serial.
    pub serial: String,
    /// When the run was measured (RFC 3339).
    pub tested_at: String,
    /// Cycles of the least measured point.
    pub cycles: i64,
    /// The largest `AP` of the points, mm.
    pub ap_max_mm: f64,
    /// The largest `RP` of the points, mm.
    pub rp_max_mm: f64,
}

impl PoseTestSummary {
    /// One line for people.
    pub fn line(&self) -> String {
        format!(
            "pose test {:>4}  {}  {}  {} cycles  AP max {:.4} mm  RP max {:.4} mm",
            self.id, self.serial, self.tested_at, self.cycles, self.ap_max_mm, self.rp_max_mm
        )
    }
}

impl Registry {
    /// Records the pose test `test` of robot `serial`, measured at `tested_at` (RFC 3339); its
    /// number. Refused: the same run and commanded poses already recorded (its number named).
    pub fn add_pose_test(
        &mut self,
        serial: &str,
        test: &PoseTest,
        tested_at: &str,
    ) -> crate::Result<i64> {
        let path = self.path.clone();
        let failed = |e: &rusqlite::Error| database_error(&path, "cannot record the pose test", e);
        let points = &test.characteristics.points;
        let cycles = points.iter().map(|p| p.cycles).min().unwrap_or(0) as i64;
        let ap_max = points.iter().map(|p| p.ap_mm).fold(0.0, f64::max);
        let rp_max = points.iter().map(|p| p.rp_mm).fold(0.0, f64::max);
        let result = serde_json::to_string(test)
            .map_err(|e| crate::numerical!("the pose test as JSON: {e}"))?;
        let transaction = (self.connection)
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|e| failed(&e))?;
        let existing: Option<i64> = transaction
            .query_row(
                "SELECT id FROM pose_test WHERE serial = ?1 AND data_sha256 = ?2 AND targets_sha256 = ?3",
                params![serial, test.data_sha256, test.targets_sha256],
                |row| row.get(0),
            )
            .optional()
            .map_err(|e| failed(&e))?;
        if let Some(id) = existing {
            return Err(crate::refused!(input test.data.as_str();
                "{}: this run (SHA-256 {}) against these commanded poses is already recorded for {serial} as pose test {id}; nothing recorded",
                test.data, test.data_sha256));
        }
        transaction
            .execute(
                "INSERT INTO pose_test (serial, tested_at, data_sha256, targets_sha256, cycles,
                     ap_max_mm, rp_max_mm, result)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                params![
                    serial,
                    tested_at,
                    test.data_sha256,
                    test.targets_sha256,
                    cycles,
                    ap_max,
                    rp_max,
                    result
                ],
            )
            .map_err(|e| failed(&e))?;
        let id = transaction.last_insert_rowid();
        transaction.commit().map_err(|e| failed(&e))?;
        Ok(id)
    }

    /// Robot `serial`'s pose tests, oldest first.
    pub fn pose_tests(&self, serial: &str) -> crate::Result<Vec<PoseTestSummary>> {
        self.pose_tests_of(Some(serial))
    }

    /// Every robot's pose tests, by robot, oldest first.
    pub fn all_pose_tests(&self) -> crate::Result<Vec<PoseTestSummary>> {
        self.pose_tests_of(None)
    }

    /// The pose tests of robot `serial`, or of every robot with `None`.
    fn pose_tests_of(&self, serial: Option<&str>) -> crate::Result<Vec<PoseTestSummary>> {
        let failed =
            |e: &rusqlite::Error| database_error(&self.path, "cannot list its pose tests", e);
        let mut statement = (self.connection)
            .prepare(
                "SELECT id, serial, tested_at, cycles, ap_max_mm, rp_max_mm
                 FROM pose_test WHERE ?1 IS NULL OR serial = ?1 ORDER BY serial, tested_at, id",
            )
            .map_err(|e| failed(&e))?;
        let rows = statement
            .query_map(params![serial], |row| {
                Ok(PoseTestSummary {
                    id: row.get(0)?,
                    serial: row.get(1)?,
                    tested_at: row.get(2)?,
                    cycles: row.get(3)?,
                    ap_max_mm: row.get(4)?,
                    rp_max_mm: row.get(5)?,
                })
            })
            .map_err(|e| failed(&e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| failed(&e))
    }

    /// Robot `serial`'s pose test `id` whole. Refused: no pose test `id` of that robot.
    pub fn robot_pose_test(&self, serial: &str, id: i64) -> crate::Result<PoseTest> {
        let of_robot = self.pose_tests(serial)?.iter().any(|t| t.id == id);
        let test = match of_robot {
            true => self.pose_test(id)?,
            false => None,
        };
        test.ok_or_else(
            || crate::refused!(option "--id"; "--id {id}: no pose test {id} of robot {serial}"),
        )
    }

    /// Pose test `id`, whole; `None` when there is none of that number.
    pub fn pose_test(&self, id: i64) -> crate::Result<Option<PoseTest>> {
        let failed =
            |e: &rusqlite::Error| database_error(&self.path, "cannot read the pose test", e);
        let text: Option<String> = (self.connection)
            .query_row(
                "SELECT result FROM pose_test WHERE id = ?1",
                params![id],
                |row| row.get(0),
            )
            .optional()
            .map_err(|e| failed(&e))?;
        text.map(|t| {
            serde_json::from_str(&t).map_err(|e| {
                crate::refused!(input self.path.display();
                    "{}: pose test {id} is damaged ({e}); nothing was read", self.path.display())
            })
        })
        .transpose()
    }
}

/// The time a run was measured: `given` (RFC 3339, checked; `--tested-at`) or now.
pub fn tested_at(given: Option<&str>) -> crate::Result<String> {
    super::time_or_now(given, "--tested-at")
}

/// The serial a pose test is recorded under: `given`, else the robot file's. Refused: neither.
pub fn serial_of<'a>(given: Option<&'a str>, test: &'a PoseTest) -> crate::Result<&'a str> {
    given.or(test.serial.as_deref()).ok_or_else(|| {
        crate::refused!(option "--serial";
            "the robot's serial is not stated: give --serial, or serial = \"...\" in the robot file")
    })
}
