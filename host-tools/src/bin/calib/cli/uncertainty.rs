//! `calib uncertainty`: the identified model's predicted uncertainty at joint configurations
//! ([`host_tools::analysis::uncertainty::at_poses`]): per pose the standard deviation of the position
//! (of the measured point) along the robot's base axes and of the orientation about them, from
//! the parameters' covariance the identified robot file records, and with the instrument a data
//! profile states (`[instrument]`) what a measurement of the pose would show; the worst poses and
//! the regions of the workspace of largest uncertainty named.

use host_tools::io::outputs::Outputs;
use host_tools::io::profile::DataProfile;
use host_tools::io::robot_file::RobotFile;
use host_tools::io::tracker_data::TrackerData;
use std::path::PathBuf;

/// Options of `calib uncertainty`.
#[derive(Clone, Debug, clap::Args)]
pub struct UncertaintyOptions {
    /// The identified robot file (calib calibrate --out, least squares on the geometry), whose
    /// `[calibration.covariance]` is propagated in its measurement setup (`[measurement]`).
    #[arg(long, value_name = "FILE")]
    pub params: PathBuf,
    /// The joint configurations (CSV with q1_deg..qN_deg or _rad, optional id; any measurement
    /// columns are ignored: a plan, a data file or a program's joint targets).
    #[arg(long, value_name = "FILE")]
    pub joints: PathBuf,
    /// Data profile of the configurations file; its `[instrument]` adds the measurement's noise
    /// (sd_instrument_mm, sd_measured_mm).
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Output CSV: per configuration its id, joints, and the standard deviations sd_x_mm, sd_y_mm,
    /// sd_z_mm, sd_mm (RMS of the position error), sd_rx_deg, sd_ry_deg, sd_rz_deg, then the
    /// nominal position x_mm, y_mm, z_mm in the robot's base frame; with an instrument in the data
    /// profile also sd_instrument_mm (its noise per coordinate at the pose's distance from the
    /// tracker) and sd_measured_mm (the RMS a measurement of the pose would show: model and
    /// instrument).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// What `calib uncertainty` found, for the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Configurations evaluated.
    pub poses: usize,
    /// Mean of the RMS position standard deviation, mm.
    pub mean_mm: f64,
    /// The largest, mm, with its configuration's id and file line.
    pub worst: Vec<(String, u64, f64)>,
    /// The regions of the workspace (terciles of the configurations' nominal positions in the
    /// robot's base frame, [`host_tools::analysis::workspace`]) of largest mean predicted uncertainty:
    /// their `mean_mm` and `max_mm` are the predicted RMS standard deviation, mm.
    pub worst_regions: Vec<host_tools::analysis::workspace::Region>,
}

/// How many of the worst configurations the summary names.
const WORST_NAMED: usize = 3;

/// The position (mm) of the robot file's nominal model at each of `q` (rad), in the robot's base
/// frame: where in the workspace each configuration puts the tool.
fn nominal_positions(
    file: &RobotFile,
    path: &std::path::Path,
    q: &[Vec<f64>],
) -> anyhow::Result<Vec<[f64; 3]>> {
    let model = file.to_model(path)?;
    let kinematics = calib_core::Kinematics::nominal(&model.robot)?;
    let base = host_tools::measurement::statistics::BaseFrame::of(&model.robot);
    q.iter()
        .map(|q| {
            let q = calib_core::model::JointVec::from_slice(q)
                .ok_or_else(|| anyhow::anyhow!("more than 9 joints"))?;
            Ok(base.point(&kinematics.forward(&q)?.translation.vector))
        })
        .collect()
}

/// The instrument's noise (1 sigma per coordinate, mm) at each of `q` (rad): at the distance of
/// the identified model's point from the tracker (the file's measurement setup), or its constant
/// part for a file without one (data in the base frame).
fn instrument_sd(
    instrument: &host_tools::io::profile::Instrument,
    file: &RobotFile,
    path: &std::path::Path,
    q: &[Vec<f64>],
) -> anyhow::Result<Vec<f64>> {
    if file.measurement.is_none() {
        return Ok(vec![instrument.sigma_mm(0.0); q.len()]);
    }
    let model = file.in_measurement_setup().to_model(path)?;
    let kinematics = calib_core::Kinematics::nominal(&model.robot)?;
    q.iter()
        .map(|q| {
            let q = calib_core::model::JointVec::from_slice(q)
                .ok_or_else(|| anyhow::anyhow!("more than 9 joints"))?;
            let distance = kinematics.forward(&q)?.translation.vector.norm();
            Ok(instrument.sigma_mm(distance))
        })
        .collect()
}

