//! The paper's Table 3 statistics of pose errors, accumulated without storage: absolute position
//! error `|dp|` (mm) and the per-axis orientation errors `|dr_x|, |dr_y|, |dr_z|` (rad), each as
//! mean, sample standard deviation (n - 1) and maximum.

use crate::kinematics::pose_error::PoseError;
use crate::scalar::Real;

/// Running mean, standard deviation and maximum of a quantity (Welford's algorithm).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Summary<T> {
    /// Number of values.
    pub count: u32,
    /// Mean.
    pub mean: T,
    /// Sum of squared deviations from the mean (for the variance).
    m2: T,
    /// Largest value (0 when empty).
    pub max: T,
}

impl<T: Real> Default for Summary<T> {
    fn default() -> Self {
        Self {
            count: 0,
            mean: T::zero(),
            m2: T::zero(),
            max: T::zero(),
        }
    }
}

impl<T: Real> Summary<T> {
    /// Adds a value.
    pub fn add(&mut self, value: T) {
        self.count = self.count.saturating_add(1);
        let n = T::of(f64::from(self.count));
        let delta = value - self.mean;
        self.mean += delta / n;
        self.m2 += delta * (value - self.mean);
        if self.count == 1 || value > self.max {
            self.max = value;
        }
    }

    /// Sample standard deviation (n - 1 in the denominator); 0 for fewer than two values.
    pub fn std(&self) -> T {
        if self.count < 2 {
            return T::zero();
        }
        (self.m2 / T::of(f64::from(self.count - 1)))
            .max(T::zero())
            .sqrt()
    }
}

/// Table 3 statistics of a set of pose errors.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseStatistics<T> {
    /// Absolute position error `|dp|`, mm.
    pub position: Summary<T>,
    /// `|dr_x|`, `|dr_y|`, `|dr_z|`, rad.
    pub orientation: [Summary<T>; 3],
    /// Number of poses that had an orientation measurement.
    pub with_orientation: u32,
}

impl<T: Real> Default for PoseStatistics<T> {
    fn default() -> Self {
        Self {
            position: Summary::default(),
            orientation: [Summary::default(); 3],
            with_orientation: 0,
        }
    }
}

impl<T: Real> PoseStatistics<T> {
    /// Adds one pose error; `has_orientation = false` leaves the orientation summaries unchanged.
    pub fn add(&mut self, error: &PoseError<T>, has_orientation: bool) {
        self.position.add(error.position.norm());
        if has_orientation {
            self.with_orientation = self.with_orientation.saturating_add(1);
            for (summary, value) in self.orientation.iter_mut().zip(error.rotation.iter()) {
                summary.add(value.abs());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_matches_closed_form() {
        let mut s = Summary::<f64>::default();
        for v in [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0] {
            s.add(v);
        }
        assert_eq!(s.count, 8);
        assert!((s.mean - 5.0).abs() < 1e-15);
        // Sum of squared deviations 32, n - 1 = 7.
        assert!((s.std() - (32.0f64 / 7.0).sqrt()).abs() < 1e-15);
        assert_eq!(s.max, 9.0);
        assert_eq!(Summary::<f64>::default().std(), 0.0);
    }
}
