//! One quasi-static step of the cable drive along a long random load history.
//!
//! Each iteration applies the next transmitted torque of a pre-drawn random history
//! (a random walk with frequent reversals of random size, within +-3 N m on the paper
//! bench) and commits the wrap memory, so the breakpoint lists grow and get wiped out as
//! in a real load history. Reported time is per step.

use cable_servo::physics::{CableDrive, DriveParams, HysteresisModel};
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use rand::{Rng, SeedableRng};

fn history(n: usize) -> Vec<f64> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut m = 0.0f64;
    let mut rate: f64 = 0.05;
    (0..n)
        .map(|_| {
            if rng.gen_bool(0.05) {
                rate = -rate.signum() * rng.gen_range(0.005..0.1);
            }
            m = (m + rate).clamp(-3.0, 3.0);
            if m.abs() >= 3.0 {
                rate = -rate;
            }
            m
        })
        .collect()
}

fn quasi_static_step(c: &mut Criterion) {
    let loads = history(100_000);
    let mut group = c.benchmark_group("quasi_static_step");
    group.throughput(Throughput::Elements(loads.len() as u64));
    for model in [HysteresisModel::Memory, HysteresisModel::Memoryless] {
        group.bench_function(format!("{model:?}").to_lowercase(), |b| {
            b.iter(|| {
                let mut drive = CableDrive::new(DriveParams::default(), model);
                let mut acc = 0.0;
                for &m in &loads {
                    if let Ok(s) = drive.apply_torque(black_box(m)) {
                        acc += s.transmission_error_rad;
                    }
                }
                acc
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = quasi_static_step
}
criterion_main!(benches);
