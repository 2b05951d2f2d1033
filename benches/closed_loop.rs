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

/// One control period of a long recorded run, the way a single-mode study runs it from the
/// command line: 100 s at 20 kHz in memory mode, the time series kept at 10 Hz, the error's
/// spectrum and line-of-sight metrics computed, for the memory and the linear cable.
/// Prints ns per control period of one run before criterion times the whole run.
fn period(c: &mut Criterion) {
    let mut group = c.benchmark_group("eots_tracking_100s_recorded");
    group.sample_size(10);
    for (name, cable) in [
        ("memory_cable", CableModel::Hysteretic),
        ("linear_cable", CableModel::Linear),
    ] {
        let mut s = case(cable);
        let mut decimation = 1;
        if let Some(p) = s.closed_loop.as_mut() {
            p.duration_s = 100.0;
            decimation = (p.controller.sample_rate_hz / 10.0).round() as usize;
        }
        let opts = RunOptions {
            modes: Some(vec![CompensationMode::Memory]),
            decimation,
            ..RunOptions::default()
        };
        let periods = s.closed_loop.as_ref().map_or(1, |p| p.periods()).max(1) as f64;
        let t = Instant::now();
        run_closed_loop(&s, &opts).expect("scenario runs");
        eprintln!(
            "{name}: {:.0} ns per control period over {periods} periods (one run)",
            t.elapsed().as_secs_f64() / periods * 1e9
        );
        group.bench_function(name, |b| {
            b.iter(|| run_closed_loop(&s, &opts).expect("scenario runs"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench, period);
criterion_main!(benches);
