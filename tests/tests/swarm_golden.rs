//! The Halton generator and the eq. (7) objective against the golden vectors of the independent
//! numpy implementation.

use calib_core::Problem;
use calib_core::identify::halton::{self, Scrambling};
use calib_core::identify::objective::{Measurement, Objective};
use calib_core::{Kinematics, ParameterSet};
use calib_tests::{read_csv, table2_errors};
use nalgebra::U6;
use nalgebra::{DVector, Dyn, SVector, U24};

#[test]
fn halton_points_match_golden_vectors() {
    let (header, rows) = read_csv("vectors/halton.csv");
    assert_eq!(header.len(), 25);
    assert_eq!(rows.len(), 41);
    for row in &rows {
        let k: u64 = row[0].parse().unwrap();
        let mut point = [0.0; 24];
        halton::halton_point(k, Scrambling::None, &mut point);
        for (i, (value, golden)) in point.iter().zip(&row[1..]).enumerate() {
            let golden: f64 = golden.parse().unwrap();
            // Ours is the correctly rounded exact fraction (3/5 -> 0.6); the reference sums digit
            // terms in floating point (0.6000000000000001), so allow a few ulp.
            assert!(
                (value - golden).abs() <= 4.0 * f64::EPSILON * golden.max(f64::MIN_POSITIVE),
                "k = {k}, base {}: {value} vs {golden}",
                halton::PRIMES[i]
            );
        }
    }
}

#[test]
fn halton_in_f32_is_the_rounded_f64_point() {
    let mut point = [0.0; 24];
    halton::halton_point(17, Scrambling::None, &mut point);
    // base 2: 17 = 10001b -> 0.10001b = 0.53125; base 3: 17 = 122_3 -> 0.221_3 = 25/27.
    assert_eq!(point[0], 0.53125);
    assert_eq!(point[1], 25.0 / 27.0);
    assert_eq!(point[1] as f32, (25.0f32 / 27.0));
}

#[test]
fn objective_matches_golden_values() {
    let robot = calib_core::model::paper::er10l_c10::<f64>();
    let truth = Kinematics::new(&robot, &table2_errors()).unwrap();
    let (_, rows) = read_csv("vectors/pose-error-er10l-c10.csv");
    let measurements: Vec<Measurement<f64, U6>> = rows
        .iter()
        .map(|row| {
            let q: [f64; 6] = std::array::from_fn(|i| row[i].parse::<f64>().unwrap().to_radians());
            Measurement::from_pose(&q, &truth.forward(&q).unwrap()).unwrap()
        })
        .collect();
    // The counts compiled (as on the controller) and at run time (as on a host): the same bits.
    let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
    let at_table2 = set.pack(&table2_errors::<f64>());
    let dynamic_robot = robot.recount::<Dyn>().unwrap();
    let dynamic_measurements: Vec<Measurement<f64, Dyn>> =
        measurements.iter().map(|m| m.recount().unwrap()).collect();
    let dynamic_set = ParameterSet::<Dyn, Dyn>::default_for(&dynamic_robot).unwrap();
    let text =
        std::fs::read_to_string(calib_tests::data("vectors/objective-er10l-c10.txt")).unwrap();
    let mut checked = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let f: Vec<&str> = line.split_whitespace().collect();
        let k: f64 = f[0].trim_start_matches("k=").parse().unwrap();
        let golden: f64 = f[2].trim_start_matches("f=").parse().unwrap();
        let x = if f[1] == "x=table2" {
            at_table2
        } else {
            SVector::zeros()
        };
        let dynamic_x = DVector::from_column_slice(x.as_slice());
        let problem = Problem::new(
            &robot,
            &calib_core::ParameterErrors::zero(),
            set,
            &measurements,
            k,
        )
        .unwrap();
        let objective = Objective::new(&problem);
        let value = objective.value(&x);
        let dynamic_problem = Problem::new(
            &dynamic_robot,
            &calib_core::ParameterErrors::zeros_for(dynamic_robot.joint_count()),
            dynamic_set.clone(),
            &dynamic_measurements,
            k,
        )
        .unwrap();
        let dynamic = Objective::new(&dynamic_problem).value(&dynamic_x);
        assert_eq!(value.to_bits(), dynamic.to_bits(), "k={k} {}", f[1]);
        assert!(
            (value - golden).abs() <= 1e-10 * golden.max(1.0),
            "k={k} {}: {value} vs {golden}",
            f[1]
        );
        checked += 1;
    }
    assert_eq!(checked, 4);
}
