//! The registry (issue 55): every calibration of every robot in one SQLite file (`calib.db` by
//! default), so that "which calibration is on this controller, and is the robot still within
//! it?" has an answer that lasts.
//!
//! One record per calibration ([`record`]), keyed by the robot's serial and model: the
//! identified model as the robot file writes it, the covariance, the held-out figures, the
//! inputs' and the certificate's and the controller block's SHA-256, dates and software. The
//! database is SQLite (bundled: nothing to install), because a record must never be lost or half
//! written: each registration is one transaction (`BEGIN IMMEDIATE`, so two writers queue
//! instead of failing; a writer waits up to [`BUSY_TIMEOUT`]), and SQLite's journal makes a
//! process killed in the middle leave the previous state. The file is created readable and
//! writable by its owner only (0600).
//!
//! The schema is versioned (`PRAGMA user_version`, [`SCHEMA_VERSION`]) and the file marked as
//! ours (`PRAGMA application_id`, [`APPLICATION_ID`]): a file of a newer schema is refused with
//! its version named, an SQLite file of another program or a file that is not a database at all
//! is refused, never altered; an older schema is migrated forward in one transaction.

pub mod compare;
pub mod export;
pub mod fleet;
pub mod pose_tests;
pub mod record;
pub mod shift;
pub mod trend;
pub mod verify;

use record::{Kind, NewRecord, Record, Summary};
use rusqlite::{Connection, OpenFlags, OptionalExtension as _, TransactionBehavior, params};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The schema this version writes and reads.
pub const SCHEMA_VERSION: i64 = 4;

/// `PRAGMA application_id` of a registry: "CALB".
pub const APPLICATION_ID: i64 = 0x4341_4C42;

/// The registry's file when `--db` is not given.
pub const DEFAULT_PATH: &str = "calib.db";

/// How long a writer waits for another to finish.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(30);

/// The migrations: entry `n` takes schema `n` to `n + 1` (a new file runs them all).
///
/// Version 1 kept each record in one row, the whole report in it. Version 2 keeps the short
/// fields listings read in `calibration` and the long ones (held-out figures, covariance,
/// inputs, identified file, report) in `calibration_content`, so that listing 100,000
/// calibrations reads a few megabytes instead of every record's first page; and it keeps the
/// report without its per-pose lists ([`record::NOT_KEPT`]). Version 3 adds the shift checks
/// ([`shift`]), each against the calibration it checked. Version 4 adds the ISO 9283 pose tests
/// ([`pose_tests`]).
const MIGRATIONS: [&str; 4] = [
    "CREATE TABLE calibration (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    serial TEXT NOT NULL,
    model TEXT NOT NULL,
    kind TEXT NOT NULL CHECK (kind IN ('tracker', 'touches')),
    calibrated_at TEXT NOT NULL,
    registered_at TEXT NOT NULL,
    software TEXT NOT NULL,
    held_out_mm REAL,
    held_out TEXT NOT NULL,
    covariance TEXT NOT NULL,
    inputs TEXT NOT NULL,
    identified_toml TEXT,
    identified_sha256 TEXT,
    certificate_sha256 TEXT,
    block_sha256 TEXT,
    report TEXT NOT NULL,
    report_sha256 TEXT NOT NULL,
    UNIQUE (serial, report_sha256)
);
CREATE INDEX calibration_by_robot ON calibration (serial, calibrated_at, id);",
    "ALTER TABLE calibration RENAME TO calibration_v1;
DROP INDEX calibration_by_robot;
CREATE TABLE calibration (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    serial TEXT NOT NULL,
    model TEXT NOT NULL,
    kind TEXT NOT NULL CHECK (kind IN ('tracker', 'touches')),
    calibrated_at TEXT NOT NULL,
    registered_at TEXT NOT NULL,
    software TEXT NOT NULL,
    held_out_mm REAL,
    identified_sha256 TEXT,
    certificate_sha256 TEXT,
    block_sha256 TEXT,
    report_sha256 TEXT NOT NULL,
    UNIQUE (serial, report_sha256)
);
CREATE TABLE calibration_content (
    id INTEGER PRIMARY KEY REFERENCES calibration (id),
    held_out TEXT NOT NULL,
    covariance TEXT NOT NULL,
    inputs TEXT NOT NULL,
    identified_toml TEXT,
    report TEXT NOT NULL
);
INSERT INTO calibration SELECT id, serial, model, kind, calibrated_at, registered_at, software,
    held_out_mm, identified_sha256, certificate_sha256, block_sha256, report_sha256
    FROM calibration_v1;
