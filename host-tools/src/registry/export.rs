//! The registry written out for other tools: every record as JSON (the report as the JSON it
//! is) or a CSV of one line per calibration (`calib registry export`).

use super::record::Record;

/// Every record as one JSON array (pretty), each report parsed back into its JSON.
pub fn json(records: &[Record]) -> crate::Result<String> {
    let values: Vec<serde_json::Value> = (records.iter())
        .map(|r| {
            let mut value = serde_json::to_value(r)
                .map_err(|e| crate::numerical!("record {} as JSON: {e}", r.id))?;
            let report: serde_json::Value = serde_json::from_str(&r.calibration.report)
                .unwrap_or_else(|_| serde_json::Value::String(r.calibration.report.clone()));
            if let Some(object) = value.as_object_mut() {
                object.insert("report".to_string(), report);
            }
            Ok(value)
        })
        .collect::<crate::Result<_>>()?;
    let text = serde_json::to_string_pretty(&values)
        .map_err(|e| crate::numerical!("the registry as JSON: {e}"))?;
    Ok(format!("{text}\n"))
}

/// One CSV line per record: number, robot, kind, dates, the held-out figure (mm) and the
/// files' SHA-256.
pub fn csv(records: &[Record]) -> crate::Result<String> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let failed = |e: csv::Error| crate::numerical!("the registry as CSV: {e}");
    writer
        .write_record([
            "id",
            "serial",
            "model",
            "kind",
            "calibrated_at",
            "registered_at",
            "held_out_mm",
            "software",
            "report_sha256",
            "identified_sha256",
            "certificate_sha256",
            "block_sha256",
        ])
        .map_err(failed)?;
    for r in records {
        let c = &r.calibration;
        let optional = |v: &Option<String>| v.clone().unwrap_or_default();
        writer
            .write_record([
                r.id.to_string(),
                c.serial.clone(),
                c.model.clone(),
                c.kind.name().to_string(),
                c.calibrated_at.clone(),
                r.registered_at.clone(),
                c.held_out_mm.map_or(String::new(), |v| format!("{v}")),
                c.software.clone(),
                c.report_sha256.clone(),
                optional(&c.identified_sha256),
                optional(&c.certificate_sha256),
                optional(&c.block_sha256),
            ])
            .map_err(failed)?;
    }
    let bytes = writer
        .into_inner()
        .map_err(|e| crate::numerical!("the registry as CSV: {e}"))?;
    String::from_utf8(bytes).map_err(|e| crate::numerical!("the registry as CSV: {e}"))
}