/// The `--out` table: per configuration its id, joints (deg), standard deviations, nominal
/// position and, with `instrument` (its noise per configuration, mm), the noise and what a
/// measurement would show.
fn table(
    data: &TrackerData,
    sds: &[host_tools::analysis::uncertainty::PoseSd],
    positions: &[[f64; 3]],
    instrument: Option<&[f64]>,
) -> anyhow::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["id".to_string()];
    header.extend((1..=data.joints).map(|j| format!("q{j}_deg")));
    header.extend(
        [
            "sd_x_mm",
            "sd_y_mm",
            "sd_z_mm",
            "sd_mm",
            "sd_rx_deg",
            "sd_ry_deg",
            "sd_rz_deg",
            "x_mm",
            "y_mm",
            "z_mm",
        ]
        .map(String::from),
    );
    if instrument.is_some() {
        header.extend(["sd_instrument_mm", "sd_measured_mm"].map(String::from));
    }
    writer.write_record(&header)?;
    for (i, ((r, sd), p)) in data.records.iter().zip(sds).zip(positions).enumerate() {
        let mut row = vec![r.id.clone()];
        row.extend(r.q.iter().map(|v| v.to_degrees().to_string()));
        row.extend(
            (sd.position_mm.iter())
                .chain([&sd.position_rms_mm])
                .chain(&sd.orientation_deg)
                .chain(p)
                .map(|v| format!("{v:e}")),
        );
        if let Some(noise) = instrument.and_then(|n| n.get(i)) {
            let measured = (sd.position_rms_mm.powi(2) + 3.0 * noise * noise).sqrt();
            row.extend([format!("{noise:e}"), format!("{measured:e}")]);
        }
        writer.write_record(&row)?;
    }
    let csv = writer
        .into_inner()
        .map_err(|e| anyhow::anyhow!("{}", e.error()))?;
    Ok(csv)
}

/// Runs `calib uncertainty`; writes `--out` and returns the summary.
pub fn uncertainty(options: &UncertaintyOptions) -> anyhow::Result<Summary> {
    let file = RobotFile::read(&options.params)?;
    let profile = DataProfile::load(options.profile.as_deref())?;
    let data = TrackerData::read_joints(&options.joints, &profile)?;
    if data.joints != file.joint.len() {
        anyhow::bail!(
            "{}: has {} joint columns, the robot {} has {}",
            options.joints.display(),
            data.joints,
            options.params.display(),
            file.joint.len()
        );
    }
    // Joints within the robot's limits, as fk, evaluate and compensate require.
    let model = file.to_model(&options.params)?;
    for record in &data.records {
        if let Some(outside) = model.outside_limits(&record.q) {
            anyhow::bail!("{}:{}: {outside}", options.joints.display(), record.line);
        }
    }
    let q: Vec<Vec<f64>> = data.records.iter().map(|r| r.q.clone()).collect();
    let sds = host_tools::analysis::uncertainty::at_poses(&file, &options.params, &q)?;
    let positions = nominal_positions(&file, &options.params, &q)?;
    let instrument = match &profile.instrument {
        Some(i) => Some(instrument_sd(i, &file, &options.params, &q)?),
        None => None,
    };
    let csv = table(&data, &sds, &positions, instrument.as_deref())?;
    let mut outputs = Outputs::new(&[("--params", &options.params), ("--joints", &options.joints)]);
    outputs.stage("--out", &options.out, &csv)?;
    outputs.commit()?;
    let mut worst: Vec<(String, u64, f64)> = (data.records.iter().zip(&sds))
        .map(|(r, sd)| (r.id.clone(), r.line, sd.position_rms_mm))
        .collect();
    worst.sort_by(|a, b| b.2.total_cmp(&a.2));
    worst.truncate(WORST_NAMED);
    let rms: Vec<f64> = sds.iter().map(|s| s.position_rms_mm).collect();
    let lines: Vec<u64> = data.records.iter().map(|r| r.line).collect();
    let worst_regions =
        host_tools::analysis::workspace::WorkspaceMap::of(&positions, &rms, &lines, None)
            .map(|m| m.worst)
            .unwrap_or_default();
    Ok(Summary {
        worst_regions,
        poses: sds.len(),
        mean_mm: sds.iter().map(|s| s.position_rms_mm).sum::<f64>() / sds.len().max(1) as f64,
        worst,
    })
}

impl Summary {
    /// The lines for people.
    pub fn text(&self, out: &std::path::Path) -> String {
        let worst: Vec<String> = (self.worst.iter())
            .map(|(id, line, sd)| format!("{id} (line {line}) {sd:.4} mm"))
            .collect();
        let mut text = format!(
            "predicted position uncertainty (1 sigma, RMS over x, y, z) of {} configurations: mean {:.4} mm; largest: {}\n",
            self.poses,
            self.mean_mm,
            worst.join(", "),
        );
        if !self.worst_regions.is_empty() {
            text.push_str("regions of largest predicted uncertainty (terciles of x, y and z in the base frame):\n");
        }
        for r in &self.worst_regions {
            text.push_str(&format!(
                "  {}: mean {:.4} mm over {} configurations, max {:.4} mm (line {})\n",
                r.bounds_text(),
                r.mean_mm,
                r.poses,
                r.max_mm,
                r.max_line
            ));
        }
        text.push_str(&format!("wrote {}\n", out.display()));
        text
    }
}
