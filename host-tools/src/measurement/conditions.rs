//! The conditions a robot was measured under, as a calibration certificate states them: which
//! robot (its serial number, from the robot file), what the flange carried (the payload, from
//! `--payload-kg` or the robot file's `[dynamics] tool`), the instrument and its maximum
//! permissible error (from the data profile's `[instrument]`) and the air temperature range (from
//! a `temperature_c` column). What the inputs do not state is stated as not stated, never
//! guessed.

use crate::io::profile::Instrument;
use crate::measurement::dataset::Dataset;
use serde::Serialize;

/// Where the payload figure came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PayloadSource {
    /// The `--payload-kg` option.
    Option,
    /// The robot file's `[dynamics] tool` mass.
    RobotFile,
}

/// The payload during the measurement.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Payload {
    /// The mass the flange carried, kg.
    pub mass_kg: f64,
    /// Where the figure came from.
    pub source: PayloadSource,
}

/// The air temperature over the measured poses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct TemperatureRange {
    /// Lowest, deg C.
    pub min_c: f64,
    /// Highest, deg C.
    pub max_c: f64,
    /// Poses with a temperature.
    pub poses: usize,
}

/// What the certificate says of the measurement.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct MeasurementConditions {
    /// The robot's serial number (the robot file's `serial`), if stated.
    pub robot_serial: Option<String>,
    /// The payload, if stated.
    pub payload: Option<Payload>,
    /// The instrument, if the data profile states it.
    pub instrument: Option<Instrument>,
    /// The air temperature over every measured pose (calibration and held out), if the data
    /// carry it.
    pub temperature: Option<TemperatureRange>,
}

/// Payloads `--payload-kg` accepts, kg.
pub const PAYLOAD_KG: std::ops::RangeInclusive<f64> = 0.0..=2000.0;

impl MeasurementConditions {
    /// The conditions of `dataset` and the held-out `validation`; `payload_kg` is the
    /// `--payload-kg` option. Refused: a payload outside [`PAYLOAD_KG`], or one that differs from
    /// the robot file's `[dynamics] tool` mass.
    pub fn of(
        dataset: &Dataset,
        validation: Option<&Dataset>,
        payload_kg: Option<f64>,
    ) -> crate::Result<Self> {
        let file_payload = (dataset.robot.file.dynamics.as_ref())
            .and_then(|d| d.tool.as_ref())
            .map(|t| t.mass_kg);
        let payload = match (payload_kg, file_payload) {
            (Some(kg), _) if !PAYLOAD_KG.contains(&kg) => {
                return Err(crate::refused!(option "--payload-kg";
                    "--payload-kg {kg} is not a payload of 0 to {} kg",
                    PAYLOAD_KG.end()
                ));
            }
            (Some(kg), Some(file)) if (kg - file).abs() > 1e-9 => {
                return Err(crate::refused!(option "--payload-kg";
                    "--payload-kg {kg} differs from the {file} kg the robot file's [dynamics] tool carries \
                     while measured: give one of them (or correct [dynamics.tool] mass_kg)"
                ));
            }
            (Some(kg), _) => Some(Payload {
                mass_kg: kg,
                source: PayloadSource::Option,
            }),
            (None, Some(file)) => Some(Payload {
                mass_kg: file,
                source: PayloadSource::RobotFile,
            }),
            (None, None) => None,
        };
        let temperatures: Vec<f64> = std::iter::once(dataset)
            .chain(validation)
            .flat_map(|d| d.data.records.iter().filter_map(|r| r.temperature_c))
            .collect();
        let temperature = (!temperatures.is_empty()).then(|| TemperatureRange {
            min_c: temperatures.iter().copied().fold(f64::INFINITY, f64::min),
            max_c: temperatures
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max),
            poses: temperatures.len(),
        });
        Ok(Self {
            robot_serial: dataset.robot.file.serial.clone(),
            payload,
            instrument: dataset.data.instrument.clone(),
            temperature,
        })
    }

    /// The lines for people.
    pub fn text(&self) -> String {
        let not_stated = |what: &str| format!("not stated ({what})");
        let serial = self
            .robot_serial
            .clone()
            .unwrap_or_else(|| not_stated("serial = \"...\" in the robot file"));
        let payload = self.payload.map_or_else(
            || not_stated("--payload-kg, or [dynamics] tool in the robot file"),
            |p| {
                match p.source {
                    PayloadSource::Option => format!(
                        "{} kg (given for this measurement, --payload-kg)",
                        p.mass_kg
                    ),
                    PayloadSource::RobotFile => format!(
                        "assumed {} kg (the robot file's [dynamics] tool, not given for this measurement: --payload-kg states it)",
                        p.mass_kg
                    ),
                }
            },
        );
        let instrument = self.instrument.as_ref().map_or_else(
            || not_stated("[instrument] in the data profile"),
            |i| {
                format!(
                    "{}{}, MPE {} um + {} um/m",
                    i.name.as_deref().unwrap_or("unnamed"),
                    i.serial
                        .as_ref()
                        .map_or(String::new(), |s| format!(" (serial {s})")),
                    i.mpe_um,
                    i.mpe_um_per_m
                )
            },
        );
        let temperature = self.temperature.map_or_else(
            || not_stated("a temperature_c column in the data"),
            |t| {
                format!(
                    "{:.2} to {:.2} deg C over {} poses",
                    t.min_c, t.max_c, t.poses
                )
            },
        );
        format!(
            "measured: robot serial {serial}; payload {payload}; instrument {instrument}; air temperature {temperature}\n"
        )
    }
}
