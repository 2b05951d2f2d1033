//! `compare` of four designs of the stabilised gimbal, 20 s each at 20 kHz, with every
//! design's files and the overlay figures, into a fresh directory each time. The
//! designs are the walk of `docs/stabilise.md`: the encoder loop, the gyro rate loop without its notch
//! (it stops as unstable, which costs a fraction of a run), the rate loop with the notch,
//! and the same with memory compensation. See benches/README.md.

use cable_servo::run::{run_compare, CompareDesign, OutputOptions};
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

fn design(name: &str, sets: &[&str]) -> CompareDesign {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    CompareDesign {
        name: name.into(),
        description: sets.join("; "),
        scenario: Scenario::load("gimbal_stabilized", &sets).expect("built-in scenario"),
    }
}

fn bench(c: &mut Criterion) {
    let designs = vec![
        design(
            "encoders_only",
            &[
                "closed_loop.modes=[\"none\"]",
                "closed_loop.controller.feedback=\"motor\"",
                "closed_loop.controller.rate_loop.measurement=\"motor_velocity\"",
            ],
        ),
        design(
            "gyro_rate_loop",
            &[
                "closed_loop.modes=[\"none\"]",
                "closed_loop.controller.command_filters=[]",
            ],
        ),
        design("gyro_notch", &["closed_loop.modes=[\"none\"]"]),
        design("gyro_notch_memory", &["closed_loop.modes=[\"memory\"]"]),
    ];
    let tmp = tempfile::tempdir().expect("temporary directory");
    let mut k = 0u64;
    let mut group = c.benchmark_group("compare");
    group.sample_size(10);
    group.bench_function("gimbal_4_designs_20s", |b| {
        b.iter(|| {
            k += 1;
            let out = OutputOptions {
                dir: tmp.path().join(format!("run-{k}")),
                force: false,
            };
            run_compare(&designs, None, &out).expect("the comparison runs")
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
