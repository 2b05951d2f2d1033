//! Sweep throughput (cases per second) at 1 and 2 worker threads.
//!
//! `fig11`: the 48-case backlash grid of the paper's Fig. 11. `tolerance`: 1000 random
//! cases of the quasi-static paper bench (20 s of 0.1 Hz sine at 200 Hz, first model)
//! with preload, friction, cable stiffness and brake torque drawn around their nominal
//! values. `closed_loop_tolerance_1000`: the built-in `eots_tolerance` sweep, 1000
//! Latin-hypercube cases of the EOTS tracking loop, 2 s at 10 kHz each (memory mode),
//! on two threads; run it alone with `cargo bench --bench sweep -- closed_loop`. Rows go to
//! a sink that only counts them, so the figures exclude file output.

use cable_servo::run::{
    run_one_case, BacklashRunner, CaseRunner, ClosedLoopRunner, QuasiStaticRunner,
};
use cable_servo::scenario::{builtin, Scenario};
use cable_servo::sweep::engine::{expand, run_cases, Plan};
use cable_servo::sweep::vary::SweepOverrides;
use cable_servo::sweep::{Case, Shard};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};

fn prepared(name: &str, overrides: &SweepOverrides) -> (toml::Table, Vec<Case>) {
    let mut scenario = Scenario::from_toml(builtin(name).unwrap(), name, name, &[]).unwrap();
    if !overrides.is_empty() {
        scenario.sweep = Some(overrides.apply(scenario.sweep.take()).unwrap());
    }
    let base = scenario.to_table();
    let cases = expand(scenario.sweep.as_ref().unwrap(), &base).unwrap();
    (base, cases)
}

fn run(base: &toml::Table, cases: &[Case], runner: &dyn CaseRunner, threads: usize) -> usize {
    let plan = Plan {
        cases,
        shard: Shard::ALL,
        threads,
        stop: None,
    };
    let mut rows = 0;
    run_cases(
        &plan,
        runner.columns().len(),
        &|case| run_one_case(base, "bench", case, runner, None),
        &mut |_, _| {
            rows += 1;
            Ok(())
        },
        &|| {},
    )
    .unwrap();
    rows
}

fn sweeps(c: &mut Criterion) {
    let (base, cases) = prepared("paper_fig11", &SweepOverrides::default());
    let mut group = c.benchmark_group("fig11");
    group.throughput(Throughput::Elements(cases.len() as u64));
    for threads in [1, 2] {
        group.bench_with_input(BenchmarkId::new("threads", threads), &threads, |b, &t| {
            b.iter(|| run(&base, &cases, &BacklashRunner, t))
        });
    }
    group.finish();

    let tolerance = SweepOverrides {
        vary: vec![
            "drive.preload_n=normal_rel(0.05)".into(),
            "drive.friction_coefficient=uniform_rel(0.2)".into(),
            "drive.cable_modulus_n=normal_rel(0.05,0.15)".into(),
            "load.brake_nm=tnormal(0.7,0.05,0.6,0.8)".into(),
        ],
        samples: Some(1000),
        seed: Some(1),
        ..SweepOverrides::default()
    };
    let (base, cases) = prepared("paper_bench", &tolerance);
    let mut group = c.benchmark_group("tolerance_1000");
    group.throughput(Throughput::Elements(cases.len() as u64));
    group.sample_size(10);
    for threads in [1, 2] {
        group.bench_with_input(BenchmarkId::new("threads", threads), &threads, |b, &t| {
            b.iter(|| run(&base, &cases, &QuasiStaticRunner, t))
        });
    }
    group.finish();

    let (base, cases) = prepared("eots_tolerance", &SweepOverrides::default());
    let scenario = Scenario::from_toml(
        builtin("eots_tolerance").unwrap(),
        "eots_tolerance",
        "eots_tolerance",
        &[],
    )
    .unwrap();
    let runner = ClosedLoopRunner::for_scenario(&scenario);
    let mut group = c.benchmark_group("closed_loop_tolerance_1000");
    group.throughput(Throughput::Elements(cases.len() as u64));
    group.sample_size(10);
    group.bench_function("threads/2", |b| b.iter(|| run(&base, &cases, &runner, 2)));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = sweeps
}
criterion_main!(benches);