INSERT INTO calibration_content SELECT id, held_out, covariance, inputs, identified_toml,
    json_remove(report, '$.per_pose', '$.poses', '$.convergence') FROM calibration_v1;
DROP TABLE calibration_v1;
CREATE INDEX calibration_by_robot ON calibration (serial, calibrated_at, id);",
    "CREATE TABLE shift_check (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    calibration_id INTEGER NOT NULL REFERENCES calibration (id),
    serial TEXT NOT NULL,
    checked_at TEXT NOT NULL,
    data_sha256 TEXT NOT NULL,
    settings TEXT NOT NULL,
    poses INTEGER NOT NULL,
    mean_mm REAL NOT NULL,
    max_mm REAL NOT NULL,
    drifted INTEGER NOT NULL CHECK (drifted IN (0, 1)),
    cause TEXT,
    result TEXT NOT NULL,
    UNIQUE (calibration_id, data_sha256, settings)
);
CREATE INDEX shift_check_by_robot ON shift_check (serial, checked_at, id);",
    "CREATE TABLE pose_test (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    serial TEXT NOT NULL,
    tested_at TEXT NOT NULL,
    data_sha256 TEXT NOT NULL,
    targets_sha256 TEXT NOT NULL,
    cycles INTEGER NOT NULL,
    ap_max_mm REAL NOT NULL,
    rp_max_mm REAL NOT NULL,
    result TEXT NOT NULL,
    UNIQUE (serial, data_sha256, targets_sha256)
);
CREATE INDEX pose_test_by_robot ON pose_test (serial, tested_at, id);",
];

/// What a command does with the registry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Lists, shows, exports: the file must exist and is opened read-only.
    Read,
    /// Registers: the file is created (0600) when it does not exist, and migrated.
    Write,
}

/// An open registry.
#[derive(Debug)]
pub struct Registry {
    connection: Connection,
    path: PathBuf,
}

impl Registry {
    /// Opens the registry at `path` for `access`. Refused, naming the file: a file that is not
    /// an SQLite database, an SQLite database of another program, a newer schema, a missing
    /// file for reading, a file or folder the user cannot write for writing.
    pub fn open(path: &Path, access: Access) -> crate::Result<Self> {
        let exists = path.exists();
        if access == Access::Read && !exists {
            return Err(crate::refused!(input path.display();
                "{}: no registry there; register a calibration first (calib registry add REPORT.json --db {})", path.display(), path.display()));
        }
        if access == Access::Write && !exists {
            create_private(path)?;
        }
        let read_only = std::fs::metadata(path).is_ok_and(|m| m.permissions().readonly());
        if access == Access::Write && read_only {
            return Err(crate::refused!(output path;
                "{}: the registry is read-only (its mode has no write bit): make it writable (chmod u+w) or name another with --db; nothing was written", path.display()));
        }
        let mut registry = Self::connect(path, access)?;
        if access == Access::Read && registry.interrupted_write() {
            if read_only {
                return Err(crate::refused!(input path.display();
                    "{}: a write was interrupted (a crash, a full disk) and left its journal beside it, which only a writable file can roll back: make it writable (chmod u+w) and read it again; the records before that write are intact", path.display()));
            }
            // Opened for writing, SQLite rolls the interrupted write back as it reads.
            registry = Self::connect(path, Access::Write)?;
        }
        registry.check_and_migrate(access)?;
        Ok(registry)
    }

