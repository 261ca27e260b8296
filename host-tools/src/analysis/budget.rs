//! The uncertainty budget of a calibration's accuracy statement after the GUM (JCGM 100:2008;
//! issue 55, item 6).
//!
//! The measurand is one coordinate of the position error that a measurement with the same
//! instrument finds at a pose of the calibrated workspace after calibration (measured minus the
//! identified model's prediction), as the held-out poses measure it. Its standard uncertainty
//! combines uncorrelated components with unit sensitivity (GUM 5.1.2, eq. 10):
//!
//! - **model** (type A): the identified parameters' covariance propagated to the held-out poses,
//!   `sqrt(mean(trace(J S J^T)) / 3)` per coordinate;
//! - **instrument** (type B): the data profile's maximum permissible error read as 2 sigma, at
//!   the held-out poses' distances (mean of their variances);
//! - **unmodelled error and repeatability** (type A): the calibration's position residuals per
//!   coordinate, corrected for the parameters fitted (`rms / sqrt 3 * sqrt(rows / (rows -
//!   parameters))`), less the instrument's part: `sqrt(max(0, s^2 - u_instrument^2))`; without
//!   an instrument stated it is the whole residual, the instrument's noise inside it;
//! - **temperature** (type B, when the data carry the air temperature): the arm growing by
//!   `alpha dT` over the range of temperatures seen, a rectangular distribution of half-width
//!   `alpha (T_max - T_min) R / 2` at the held-out poses' mean distance `R` from the base,
//!   `alpha` = 23e-6 /K (aluminium, the larger of the arms' usual metals).
//!
//! The expanded uncertainty is `U = k u_c` with `k = 2` (about 95 % of a normal distribution);
//! the budget states the share of the held-out poses' coordinates within `+-U`, and simulation
//! checks it (`tests/certificate.rs`).

use serde::{Deserialize, Serialize};

/// The coverage factor.
pub const COVERAGE_FACTOR: f64 = 2.0;

/// Linear thermal expansion assumed for the arm, 1/K (aluminium; steel is 11.5e-6).
pub const EXPANSION_PER_K: f64 = 23e-6;

/// One component of the budget.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Component {
    /// What it is.
    pub name: String,
    /// How it is evaluated: `A` (from the data, statistically) or `B` (from other knowledge).
    pub evaluation: String,
    /// Where its value comes from.
    pub source: String,
    /// Its standard uncertainty per coordinate, mm.
    pub standard_uncertainty_mm: f64,
}

/// The budget.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UncertaintyBudget {
    /// The components evaluated.
    pub components: Vec<Component>,
    /// Components not evaluated, and why.
    pub not_evaluated: Vec<String>,
    /// The combined standard uncertainty per coordinate, mm.
    pub combined_mm: f64,
    /// The coverage factor `k`.
    pub k: f64,
    /// The expanded uncertainty `U = k u_c` per coordinate, mm.
    pub expanded_mm: f64,
    /// Held-out coordinates (3 per pose).
    pub held_out_coordinates: usize,
    /// Their share within `+-U`, %.
    pub held_out_within_percent: f64,
}

/// What the budget is made from.
#[derive(Clone, Debug, PartialEq)]
pub struct BudgetInputs<'a> {
    /// Per held-out pose, the parameters' predicted RMS position error `sqrt(trace(J S J^T))`,
    /// mm.
    pub model_rms_mm: &'a [f64],
    /// Per held-out pose, the signed position error after calibration, mm.
    pub held_out_errors_mm: &'a [[f64; 3]],
    /// Per held-out pose, its distance from the robot's base, mm.
    pub reach_mm: &'a [f64],
    /// The calibration poses' RMS position residual, mm, with the residual rows and the
    /// parameters fitted.
    pub residual: (f64, f64, f64),
    /// The instrument's standard uncertainty per coordinate at the held-out poses (RMS), mm, and
    /// its description; `None` when no instrument is stated.
    pub instrument: Option<(f64, String)>,
    /// The air temperatures seen, deg C (lowest, highest); `None` when not measured.
    pub temperature_c: Option<(f64, f64)>,
}

/// The noise per coordinate estimated from a calibration's position residuals: their RMS
/// length per coordinate (`/ sqrt 3`) corrected for the parameters fitted (`sqrt(rows / (rows
/// - parameters))`); `None` without residual degrees of freedom or residuals.
pub fn residual_noise_mm(position_rms_mm: f64, rows: f64, parameters: f64) -> Option<f64> {
    (position_rms_mm.is_finite() && position_rms_mm > 0.0 && rows > parameters)
        .then(|| position_rms_mm / 3f64.sqrt() * (rows / (rows - parameters)).sqrt())
}

