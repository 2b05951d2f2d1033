//! The published bench's oracle numbers (physics.md section 6).

use cable_servo::physics::{CableDrive, DriveFault, DriveParams, HysteresisModel};

fn bench(preload_n: f64) -> CableDrive {
    let params = DriveParams {
        preload_n,
        ..DriveParams::default()
    };
    CableDrive::new(params, HysteresisModel::Memory)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn free_span_of_the_bench() {
    let lf = DriveParams::default().free_span_m();
    assert!(rel(lf, 0.0776918) < 1e-6, "{lf}");
}

#[test]
fn oracle_point_072() {
    let mut drive = bench(100.0);
    let first = drive.apply_torque(0.72).unwrap();
    assert!(rel(first.tension_upper_n, 103.52112) < 1e-7);
    assert!(rel(first.elongation_upper_m, 22.1902e-6) < 1e-5);
    assert!(rel(-first.transmission_error_rad * 1e3, 0.216490) < 1e-5);
    let back = drive.apply_torque(-0.72).unwrap();
    assert!(rel(back.tension_upper_n, 96.49681) < 1e-7);
    let jump = (back.transmission_error_rad - first.transmission_error_rad) * 1e3;
    assert!(rel(jump, 0.432974) < 1e-5, "{jump}");
}

#[test]
fn oracle_point_13() {
    let mut drive = bench(100.0);
    let first = drive.apply_torque(1.3).unwrap();
    assert!(rel(first.tension_upper_n, 106.3862) < 1e-6);
    let back = drive.apply_torque(-1.3).unwrap();
    let again = drive.apply_torque(1.3).unwrap();
    let jump = (back.transmission_error_rad - again.transmission_error_rad) * 1e3;
    assert!(rel(jump, 0.858402) < 1e-5, "{jump}");
}

const PRELOADS: [f64; 8] = [10.0, 20.0, 30.0, 50.0, 70.0, 100.0, 140.0, 180.0];
const LOADS: [f64; 6] = [0.15, 0.47, 0.72, 1.0, 1.3, 3.0];
#[rustfmt::skip]
const TABLE: [[f64; 8]; 6] = [
    [0.102098, 0.0906589, 0.0868484, 0.0838008, 0.0824948, 0.0815154, 0.0808625, 0.0804997],
    [0.472954, 0.360564, 0.323094, 0.293141, 0.280312, 0.270693, 0.264281, 0.260719],
    [0.906541, 0.64398, 0.556019, 0.485675, 0.45555, 0.432968, 0.417918, 0.409558],
    [1.53743, 1.03675, 0.867273, 0.73153, 0.673386, 0.629804, 0.600763, 0.584634],
    [2.38274, 1.54517, 1.25973, 1.03039, 0.932088, 0.858402, 0.809306, 0.782041],
    [f64::NAN, 6.01402, 4.6123, 3.41425, 2.89253, 2.50001, 2.23821, 2.09283],
];

#[test]
fn whole_reversal_table() {
    for (i, &m) in LOADS.iter().enumerate() {
        for (j, &pre) in PRELOADS.iter().enumerate() {
            let mut drive = bench(pre);
            let expect = TABLE[i][j];
            let result = drive
                .apply_torque(m)
                .and_then(|_| drive.apply_torque(-m))
                .and_then(|back| Ok((back, drive.apply_torque(m)?)));
            if expect.is_nan() {
                assert!(
                    matches!(result, Err(DriveFault::Slack { .. })),
                    "M {m} Tpre {pre}: expected slack, got {result:?}"
                );
                continue;
            }
            let (back, again) = result.unwrap();
            let jump = (back.transmission_error_rad - again.transmission_error_rad) * 1e3;
            assert!(
                rel(jump, expect) < 1e-4,
                "M {m} Tpre {pre}: {jump} vs {expect}"
            );
        }
    }
}

#[test]
fn region_elongations_add_up_to_the_half() {
    for model in [HysteresisModel::Memory, HysteresisModel::Memoryless] {
        let mut drive = CableDrive::new(DriveParams::default(), model);
        for m in [0.72, -0.72, 0.3, 1.3] {
            let s = drive.apply_torque(m).unwrap();
            let (span, drum, pulley) = drive.upper().region_elongations_m(s.tension_upper_n);
            assert!(
                (span + drum + pulley - s.elongation_upper_m).abs() < 1e-12,
                "{model:?} {m}"
            );
            let (span, drum, pulley) = drive.lower().region_elongations_m(s.tension_lower_n);
            assert!((span + drum + pulley - s.elongation_lower_m).abs() < 1e-12);
        }
    }
    // On the first loading of the bench the drum and pulley wraps follow
    // (r Tpre / (G mu)) f(Tu/Tpre) with their own radii.
    let mut drive = CableDrive::new(DriveParams::default(), HysteresisModel::Memory);
    let s = drive.apply_torque(0.72).unwrap();
    let v: f64 = s.tension_upper_n / 100.0;
    let f = v - 1.0 - v.ln();
    let (_, drum, pulley) = drive.upper().region_elongations_m(s.tension_upper_n);
    assert!(rel(drum, 0.1025 * 100.0 / (1.4e4 * 0.2) * f) < 1e-6);
    assert!(rel(pulley, 0.020 * 100.0 / (1.4e4 * 0.2) * f) < 1e-6);
}