    /// The connection to `path` for `access` (read-only for reading), waiting up to
    /// [`BUSY_TIMEOUT`] for another process's write.
    fn connect(path: &Path, access: Access) -> crate::Result<Self> {
        let flags = match access {
            Access::Read => OpenFlags::SQLITE_OPEN_READ_ONLY,
            Access::Write => OpenFlags::SQLITE_OPEN_READ_WRITE,
        } | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let connection = Connection::open_with_flags(path, flags)
            .map_err(|e| database_error(path, "cannot open it", &e))?;
        connection
            .busy_timeout(BUSY_TIMEOUT)
            .map_err(|e| database_error(path, "cannot open it", &e))?;
        Ok(Self {
            connection,
            path: path.to_owned(),
        })
    }

    /// Whether a read-only connection finds the journal of an interrupted write (a process
    /// killed or a disk full while it wrote) that must be rolled back before anything is read.
    fn interrupted_write(&self) -> bool {
        let read = (self.connection).query_row("SELECT count(*) FROM sqlite_master", [], |row| {
            row.get::<_, i64>(0)
        });
        matches!(read, Err(rusqlite::Error::SqliteFailure(e, _))
            if e.extended_code == rusqlite::ffi::SQLITE_READONLY_ROLLBACK)
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Refuses a foreign or newer file; migrates an older or new one (writing only).
    fn check_and_migrate(&mut self, access: Access) -> crate::Result<()> {
        let (application, version, tables) = self.header()?;
        let path = self.path.display();
        if application != APPLICATION_ID && (application != 0 || tables > 0) {
            return Err(crate::refused!(input path;
                "{path}: an SQLite database of another program ({tables} tables, application id {application:#x}; a registry's is {APPLICATION_ID:#x}), not a calib registry; name a registry file or a new path with --db"));
        }
        if version > SCHEMA_VERSION {
            return Err(crate::refused!(input path;
                "{path}: a registry of schema version {version}, written by a newer calib; this calib reads versions up to {SCHEMA_VERSION}: use the newer calib"));
        }
        if version == SCHEMA_VERSION {
            return Ok(());
        }
        if access == Access::Read {
            return Err(crate::refused!(input path;
                "{path}: a registry of schema version {version}; register a calibration with this calib (calib registry add) to bring it to version {SCHEMA_VERSION}"));
        }
        let transaction = (self.connection)
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|e| database_error(&self.path, "cannot start migrating it", &e))?;
        // Another process may have migrated it meanwhile: read the version again, inside.
        let version: i64 = transaction
            .pragma_query_value(None, "user_version", |row| row.get(0))
            .map_err(|e| database_error(&self.path, "cannot read its schema version", &e))?;
        for migration in MIGRATIONS
            .iter()
            .skip(usize::try_from(version).unwrap_or(0))
        {
            transaction
                .execute_batch(migration)
                .map_err(|e| database_error(&self.path, "cannot migrate it", &e))?;
        }
        transaction
            .execute_batch(&format!(
                "PRAGMA application_id = {APPLICATION_ID}; PRAGMA user_version = {SCHEMA_VERSION};"
            ))
            .map_err(|e| database_error(&self.path, "cannot mark its schema", &e))?;
        transaction
            .commit()
            .map_err(|e| database_error(&self.path, "cannot migrate it", &e))
    }

    /// `(application id, schema version, tables)` of the file, read in one statement (one read
    /// transaction: another process's migration is seen whole or not at all).
    fn header(&self) -> crate::Result<(i64, i64, i64)> {
        (self.connection)
            .query_row(
                "SELECT (SELECT application_id FROM pragma_application_id),
                        (SELECT user_version FROM pragma_user_version),
                        (SELECT count(*) FROM sqlite_master)",
                [],
                |row| Ok((row.get(0)?, row.get(1)?, row.get(2)?)),
            )
            .map_err(|e| database_error(&self.path, "cannot read it", &e))
    }

    /// Registers `record`; its number. Refused: the same report already registered for this
    /// serial (its number named), a write the file or the disk refuses.
    pub fn add(&mut self, record: &NewRecord) -> crate::Result<i64> {
        Ok(self.add_all(std::slice::from_ref(record))?[0])
    }