impl UncertaintyBudget {
    /// The budget of `inputs`; `None` without held-out poses or residual degrees of freedom.
    pub fn of(inputs: &BudgetInputs<'_>) -> Option<Self> {
        let n = inputs.model_rms_mm.len();
        if n == 0 || inputs.held_out_errors_mm.len() != n {
            return None;
        }
        let (rms, rows, parameters) = inputs.residual;
        let residual = residual_noise_mm(rms, rows, parameters)?;
        let model =
            (inputs.model_rms_mm.iter().map(|r| r * r).sum::<f64>() / n as f64 / 3.0).sqrt();
        let mut components = vec![Component {
            name: "model: the identified parameters' uncertainty".into(),
            evaluation: "A".into(),
            source: format!("least squares' covariance propagated to the {n} held-out poses"),
            standard_uncertainty_mm: model,
        }];
        let mut not_evaluated = Vec::new();
        match &inputs.instrument {
            Some((u, description)) => {
                components.push(Component {
                    name: "instrument".into(),
                    evaluation: "B".into(),
                    source: format!("{description}: its maximum permissible error read as 2 sigma"),
                    standard_uncertainty_mm: *u,
                });
                components.push(Component {
                    name: "unmodelled error and repeatability".into(),
                    evaluation: "A".into(),
                    source: format!(
                        "the calibration's position residuals ({residual:.4} mm per coordinate) less the instrument's part"
                    ),
                    standard_uncertainty_mm: (residual * residual - u * u).max(0.0).sqrt(),
                });
            }
            None => {
                components.push(Component {
                    name: "noise: unmodelled error, repeatability and the instrument together".into(),
                    evaluation: "A".into(),
                    source: "the calibration's position residuals per coordinate, corrected for the parameters fitted".into(),
                    standard_uncertainty_mm: residual,
                });
                not_evaluated.push(
                    "the instrument apart from the noise ([instrument] in the data profile)".into(),
                );
            }
        }
        match inputs.temperature_c {
            Some((low, high)) => {
                let reach =
                    inputs.reach_mm.iter().sum::<f64>() / inputs.reach_mm.len().max(1) as f64;
                let half_width = EXPANSION_PER_K * (high - low) * reach / 2.0;
                components.push(Component {
                    name: "temperature".into(),
                    evaluation: "B".into(),
                    source: format!(
                        "{low:.2} to {high:.2} deg C seen; the arm ({reach:.0} mm mean reach) growing by {EXPANSION_PER_K:e} /K, rectangular"
                    ),
                    standard_uncertainty_mm: half_width / 3f64.sqrt(),
                });
            }
            None => not_evaluated.push("temperature (a temperature_c column in the data)".into()),
        }
        let combined = (components.iter())
            .map(|c| c.standard_uncertainty_mm.powi(2))
            .sum::<f64>()
            .sqrt();
        let expanded = COVERAGE_FACTOR * combined;
        let coordinates = 3 * n;
        let within = (inputs.held_out_errors_mm.iter().flatten())
            .filter(|e| e.abs() <= expanded)
            .count();
        Some(Self {
            components,
            not_evaluated,
            combined_mm: combined,
            k: COVERAGE_FACTOR,
            expanded_mm: expanded,
            held_out_coordinates: coordinates,
            held_out_within_percent: 100.0 * within as f64 / coordinates as f64,
        })
    }

    /// The budget for people.
    pub fn text(&self) -> String {
        use std::fmt::Write as _;
        let mut text = String::from(
            "uncertainty budget (GUM; per coordinate of the position error after calibration):\n",
        );
        for c in &self.components {
            let _ = writeln!(
                text,
                "  {:<62} type {}  u = {:.4} mm  ({})",
                c.name, c.evaluation, c.standard_uncertainty_mm, c.source
            );
        }
        for n in &self.not_evaluated {
            let _ = writeln!(text, "  not evaluated: {n}");
        }
        let _ = writeln!(
            text,
            "  combined u_c = {:.4} mm; expanded U = {:.4} mm (k = {}); held out: {:.1} % of {} coordinates within +-U",
            self.combined_mm,
            self.expanded_mm,
            self.k,
            self.held_out_within_percent,
            self.held_out_coordinates
        );
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The components and their combination against the closed forms: the model's RMS per
    /// coordinate, the residual less the instrument, the rectangular temperature term, `U = 2
    /// u_c`, and the held-out share counted.
    #[test]
    fn the_budget_combines_its_components_as_the_gum_does() {
        let errors = [[0.01, -0.02, 0.03], [0.2, 0.0, -0.01]];
        let inputs = BudgetInputs {
            model_rms_mm: &[0.03, 0.04],
            held_out_errors_mm: &errors,
            reach_mm: &[1000.0, 1200.0],
            residual: (0.05 * 3f64.sqrt(), 103.0, 3.0),
            instrument: Some((0.02, "a tracker".into())),
            temperature_c: Some((20.0, 22.0)),
        };
        let b = UncertaintyBudget::of(&inputs).unwrap();
        let model = ((0.03f64.powi(2) + 0.04f64.powi(2)) / 2.0 / 3.0).sqrt();
        let residual = 0.05 * (103.0f64 / 100.0).sqrt();
        let unmodelled = (residual * residual - 0.0004).sqrt();
        let temperature = 23e-6 * 2.0 * 1100.0 / 2.0 / 3f64.sqrt();
        let u: Vec<f64> = b
            .components
            .iter()
            .map(|c| c.standard_uncertainty_mm)
            .collect();
        assert_eq!(u.len(), 4);
        for (got, want) in u.iter().zip([model, 0.02, unmodelled, temperature]) {
            assert!((got - want).abs() < 1e-15, "{got} {want}");
        }
        let combined =
            (model * model + 0.0004 + unmodelled * unmodelled + temperature * temperature).sqrt();
        assert!((b.combined_mm - combined).abs() < 1e-15);
        assert!((b.expanded_mm - 2.0 * combined).abs() < 1e-15);
        // 5 of 6 coordinates within +-U (0.2 mm is not).
        assert!(b.expanded_mm < 0.2 && b.expanded_mm > 0.03);
        assert!((b.held_out_within_percent - 500.0 / 6.0).abs() < 1e-12);
        assert!(b.not_evaluated.is_empty());
        let none = UncertaintyBudget::of(&BudgetInputs {
            instrument: None,
            temperature_c: None,
            ..inputs
        })
        .unwrap();
        assert_eq!(none.not_evaluated.len(), 2);
        assert!((none.components[1].standard_uncertainty_mm - residual).abs() < 1e-15);
    }
}
