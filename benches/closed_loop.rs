//! Real-time factor of the closed loop on `eots_tracking` (20 s at 20 kHz, one sample of
//! computation delay) per mode, and with the linear cable as the cost reference. See benches/README.md.

use std::time::Instant;

use cable_servo::closed_loop::{
    run_closed_loop, CableModel, ClosedLoopParams, CompensationMode, RunOptions,
};
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

fn case(cable: CableModel) -> Scenario {
    let mut s = Scenario::load("eots_tracking", &[]).expect("built-in scenario");
    if let Some(p) = s.closed_loop.as_mut() {
        p.cable = cable;
    }
    s
}

fn options(mode: CompensationMode) -> RunOptions {
    RunOptions {
        modes: Some(vec![mode]),
        ..RunOptions::metrics_only()
    }
}

fn simulated_s(s: &Scenario) -> f64 {
    s.closed_loop
        .as_ref()
        .map_or(0.0, |p: &ClosedLoopParams| p.duration_s)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("eots_tracking_20s");
    group.sample_size(10);
    let cases = [
        (
            "linear_cable_none",
            CableModel::Linear,
            CompensationMode::None,
        ),
        ("none", CableModel::Hysteretic, CompensationMode::None),
        (
            "memoryless",
            CableModel::Hysteretic,
            CompensationMode::Memoryless,
        ),
        ("memory", CableModel::Hysteretic, CompensationMode::Memory),
    ];
    for (name, cable, mode) in cases {
        let s = case(cable);
        let opts = options(mode);
        // One timed run for the headline figure: simulated seconds per wall second.
        let t = Instant::now();
        let r = run_closed_loop(&s, &opts).expect("scenario runs");
        let wall = t.elapsed().as_secs_f64();
        eprintln!(
            "{name}: real-time factor {:.0}x ({:.3} s wall for {} s; {} RHS evaluations)",
            simulated_s(&s) / wall,
            wall,
            simulated_s(&s),
            r.modes[0].stats.rhs_evaluations
        );
        group.bench_function(name, |b| {
            b.iter(|| run_closed_loop(&s, &opts).expect("scenario runs"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