    /// Registers `records` in one transaction (all or none); their numbers. Refused as
    /// [`Registry::add`] for any of them.
    pub fn add_all(&mut self, records: &[NewRecord]) -> crate::Result<Vec<i64>> {
        let now = humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string();
        let path = self.path.clone();
        let failed =
            |e: &rusqlite::Error| database_error(&path, "cannot register the calibration", e);
        let transaction = (self.connection)
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|e| failed(&e))?;
        let ids = (records.iter())
            .map(|record| insert(&transaction, record, &now, &path))
            .collect::<crate::Result<Vec<i64>>>()?;
        transaction.commit().map_err(|e| failed(&e))?;
        Ok(ids)
    }

    /// Every record's summary (of robot `serial` only, when given), by serial, then date, then
    /// number.
    pub fn list(&self, serial: Option<&str>) -> crate::Result<Vec<Summary>> {
        let failed = |e: &rusqlite::Error| database_error(&self.path, "cannot list it", e);
        let mut statement = (self.connection)
            .prepare(
                "SELECT id, serial, model, kind, calibrated_at, held_out_mm, software FROM calibration
                 WHERE ?1 IS NULL OR serial = ?1 ORDER BY serial, calibrated_at, id",
            )
            .map_err(|e| failed(&e))?;
        let rows = statement
            .query_map(params![serial], |row| {
                Ok(Summary {
                    id: row.get(0)?,
                    serial: row.get(1)?,
                    model: row.get(2)?,
                    kind: kind_of(row.get_ref(3)?.as_str()?),
                    calibrated_at: row.get(4)?,
                    held_out_mm: row.get(5)?,
                    software: row.get(6)?,
                })
            })
            .map_err(|e| failed(&e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| failed(&e))
    }

    /// The record `id`, whole. Refused: no such record.
    pub fn show(&self, id: i64) -> crate::Result<Record> {
        let failed = |e: &rusqlite::Error| database_error(&self.path, "cannot read a record", e);
        let record = (self.connection)
            .query_row(
                &format!("{RECORD_QUERY} WHERE c.id = ?1"),
                params![id],
                record_of_row,
            )
            .optional()
            .map_err(|e| failed(&e))?;
        record.ok_or_else(|| {
            crate::refused!(option "ID";
                "{}: no record {id}; calib registry list --db {} lists them", self.path.display(), self.path.display())
        })
    }

    /// Every record of robot `serial`, whole, in the order of [`Registry::list`] (oldest
    /// first).
    pub fn robot(&self, serial: &str) -> crate::Result<Vec<Record>> {
        let failed = |e: &rusqlite::Error| database_error(&self.path, "cannot read a record", e);
        let mut statement = (self.connection)
            .prepare(&format!(
                "{RECORD_QUERY} WHERE c.serial = ?1 ORDER BY c.calibrated_at, c.id"
            ))
            .map_err(|e| failed(&e))?;
        let rows = statement
            .query_map(params![serial], record_of_row)
            .map_err(|e| failed(&e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| failed(&e))
    }

    /// Records the shift check `check`, measured at `checked_at` (RFC 3339); its number.
    /// Refused: the same data already checked against the same calibration (its number named).
    pub fn add_check(&mut self, check: &shift::ShiftCheck, checked_at: &str) -> crate::Result<i64> {
        let path = self.path.clone();
        let failed =
            |e: &rusqlite::Error| database_error(&path, "cannot record the shift check", e);
        let settings = serde_json::to_string(&check.settings)
            .map_err(|e| crate::numerical!("the shift check's settings as JSON: {e}"))?;
        let transaction = (self.connection)
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|e| failed(&e))?;
        let existing: Option<i64> = transaction
            .query_row(
                "SELECT id FROM shift_check
                 WHERE calibration_id = ?1 AND data_sha256 = ?2 AND settings = ?3",
                params![check.calibration, check.data_sha256, settings],
                |row| row.get(0),
            )
            .optional()
            .map_err(|e| failed(&e))?;
        if let Some(id) = existing {
            return Err(crate::refused!(input check.data.as_str();
                "{}: these data (SHA-256 {}) were already checked against record {} with these settings as shift check {id}; nothing recorded",
                check.data, check.data_sha256, check.calibration));
        }
        let result = serde_json::to_string(check)
            .map_err(|e| crate::numerical!("the shift check as JSON: {e}"))?;
        transaction
            .execute(
                "INSERT INTO shift_check (calibration_id, serial, checked_at, data_sha256, settings,
                     poses, mean_mm, max_mm, drifted, cause, result)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                params![
                    check.calibration,
                    check.serial,
                    checked_at,
                    check.data_sha256,
                    settings,
                    check.poses.len() as i64,
                    check.mean_mm,
                    check.max_mm,
                    check.drifted,
                    check.cause.as_ref().map(|c| c.name.clone()),
                    result,
                ],
            )
            .map_err(|e| failed(&e))?;
        let id = transaction.last_insert_rowid();
        transaction.commit().map_err(|e| failed(&e))?;
        Ok(id)
    }

    /// Robot `serial`'s shift checks, oldest first.
    pub fn checks(&self, serial: &str) -> crate::Result<Vec<shift::CheckSummary>> {
        self.checks_of(Some(serial))
    }

    /// Every robot's shift checks, by robot, oldest first.
    pub fn all_checks(&self) -> crate::Result<Vec<shift::CheckSummary>> {
        self.checks_of(None)
    }

    /// The shift checks of robot `serial`, or of every robot with `None`.
    fn checks_of(&self, serial: Option<&str>) -> crate::Result<Vec<shift::CheckSummary>> {
        let failed =
            |e: &rusqlite::Error| database_error(&self.path, "cannot list its shift checks", e);
        let mut statement = (self.connection)
            .prepare(
                "SELECT id, calibration_id, serial, checked_at, poses, mean_mm, max_mm, drifted, cause
                 FROM shift_check WHERE ?1 IS NULL OR serial = ?1 ORDER BY serial, checked_at, id",
            )
            .map_err(|e| failed(&e))?;
        let rows = statement
            .query_map(params![serial], |row| {
                Ok(shift::CheckSummary {
                    id: row.get(0)?,
                    calibration: row.get(1)?,
                    serial: row.get(2)?,
                    checked_at: row.get(3)?,
                    poses: row.get(4)?,
                    mean_mm: row.get(5)?,
                    max_mm: row.get(6)?,
                    drifted: row.get(7)?,
                    cause: row.get(8)?,
                })
            })
            .map_err(|e| failed(&e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| failed(&e))
    }

    /// Every record, whole, in the order of [`Registry::list`].
    pub fn all(&self) -> crate::Result<Vec<Record>> {
        let failed = |e: &rusqlite::Error| database_error(&self.path, "cannot read a record", e);
        let mut statement = (self.connection)
            .prepare(&format!(
                "{RECORD_QUERY} ORDER BY c.serial, c.calibrated_at, c.id"
            ))
            .map_err(|e| failed(&e))?;
        let rows = statement
            .query_map([], record_of_row)
            .map_err(|e| failed(&e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| failed(&e))
    }
}

/// The query of whole records, in the column order [`record_of_row`] reads.
const RECORD_QUERY: &str =
    "SELECT c.id, c.registered_at, c.serial, c.model, c.kind, c.calibrated_at,
        c.software, c.held_out_mm, t.held_out, t.covariance, t.inputs, t.identified_toml,
        c.identified_sha256, c.certificate_sha256, c.block_sha256, t.report, c.report_sha256
    FROM calibration AS c JOIN calibration_content AS t ON t.id = c.id";

/// Inserts `record`, registered at `now`, in `transaction`; its number.
fn insert(
    transaction: &rusqlite::Transaction<'_>,
    record: &NewRecord,
    now: &str,
    path: &Path,
) -> crate::Result<i64> {
    let failed = |e: &rusqlite::Error| database_error(path, "cannot register the calibration", e);
    let existing: Option<i64> = transaction
        .query_row(
            "SELECT id FROM calibration WHERE serial = ?1 AND report_sha256 = ?2",
            params![record.serial, record.report_sha256],
            |row| row.get(0),
        )
        .optional()
        .map_err(|e| failed(&e))?;
    if let Some(id) = existing {
        return Err(crate::refused!(input path.display();
            "{}: this report (SHA-256 {}) is already registered for robot {} as record {id}",
            path.display(), record.report_sha256, record.serial));
    }
    let json = |v: &serde_json::Value| v.to_string();
    transaction
        .prepare_cached(
            "INSERT INTO calibration (serial, model, kind, calibrated_at, registered_at, software,
                 held_out_mm, identified_sha256, certificate_sha256, block_sha256, report_sha256)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
        )
        .and_then(|mut statement| {
            statement.execute(params![
                record.serial,
                record.model,
                record.kind.name(),
                record.calibrated_at,
                now,
                record.software,
                record.held_out_mm,
                record.identified_sha256,
                record.certificate_sha256,
                record.block_sha256,
                record.report_sha256,
            ])
        })
        .map_err(|e| failed(&e))?;
    let id = transaction.last_insert_rowid();
    transaction
        .prepare_cached(
            "INSERT INTO calibration_content (id, held_out, covariance, inputs, identified_toml,
                 report)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        )
        .and_then(|mut statement| {
            statement.execute(params![
                id,
                json(&record.held_out),
                json(&record.covariance),
                json(&record.inputs),
                record.identified_toml,
                record.report,
            ])
        })
        .map_err(|e| failed(&e))?;
    Ok(id)
}

/// The kind stored in a row (the schema's CHECK admits only these two).
fn kind_of(name: &str) -> Kind {
    Kind::from_name(name).unwrap_or(Kind::Tracker)
}

/// A full record from a row of [`RECORD_QUERY`].
fn record_of_row(row: &rusqlite::Row<'_>) -> rusqlite::Result<Record> {
    let json = |i: usize| -> rusqlite::Result<serde_json::Value> {
        let text: String = row.get(i)?;
        serde_json::from_str(&text).map_err(|e| {
            rusqlite::Error::FromSqlConversionFailure(i, rusqlite::types::Type::Text, Box::new(e))
        })
    };
    Ok(Record {
        id: row.get(0)?,
        registered_at: row.get(1)?,
        calibration: NewRecord {
            serial: row.get(2)?,
            model: row.get(3)?,
            kind: kind_of(row.get_ref(4)?.as_str()?),
            calibrated_at: row.get(5)?,
            software: row.get(6)?,
            held_out_mm: row.get(7)?,
            held_out: json(8)?,
            covariance: json(9)?,
            inputs: json(10)?,
            identified_toml: row.get(11)?,
            identified_sha256: row.get(12)?,
            certificate_sha256: row.get(13)?,
            block_sha256: row.get(14)?,
            report: row.get(15)?,
            report_sha256: row.get(16)?,
        },
    })
}

/// When something was measured: `given` (RFC 3339, checked; named by `option` in the refusal)
/// or now, as RFC 3339 to the second.
fn time_or_now(given: Option<&str>, option: &'static str) -> crate::Result<String> {
    match given {
        Some(t) => {
            humantime::parse_rfc3339_weak(t).map_err(|e| {
                crate::refused!(option option;
                    "{option} {t}: {e}; give a time such as 2026-11-29T06:00:00Z")
            })?;
            Ok(t.to_string())
        }
        None => Ok(humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()),
    }
}

/// Creates an empty file at `path` readable and writable by its owner only (another process
/// creating it at the same moment is fine: the file then exists).
fn create_private(path: &Path) -> crate::Result<()> {
    use std::os::unix::fs::OpenOptionsExt as _;
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
    {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(crate::refused!(output path;
            "{}: cannot create the registry ({e}); choose a folder you can write with --db", path.display())),
    }
}

/// The message of a database error on `path` while `doing`, with what to do about it.
fn database_error(path: &Path, doing: &str, error: &rusqlite::Error) -> crate::Error {
    use rusqlite::ErrorCode;
    let shown = path.display();
    let code = error.sqlite_error_code();
    let advice = match code {
        Some(ErrorCode::NotADatabase) => {
            return crate::refused!(input shown;
                "{shown}: not a calib registry (not an SQLite database); name a registry file or a new path with --db");
        }
        Some(ErrorCode::DatabaseCorrupt) => "the file is damaged: restore it from a backup",
        Some(ErrorCode::ReadOnly) | Some(ErrorCode::PermissionDenied) => {
            "the file (or its folder, where SQLite writes its journal) is read-only for you: make it writable or name another with --db"
        }
        Some(ErrorCode::DiskFull) => {
            "the disk is full: free space and register again (nothing was written)"
        }
        Some(ErrorCode::SystemIoFailure) => {
            "the disk refused a write (full, a file-size limit, or failing): free space or check the disk and try again; nothing was written, and what was begun is rolled back the next time the registry is opened"
        }
        Some(ErrorCode::DatabaseBusy) | Some(ErrorCode::DatabaseLocked) => {
            "another process held it too long: try again"
        }
        Some(ErrorCode::CannotOpen) => "check that the path and its folder exist and are yours",
        _ => "nothing was written",
    };
    crate::refused!(output path; "{shown}: {doing}: {error}; {advice}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A registry of schema 1 holding one record, as the calib of the ninth session wrote it,
    /// comes through the migration to schema 2 with every field, the report without its
    /// per-pose lists, and takes the next record under the next number.
    #[test]
    fn a_schema_1_registry_is_migrated_with_its_records() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.db");
        let report = r#"{"robot":"ur10.toml","per_pose":[1,2,3],"poses":[{"line":2}],"convergence":[0.5],"seconds":0.25}"#;
        {
            let connection = Connection::open(&path).unwrap();
            connection.execute_batch(MIGRATIONS[0]).unwrap();
            connection
                .execute_batch(&format!(
                    "PRAGMA application_id = {APPLICATION_ID}; PRAGMA user_version = 1;"
                ))
                .unwrap();
            connection
                .execute(
                    "INSERT INTO calibration VALUES (7, 'SN-1', 'UR10', 'tracker', '2026-11-01T10:00:00Z',
                     '2026-11-02T10:00:00Z', 'calib 0.4', 0.385, '{\"n\":1}', '[[1.0]]', '[]', 'name = \"x\"',
                     'aa', 'bb', 'cc', ?1, 'dd')",
                    params![report],
                )
                .unwrap();
        }
        let mut registry = Registry::open(&path, Access::Write).unwrap();
        let header = registry.header().unwrap();
        assert_eq!(
            header,
            (APPLICATION_ID, 4, 11),
            "four tables, sqlite_sequence, six indexes"
        );
        let record = registry.show(7).unwrap();
        let c = &record.calibration;
        assert_eq!(
            (c.serial.as_str(), c.model.as_str(), c.kind, c.held_out_mm),
            ("SN-1", "UR10", Kind::Tracker, Some(0.385))
        );
        assert_eq!(record.registered_at, "2026-11-02T10:00:00Z");
        assert_eq!(c.held_out, serde_json::json!({"n": 1}));
        assert_eq!(c.covariance, serde_json::json!([[1.0]]));
        assert_eq!(c.identified_toml.as_deref(), Some("name = \"x\""));
        let hashes = [&c.identified_sha256, &c.certificate_sha256, &c.block_sha256];
        assert_eq!(
            hashes.map(|h| h.as_deref()),
            [Some("aa"), Some("bb"), Some("cc")]
        );
        assert_eq!(c.report_sha256, "dd");
        let kept: serde_json::Value = serde_json::from_str(&c.report).unwrap();
        assert_eq!(
            kept,
            serde_json::json!({"robot": "ur10.toml", "seconds": 0.25})
        );
        let mut next = c.clone();
        next.report_sha256 = "ee".to_string();
        assert_eq!(registry.add(&next).unwrap(), 8);
        assert_eq!(registry.list(Some("SN-1")).unwrap().len(), 2);
        assert_eq!(registry.all().unwrap()[1].calibration.report_sha256, "ee");
    }
}
